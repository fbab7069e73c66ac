# syntax=docker/dockerfile:1
# meshatlas service image: build in the Rust image, run as a non-root user
# in a slim Debian image with the data directory as a volume.

FROM rust:1.95-bookworm AS build
WORKDIR /src
# METIS (vendored C, via the metis crate) and SQLite (bundled) build with the image's gcc.
COPY Cargo.toml Cargo.lock ./
COPY src ./src
COPY benches ./benches
COPY api ./api
RUN cargo build --release --locked --bin meshatlas \
 && install -m 0755 target/release/meshatlas /usr/local/bin/meshatlas

FROM debian:bookworm-slim
RUN groupadd --system --gid 10001 meshatlas \
 && useradd --system --uid 10001 --gid meshatlas --home-dir /var/lib/meshatlas --shell /usr/sbin/nologin meshatlas \
 && mkdir -p /var/lib/meshatlas \
 && chown meshatlas:meshatlas /var/lib/meshatlas
COPY --from=build /usr/local/bin/meshatlas /usr/local/bin/meshatlas
COPY api/openapi.yaml /usr/share/meshatlas/openapi.yaml
USER meshatlas:meshatlas
# 0.0.0.0 needs MESHATLAS_AUTH_TOKENS (a token file's path) or MESHATLAS_INSECURE_NO_AUTH=true.
ENV MESHATLAS_ADDR=0.0.0.0:8080 \
    MESHATLAS_DATA_DIR=/var/lib/meshatlas \
    MESHATLAS_LOG=info
VOLUME ["/var/lib/meshatlas"]
EXPOSE 8080
# SIGTERM: stop accepting, put running jobs back in the queue, exit.
STOPSIGNAL SIGTERM
ENTRYPOINT ["/usr/local/bin/meshatlas"]
CMD ["serve"]
