//! More than one process: the cost of keeping jobs in PostgreSQL instead of the embedded store
//! for a job of about 50 ms (`POST /api/v1/render`, one at a time, the two stores in turns,
//! median of 100 each), and small-job
//! throughput with one, two and three `wavrad serve` processes on one database (jobs posted
//! round-robin with `POST /api/v1/jobs`, timed until all have succeeded). Needs a PostgreSQL
//! cluster: `WAVRAD_BENCH_DATABASE_URL` or `WAVRAD_TEST_DATABASE_URL` (`eval "$(.ci/postgres)"`);
//! each run makes databases of its own there. Figures: `benches/README.md`.
//!
//! `cargo bench --bench shared`; `WAVRAD_BENCH_LEASE` and `WAVRAD_BENCH_POLL` (default 10s and
//! 250ms, the server's defaults) set the processes' lease and poll interval.

#[path = "../tests/listening/mod.rs"]
mod listening;

use serde_json::{json, Value};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

struct Server {
    child: Child,
    base: String,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn start(database: Option<&str>, dir: &std::path::Path, workers: usize) -> Server {
    let lease = std::env::var("WAVRAD_BENCH_LEASE").unwrap_or_else(|_| "10s".into());
    let poll = std::env::var("WAVRAD_BENCH_POLL").unwrap_or_else(|_| "250ms".into());
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_wavrad"));
    cmd.args(["serve", "--addr", "127.0.0.1:0", "--queue-capacity", "1000"])
        .args(["--workers", &workers.to_string(), "--lease", &lease])
        .args(["--poll-interval", &poll])
        .arg("--data-dir")
        .arg(dir)
        .env("WAVRAD_LOG", "warn")
        .stdout(Stdio::piped())
        .stderr(Stdio::null());
    if let Some(url) = database {
        cmd.args(["--database", url]);
    }
    let mut child = cmd.spawn().unwrap();
    let base = listening::base_url(&mut child);
    Server { child, base }
}

fn doc(name: &str, order: usize, resolution: usize) -> String {
    let mut d: Value =
        serde_json::from_str(include_str!("../scenes/flatland-parallel.json")).unwrap();
    d["scene"]["name"] = json!(name);
    d["solver"]["order"] = json!(order);
    d["solver"]["resolution"] = json!(resolution);
    d.to_string()
}

async fn fresh_database(cluster: &str, name: &str) -> String {
    let (client, connection) = tokio_postgres::connect(cluster, tokio_postgres::NoTls)
        .await
        .unwrap();
    tokio::spawn(connection);
    for sql in [
        format!("DROP DATABASE IF EXISTS {name}"),
        format!("CREATE DATABASE {name}"),
    ] {
        client.batch_execute(&sql).await.unwrap();
    }
    format!("{}/{name}", cluster.rsplit_once('/').unwrap().0)
}

async fn wait_ready(http: &reqwest::Client, s: &Server) {
    for _ in 0..600 {
        if let Ok(r) = http.get(format!("{}/readyz", s.base)).send().await {
            if r.status() == 200 {
                return;
            }
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    panic!("{} not ready", s.base);
}

/// Seconds of one synchronous render of a distinct ~50 ms document.
async fn render_once(http: &reqwest::Client, s: &Server, name: &str) -> f64 {
    let body = doc(name, 3, 64);
    let t = Instant::now();
    let res = http
        .post(format!("{}/api/v1/render", s.base))
        .header("content-type", "application/json")
        .body(body)
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 200);
    res.bytes().await.unwrap();
    t.elapsed().as_secs_f64()
}

/// Median seconds of `n` renders on each of two servers, taken in turns (a, b, b, a, a, b, …)
/// so that the machine's drift over the run (its load, its disk's flushes) falls on both
/// alike; the first two of each warm up.
async fn render_medians(
    http: &reqwest::Client,
    a: &Server,
    b: &Server,
    tag: &str,
    n: usize,
) -> (f64, f64) {
    let (mut ta, mut tb) = (vec![], vec![]);
    for i in 0..n + 2 {
        let first_a = i % 2 == 0;
        for turn in 0..2 {
            let on_a = (turn == 0) == first_a;
            let (s, times) = if on_a { (a, &mut ta) } else { (b, &mut tb) };
            let t = render_once(http, s, &format!("{tag} {} {i}", u8::from(on_a))).await;
            if i >= 2 {
                times.push(t);
            }
        }
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    (median(ta), median(tb))
}

/// Jobs per second: `n` small jobs posted round-robin, until all have succeeded.
async fn throughput(http: &reqwest::Client, servers: &[Server], tag: &str, n: usize) -> f64 {
    let t = Instant::now();
    let mut ids = vec![];
    for i in 0..n {
        let s = &servers[i % servers.len()];
        let res = http
            .post(format!("{}/api/v1/jobs", s.base))
            .header("content-type", "application/json")
            .body(doc(&format!("{tag} {i}"), 1, 8))
            .send()
            .await
            .unwrap();
        assert_eq!(res.status(), 202);
        let v: Value = res.json().await.unwrap();
        ids.push(v["id"].as_str().unwrap().to_string());
    }
    for (i, id) in ids.iter().enumerate() {
        let s = &servers[i % servers.len()];
        loop {
            let v: Value = http
                .get(format!("{}/api/v1/jobs/{id}", s.base))
                .send()
                .await
                .unwrap()
                .json()
                .await
                .unwrap();
            if v["state"] == "succeeded" {
                break;
            }
            assert_ne!(v["state"], "failed");
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    }
    n as f64 / t.elapsed().as_secs_f64()
}

fn main() {
    let Some(cluster) = ["WAVRAD_BENCH_DATABASE_URL", "WAVRAD_TEST_DATABASE_URL"]
        .iter()
        .find_map(|v| std::env::var(v).ok())
    else {
        eprintln!("set WAVRAD_BENCH_DATABASE_URL (or eval \"$(.ci/postgres)\"): no figures");
        return;
    };
    // `cargo bench` passes --bench; `cargo test --benches` runs it once as a check
    let quick = !std::env::args().any(|a| a == "--bench");
    let (renders, jobs) = if quick { (3, 12) } else { (100, 150) };
    let rt = tokio::runtime::Runtime::new().unwrap();
    rt.block_on(async {
        let http = reqwest::Client::new();
        let dir = tempfile::tempdir().unwrap();
        let run = std::process::id();
        // overhead on a ~50 ms job, one worker each
        let embedded = start(None, &dir.path().join("e"), 1);
        let url = fresh_database(&cluster, &format!("wavrad_bench_{run}_o")).await;
        let pg = start(Some(&url), &dir.path().join("p"), 1);
        wait_ready(&http, &embedded).await;
        wait_ready(&http, &pg).await;
        let (e, p) = render_medians(&http, &embedded, &pg, &format!("o{run}"), renders).await;
        drop(embedded);
        drop(pg);
        println!(
            "50 ms job, POST /api/v1/render, median of {renders}: embedded {:.1} ms, PostgreSQL {:.1} ms ({:+.1} %)",
            e * 1e3,
            p * 1e3,
            (p / e - 1.0) * 100.0
        );
        // small-job throughput, one worker per process
        let embedded = start(None, &dir.path().join("t"), 1);
        wait_ready(&http, &embedded).await;
        let rate = throughput(&http, std::slice::from_ref(&embedded), &format!("te{run}"), jobs).await;
        drop(embedded);
        println!("small jobs, embedded store, 1 process: {rate:.0} jobs/s");
        for processes in 1..=3 {
            let url = fresh_database(&cluster, &format!("wavrad_bench_{run}_{processes}")).await;
            let servers: Vec<Server> = (0..processes)
                .map(|i| start(Some(&url), &dir.path().join(format!("s{i}")), 1))
                .collect();
            for s in &servers {
                wait_ready(&http, s).await;
            }
            let rate = throughput(&http, &servers, &format!("t{processes}_{run}"), jobs).await;
            println!("small jobs, PostgreSQL, {processes} process(es): {rate:.0} jobs/s");
        }
    });
}
