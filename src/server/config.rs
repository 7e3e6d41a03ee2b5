//! The server's configuration: every limit of `docs/api.md` as a command-line flag with a
//! `WAVRAD_`-prefixed environment variable and a safe default.

use crate::scene::Limits;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

#[derive(Debug, Clone, clap::Args)]
pub struct Config {
    /// Address to listen on.
    #[arg(long, env = "WAVRAD_ADDR", default_value = "127.0.0.1:8080")]
    pub addr: SocketAddr,
    /// Largest request body accepted, in bytes (larger: 413).
    #[arg(long, env = "WAVRAD_MAX_BODY_BYTES", default_value_t = 1 << 20)]
    pub max_body_bytes: usize,
    /// Largest model accepted by `POST /api/v1/import`, in bytes: the whole upload, every part
    /// of a multipart one together (larger: 413).
    #[arg(long, env = "WAVRAD_MAX_IMPORT_BYTES", default_value_t = 32 << 20)]
    pub max_import_bytes: usize,
    /// Most surfaces in one scene.
    #[arg(long, env = "WAVRAD_MAX_SURFACES", default_value_t = 64)]
    max_surfaces: usize,
    /// Most triangles in one scene (`triangle` and `mesh` surfaces together). A mesh's
    /// triangles are clustered, but in a cluttered scene each triangle is still linked with
    /// hundreds of its neighbours, so time and memory grow faster than this (benches/README.md).
    #[arg(long, env = "WAVRAD_MAX_TRIANGLES", default_value_t = 4096)]
    max_triangles: usize,
    /// Highest polynomial order.
    #[arg(long, env = "WAVRAD_MAX_ORDER", default_value_t = 6)]
    pub max_order: usize,
    /// Most cells per segment or quad side.
    #[arg(long, env = "WAVRAD_MAX_RESOLUTION", default_value_t = 256)]
    max_resolution: usize,
    /// Most unknowns of the projection system; the dense matrix is basis² × 8 bytes
    /// (at most 12 bytes × basis² at peak: 4096 → 192 MiB).
    #[arg(long, env = "WAVRAD_MAX_BASIS_FUNCTIONS", default_value_t = 4096)]
    pub max_basis_functions: usize,
    /// Most pixels of the main image (width × height).
    #[arg(long, env = "WAVRAD_MAX_IMAGE_PIXELS", default_value_t = 2048 * 2048)]
    max_image_pixels: usize,
    /// Jobs that may wait for a worker; one more answers 429 with Retry-After.
    #[arg(long, env = "WAVRAD_QUEUE_CAPACITY", default_value_t = 64)]
    pub queue_capacity: usize,
    /// Jobs solved at once (each on its own pool of a thread per core); 0 = one per core.
    #[arg(long, env = "WAVRAD_WORKERS", default_value_t = 0)]
    pub workers: usize,
    /// A solve running longer fails (e.g. 300, 300s, 5m, 2h).
    #[arg(long, env = "WAVRAD_JOB_TIMEOUT", default_value = "300s", value_parser = parse_positive_duration)]
    pub job_timeout: Duration,
    /// Longest wait of `POST /api/v1/render` for its result before answering 503.
    #[arg(long, env = "WAVRAD_SYNC_TIMEOUT", default_value = "30s", value_parser = parse_duration)]
    pub sync_timeout: Duration,
    /// How long finished jobs and their results are kept.
    #[arg(long, env = "WAVRAD_RESULT_TTL", default_value = "7d", value_parser = parse_duration)]
    pub result_ttl: Duration,
    /// Where job records and results are kept (created if missing).
    #[arg(long, env = "WAVRAD_DATA_DIR", default_value = "wavrad-data")]
    pub(super) data_dir: PathBuf,
    /// Most bytes of stored jobs (documents, statuses, results and images); beyond it the
    /// oldest finished jobs are forgotten first, never queued or running ones. 0: no limit.
    /// Bytes, or with a unit: 500MB, 2GiB.
    #[arg(long, env = "WAVRAD_MAX_STORE_BYTES", default_value = "1GiB", value_parser = parse_bytes)]
    pub max_store_bytes: u64,
    /// Memory the embedded store may use to cache its pages (bytes, or 64MiB…). Not used
    /// with `--database`.
    #[arg(long, env = "WAVRAD_STORE_CACHE_BYTES", default_value = "4MiB", value_parser = parse_bytes)]
    pub(super) store_cache_bytes: u64,
    /// HTTP requests handled at once; beyond this many, requests are answered 503 at once
    /// (the probes and /metrics are not counted).
    #[arg(long, env = "WAVRAD_MAX_CONCURRENT_REQUESTS", default_value_t = 256)]
    pub max_concurrent_requests: usize,
    /// On SIGTERM, how long running solves may take to finish before they are stopped and
    /// left queued for the next start.
    #[arg(long, env = "WAVRAD_SHUTDOWN_GRACE", default_value = "10s", value_parser = parse_duration)]
    pub(super) shutdown_grace: Duration,
    /// Keep jobs, results and files in this PostgreSQL database (`postgres://user:password@host:port/db`)
    /// instead of `data_dir`, shared with every other process given the same database.
    #[arg(long, env = "WAVRAD_DATABASE_URL", value_parser = parse_database_url)]
    pub(super) database: Option<String>,
    /// Most connections to the database at once.
    #[arg(long, env = "WAVRAD_DATABASE_POOL", default_value_t = 8, value_parser = parse_pool_size)]
    pub(super) database_pool: usize,
    /// With a database: how long a process's claim on a job holds without being renewed; a
    /// job whose process died runs again elsewhere after this. At least four poll intervals.
    #[arg(long, env = "WAVRAD_LEASE", default_value = "10s", value_parser = parse_positive_duration)]
    pub(super) lease: Duration,
    /// With a database: how often an idle process looks for queued jobs, leases and progress
    /// are written, and followed jobs (SSE) are read.
    #[arg(long, env = "WAVRAD_POLL_INTERVAL", default_value = "250ms", value_parser = parse_positive_duration)]
    pub(super) poll_interval: Duration,
}

