# syntax=docker/dockerfile:1
# wavrad: the render service in a small image.
#
# The build stage runs exactly the release build that CI runs (`.ci/run`):
#     cargo build --release --locked --bin wavrad
# and CI starts the built binary with this image's ENTRYPOINT and CMD arguments and checks
# that it answers /healthz (no Docker engine is needed for that check).

FROM rust:1.95-slim-bookworm AS build
WORKDIR /src
COPY Cargo.toml Cargo.lock ./
COPY src ./src
COPY benches ./benches
COPY static ./static
COPY scenes ./scenes
COPY assets ./assets
RUN cargo build --release --locked --bin wavrad

FROM debian:bookworm-slim AS runtime
RUN apt-get update \
    && apt-get install -y --no-install-recommends curl=7.88.* \
    && rm -rf /var/lib/apt/lists/* \
    && groupadd --system --gid 10001 wavrad \
    && useradd --system --uid 10001 --gid 10001 --home-dir /var/lib/wavrad --create-home wavrad
COPY --from=build /src/target/release/wavrad /usr/local/bin/wavrad
USER 10001:10001
WORKDIR /var/lib/wavrad
VOLUME ["/var/lib/wavrad"]
ENV WAVRAD_DATA_DIR=/var/lib/wavrad
EXPOSE 8080
HEALTHCHECK --interval=30s --timeout=3s --start-period=5s --retries=3 \
    CMD ["curl", "-fsS", "http://127.0.0.1:8080/healthz"]
ENTRYPOINT ["/usr/local/bin/wavrad"]
CMD ["serve", "--addr", "0.0.0.0:8080"]
