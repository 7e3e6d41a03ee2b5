# syntax=docker/dockerfile:1
# wavrad: the render service in a small image.
#
# The build stage runs exactly the release build that CI runs (`.ci/run`):
#     cargo build --release --locked --bin wavrad
# first on a placeholder crate with the project's manifest and lock file, so that the
# dependencies are built in a layer of their own and rebuilt only when those two files change,
# then on the sources. CI starts the built binary with this image's ENTRYPOINT, CMD and ENV
# and checks that it answers /healthz where WAVRAD_ADDR says (no Docker engine is needed).

FROM rust:1.95-slim-bookworm AS build
WORKDIR /src
COPY Cargo.toml Cargo.lock ./
RUN mkdir -p src benches \
    && echo 'fn main() {}' > src/main.rs \
    && touch src/lib.rs \
    && sed -n '/^\[\[bench\]\]/{n;s/^name = "\(.*\)"$/\1/p}' Cargo.toml > benches/names \
    && while read -r b; do echo 'fn main() {}' > "benches/$b.rs"; done < benches/names \
    && cargo build --release --locked --bin wavrad \
    && rm -rf src benches
COPY src ./src
COPY benches ./benches
COPY static ./static
COPY scenes ./scenes
COPY assets ./assets
RUN touch src/main.rs src/lib.rs \
    && cargo build --release --locked --bin wavrad

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
# Every setting comes from the environment (`wavrad serve --help` lists them); override any
# with `docker run -e`, e.g. -e WAVRAD_ADDR=0.0.0.0:9000 (and publish that port).
ENV WAVRAD_DATA_DIR=/var/lib/wavrad \
    WAVRAD_ADDR=0.0.0.0:8080
EXPOSE 8080
# The port is the one WAVRAD_ADDR names, whatever it was set to.
HEALTHCHECK --interval=30s --timeout=3s --start-period=5s --retries=3 \
    CMD ["sh", "-c", "curl -fsS \"http://127.0.0.1:${WAVRAD_ADDR##*:}/healthz\" || exit 1"]
ENTRYPOINT ["/usr/local/bin/wavrad"]
CMD ["serve"]