impl Config {
    /// The limits a document is validated against.
    pub(super) fn limits(&self) -> Limits {
        Limits {
            max_surfaces: self.max_surfaces,
            max_triangles: self.max_triangles,
            max_order: self.max_order,
            max_resolution: self.max_resolution,
            max_basis_functions: self.max_basis_functions,
            max_image_pixels: self.max_image_pixels,
        }
    }

    /// Worker threads: `workers`, or one per core when 0.
    pub(super) fn worker_threads(&self) -> usize {
        if self.workers > 0 {
            self.workers
        } else {
            std::thread::available_parallelism().map_or(2, |n| n.get())
        }
    }

    /// Refuses settings that do not go together.
    pub fn check(&self) -> Result<(), String> {
        if self.database.is_some() && self.lease < self.poll_interval * 4 {
            return Err(format!(
                "--lease ({:?}) must be at least four times --poll-interval ({:?}): a lease is renewed every poll interval",
                self.lease, self.poll_interval
            ));
        }
        Ok(())
    }

    /// Every request is answered within this time (the synchronous render's limit plus slack).
    pub(super) fn request_timeout(&self) -> Duration {
        self.sync_timeout + Duration::from_secs(5)
    }

    /// The defaults of `--help`, with `data_dir` set (for tests and embedding).
    pub fn with_data_dir(data_dir: impl Into<PathBuf>) -> Config {
        use clap::Parser;
        #[derive(clap::Parser)]
        struct Wrapper {
            #[command(flatten)]
            config: Config,
        }
        let mut config = Wrapper::parse_from(["wavrad"]).config;
        config.data_dir = data_dir.into();
        config
    }
}

/// `"90"`, `"90s"`, `"250ms"`, `"5m"`, `"2h"`, `"7d"`.
fn parse_duration(text: &str) -> Result<Duration, String> {
    let text = text.trim();
    let split = text
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(text.len());
    let (number, unit) = text.split_at(split);
    let value: f64 = number
        .parse()
        .map_err(|_| format!("not a duration: {text:?}"))?;
    let seconds = match unit.trim() {
        "" | "s" => value,
        "ms" => value / 1e3,
        "m" => value * 60.0,
        "h" => value * 3600.0,
        "d" => value * 86400.0,
        other => return Err(format!("unknown unit {other:?} (use ms, s, m, h or d)")),
    };
    Duration::try_from_secs_f64(seconds).map_err(|e| e.to_string())
}

