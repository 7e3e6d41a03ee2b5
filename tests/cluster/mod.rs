//! `wavrad serve` processes sharing one PostgreSQL database, for the tests of `tests/shared.rs`
//! and `tests/shared_restart.rs`.
#![allow(dead_code)]

use serde_json::{json, Value};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

pub struct Server {
    pub child: Child,
    pub base: String,
    pub log: std::path::PathBuf,
    _dir: tempfile::TempDir,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Server {
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// SIGKILL, as a lost machine.
    pub fn kill9(&mut self) {
        self.child.kill().unwrap();
        self.child.wait().unwrap();
    }

    pub fn log_text(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    /// `wavrad_solve_seconds_count` of this process: the solves it ran to their end.
    pub async fn solves(&self, http: &reqwest::Client) -> u64 {
        let text = http
            .get(format!("{}/metrics", self.base))
            .send()
            .await
            .unwrap()
            .text()
            .await
            .unwrap();
        text.lines()
            .find_map(|l| l.strip_prefix("wavrad_solve_seconds_count "))
            .map_or(0, |v| v.trim().parse().unwrap())
    }

    pub async fn ready(&self, http: &reqwest::Client) -> u16 {
        match http.get(format!("{}/readyz", self.base)).send().await {
            Ok(r) => r.status().as_u16(),
            Err(_) => 0,
        }
    }
}

/// Starts `wavrad serve` on `database` with one worker, a short lease (2 s unless `extra`
/// sets one) and poll interval (100 ms), and waits until it is ready.
pub async fn start(database: &str, extra: &[&str]) -> Server {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("stderr.log");
    let mut child = Command::new(env!("CARGO_BIN_EXE_wavrad"))
        .args([
            "serve",
            "--addr",
            "127.0.0.1:0",
            "--workers",
            "1",
            "--shutdown-grace",
            "0s",
            "--poll-interval",
            "100ms",
            // the long jobs of the tests
            "--max-resolution",
            "512",
            "--max-basis-functions",
            "6144",
            "--database",
            database,
        ])
        .args(extra)
        .args(if extra.contains(&"--lease") {
            &[][..]
        } else {
            &["--lease", "2s"][..]
        })
        .arg("--data-dir")
        .arg(dir.path().join("unused"))
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(&log).unwrap())
        .spawn()
        .unwrap();
    let base = crate::listening::base_url(&mut child);
    let server = Server {
        child,
        base,
        log,
        _dir: dir,
    };
    let http = reqwest::Client::new();
    let start = Instant::now();
    while server.ready(&http).await != 200 {
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "not ready: {}",
            server.log_text()
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    server
}

/// flatland-parallel under another name: a job of some tens of milliseconds.
pub fn small(name: &str) -> Value {
    let mut d: Value =
        serde_json::from_str(include_str!("../../scenes/flatland-parallel.json")).unwrap();
    d["scene"]["name"] = json!(name);
    d
}

/// flatland-occluded at `resolution` cells, order 2: seconds (256: about 3 s on 2 cores,
/// 512: about 11 s), reporting progress all along.
pub fn long(name: &str, resolution: usize) -> Value {
    let mut d: Value =
        serde_json::from_str(include_str!("../../scenes/flatland-occluded.json")).unwrap();
    d["scene"]["name"] = json!(name);
    d["solver"] =
        json!({"order": 2, "resolution": resolution, "tolerance": 1e-14, "max_iterations": 100000});
    d
}

/// Posts a document: (status, the job's status document).
pub async fn post(http: &reqwest::Client, base: &str, doc: &Value) -> (u16, Value) {
    let res = http
        .post(format!("{base}/api/v1/jobs"))
        .header("content-type", "application/json")
        .body(doc.to_string())
        .send()
        .await
        .unwrap();
    let code = res.status().as_u16();
    (code, res.json().await.unwrap())
}

pub async fn status(http: &reqwest::Client, base: &str, id: &str) -> (u16, Value) {
    let res = http
        .get(format!("{base}/api/v1/jobs/{id}"))
        .send()
        .await
        .unwrap();
    let code = res.status().as_u16();
    (code, res.json().await.unwrap_or(Value::Null))
}

/// Waits for a job to be in one of `states` (asked from `base`).
pub async fn wait_for(
    http: &reqwest::Client,
    base: &str,
    id: &str,
    states: &[&str],
    limit: Duration,
) -> Value {
    let start = Instant::now();
    loop {
        let (code, s) = status(http, base, id).await;
        if code == 200 && states.iter().any(|st| s["state"] == *st) {
            return s;
        }
        assert!(
            start.elapsed() < limit,
            "job {id} not {states:?} after {limit:?}: {code} {s}"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

pub async fn bytes(http: &reqwest::Client, url: String) -> Vec<u8> {
    let res = http.get(&url).send().await.unwrap();
    assert_eq!(res.status(), 200, "{url}");
    res.bytes().await.unwrap().to_vec()
}

/// The process (by pid) that holds the job in the database now, if any.
pub async fn owner_pid(db: &tokio_postgres::Client, id: &str) -> Option<u32> {
    let row = db
        .query_opt(
            "SELECT owner FROM wavrad_jobs WHERE id = $1 AND state = 'running'",
            &[&id],
        )
        .await
        .unwrap()?;
    let owner: Option<String> = row.get(0);
    owner?.split(':').nth(1)?.parse().ok()
}

/// The process (by pid) that claims the job, waiting for the claim up to 30 s.
pub async fn claimer_pid(db: &tokio_postgres::Client, id: &str) -> u32 {
    let wait = std::time::Instant::now();
    loop {
        if let Some(pid) = owner_pid(db, id).await {
            return pid;
        }
        assert!(
            wait.elapsed() < std::time::Duration::from_secs(30),
            "{id} never claimed"
        );
        tokio::time::sleep(std::time::Duration::from_millis(20)).await;
    }
}
