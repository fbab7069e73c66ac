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

# Runs a command as the postgres user (or as is when not root).
as_postgres() {
    if [ "$(id -u)" = "0" ]; then
        setpriv --reuid=postgres --regid=postgres --init-groups "$@"
    else
        "$@"
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
    as_postgres "$bin/initdb" -D "$d/data" -U meshatlas --auth=trust -E UTF8 --no-sync >"$d/initdb.log" 2>&1 \
        || { cat "$d/initdb.log"; return 1; }
    as_postgres "$bin/postgres" -D "$d/data" -p "$PG_PORT" -k "$d" -c listen_addresses=127.0.0.1 \
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

# Stops what start_* started, each by its own PID, and removes the temp dir.
stop_services() {
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