/// A size in bytes: `"1048576"`, `"500kB"`, `"64MiB"`, `"2GB"`, `"1GiB"` (kB, MB, GB, TB are
/// powers of 1000, KiB, MiB, GiB, TiB of 1024; `B` alone is bytes).
fn parse_bytes(text: &str) -> Result<u64, String> {
    let text = text.trim();
    let split = text
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(text.len());
    let (number, unit) = text.split_at(split);
    let value: f64 = number
        .parse()
        .map_err(|_| format!("not a size: {text:?}"))?;
    let scale: f64 = match unit.trim() {
        "" | "B" => 1.0,
        "kB" | "KB" => 1e3,
        "MB" => 1e6,
        "GB" => 1e9,
        "TB" => 1e12,
        "KiB" => 1024.0,
        "MiB" => 1024.0 * 1024.0,
        "GiB" => 1024.0 * 1024.0 * 1024.0,
        "TiB" => 1024.0 * 1024.0 * 1024.0 * 1024.0,
        other => {
            return Err(format!(
                "unknown unit {other:?} (use B, kB, MB, GB, TB, KiB, MiB, GiB or TiB)"
            ))
        }
    };
    let bytes = (value * scale).round();
    if !(0.0..1.8e19).contains(&bytes) {
        return Err(format!("not a size: {text:?}"));
    }
    Ok(bytes as u64)
}

/// A PostgreSQL connection URL: `postgres://` or `postgresql://`.
fn parse_database_url(text: &str) -> Result<String, String> {
    let text = text.trim();
    if !(text.starts_with("postgres://") || text.starts_with("postgresql://")) {
        return Err("give a PostgreSQL URL: postgres://user:password@host:port/database".into());
    }
    Ok(text.to_string())
}

/// A pool size: 1 to 1000 connections.
fn parse_pool_size(text: &str) -> Result<usize, String> {
    match text.trim().parse::<usize>() {
        Ok(n) if (1..=1000).contains(&n) => Ok(n),
        _ => Err(format!("not a pool size from 1 to 1000: {text:?}")),
    }
}

/// [`parse_duration`], refusing zero (a job timeout of zero would fail every job).
fn parse_positive_duration(text: &str) -> Result<Duration, String> {
    let d = parse_duration(text)?;
    if d.is_zero() {
        return Err("must be longer than zero".into());
    }
    Ok(d)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations() {
        assert_eq!(parse_duration("90").unwrap(), Duration::from_secs(90));
        assert_eq!(parse_duration("250ms").unwrap(), Duration::from_millis(250));
        assert_eq!(parse_duration("5m").unwrap(), Duration::from_secs(300));
        assert_eq!(
            parse_duration("7d").unwrap(),
            Duration::from_secs(7 * 86400)
        );
        assert!(parse_duration("soon").is_err());
        assert!(parse_duration("5y").is_err());
    }

    #[test]
    fn sizes() {
        assert_eq!(parse_bytes("1048576").unwrap(), 1 << 20);
        assert_eq!(parse_bytes("64MiB").unwrap(), 64 << 20);
        assert_eq!(parse_bytes("1GiB").unwrap(), 1 << 30);
        assert_eq!(parse_bytes("500MB").unwrap(), 500_000_000);
        assert_eq!(parse_bytes("1.5kB").unwrap(), 1500);
        assert_eq!(parse_bytes("0").unwrap(), 0);
        assert!(parse_bytes("lots").is_err());
        assert!(parse_bytes("5XB").is_err());
        assert!(parse_bytes("-1").is_err());
    }

    #[test]
    fn a_job_timeout_of_zero_is_refused() {
        assert!(parse_positive_duration("0s").is_err());
        assert!(parse_positive_duration("0").is_err());
        assert_eq!(
            parse_positive_duration("1ms").unwrap(),
            Duration::from_millis(1)
        );
    }

    #[test]
    fn database_settings_are_checked() {
        assert!(parse_database_url("mysql://x").is_err());
        assert!(parse_database_url("postgres://u@127.0.0.1/db").is_ok());
        let mut c = Config::with_data_dir("/tmp/x");
        c.database = Some("postgres://u@127.0.0.1/db".into());
        assert!(c.check().is_ok());
        c.lease = Duration::from_millis(500);
        assert!(c.check().unwrap_err().contains("--lease"));
    }

    #[test]
    fn defaults_parse() {
        let c = Config::with_data_dir("/tmp/x");
        assert_eq!(c.addr.to_string(), "127.0.0.1:8080");
        assert_eq!(c.limits().max_basis_functions, 4096);
        assert_eq!(c.max_store_bytes, 1 << 30);
        assert_eq!(c.store_cache_bytes, 4 << 20);
    }
}
