//! Results survive the server process: jobs are queued on a real `wavrad serve`, the process is
//! killed (SIGKILL) or stopped (SIGTERM), started again on the same data_dir, and every job
//! completes; a result finished before the stop is served unchanged after it.

mod listening;

use serde_json::{json, Value};
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

struct Server {
    child: Child,
    base: String,
    /// What the server logged (stderr), read as it comes.
    log: std::sync::Arc<std::sync::Mutex<String>>,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn start(dir: &Path) -> Server {
    start_with(dir, &[])
}

fn start_with(dir: &Path, extra: &[&str]) -> Server {
    let mut child = Command::new(env!("CARGO_BIN_EXE_wavrad"))
        .args([
            "serve",
            "--addr",
            "127.0.0.1:0",
            "--workers",
            "1",
            "--shutdown-grace",
            "0s",
        ])
        .args(extra)
        .arg("--data-dir")
        .arg(dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let log = std::sync::Arc::new(std::sync::Mutex::new(String::new()));
    let stderr = child.stderr.take().unwrap();
    let sink = log.clone();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let mut log = sink.lock().unwrap();
            log.push_str(&line);
            log.push('\n');
        }
    });
    let url = listening::base_url(&mut child);
    Server {
        child,
        base: url,
        log,
    }
}

fn doc(i: usize, resolution: usize) -> Value {
    let text = std::fs::read_to_string(format!(
        "{}/scenes/flatland-parallel.json",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap();
    let mut d: Value = serde_json::from_str(&text).unwrap();
    d["scene"]["name"] = json!(format!("restart {i}"));
    d["solver"]["resolution"] = json!(resolution);
    d["solver"]["order"] = json!(2);
    d
}

async fn post(http: &reqwest::Client, base: &str, d: &Value) -> String {
    let res = http
        .post(format!("{base}/api/v1/jobs"))
        .header("content-type", "application/json")
        .body(d.to_string())
        .send()
        .await
        .unwrap();
    assert!(
        res.status() == 202 || res.status() == 200,
        "{}",
        res.status()
    );
    res.json::<Value>().await.unwrap()["id"]
        .as_str()
        .unwrap()
        .to_string()
}

async fn state(http: &reqwest::Client, base: &str, id: &str) -> String {
    let s: Value = http
        .get(format!("{base}/api/v1/jobs/{id}"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    s["state"].as_str().unwrap_or("unknown").to_string()
}

async fn wait_for(
    http: &reqwest::Client,
    base: &str,
    id: &str,
    wanted: &[&str],
    limit: Duration,
) -> String {
    let t = Instant::now();
    loop {
        let s = state(http, base, id).await;
        if wanted.contains(&s.as_str()) {
            return s;
        }
        assert!(t.elapsed() < limit, "job {id} is still {s}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

async fn result(http: &reqwest::Client, base: &str, id: &str) -> Vec<u8> {
    let res = http
        .get(format!("{base}/api/v1/jobs/{id}/result"))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 200);
    res.bytes().await.unwrap().to_vec()
}

async fn survive(signal: &str) {
    let dir = tempfile::tempdir().unwrap();
    let http = reqwest::Client::new();
    let mut server = start(dir.path());
    let first = post(&http, &server.base, &doc(0, 16)).await;
    wait_for(
        &http,
        &server.base,
        &first,
        &["succeeded"],
        Duration::from_secs(60),
    )
    .await;
    let before = result(&http, &server.base, &first).await;
    let image_before = http
        .get(format!("{}/api/v1/jobs/{first}/image.png", server.base))
        .send()
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();

    let mut ids = Vec::new();
    for i in 1..=4 {
        ids.push(post(&http, &server.base, &doc(i, 256)).await);
    }
    wait_for(
        &http,
        &server.base,
        &ids[0],
        &["running", "succeeded"],
        Duration::from_secs(60),
    )
    .await;
    // One worker, and three solves ahead of it: the last job is still waiting at the stop.
    assert_eq!(state(&http, &server.base, &ids[3]).await, "queued");
    let pid = server.child.id().to_string();
    let killed = Command::new("kill").args([signal, &pid]).status().unwrap();
    assert!(killed.success());
    let exit = server.child.wait().unwrap();
    if signal == "-TERM" {
        assert!(exit.success(), "a clean exit on SIGTERM: {exit:?}");
        // it says that it stops, and what became of the running and the queued jobs
        let deadline = Instant::now() + Duration::from_secs(5);
        let said = |what: &str| server.log.lock().unwrap().contains(what);
        while !said("shut down:") && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(20));
        }
        let log = server.log.lock().unwrap().clone();
        assert!(
            log.contains("shutting down: no new requests or jobs are taken"),
            "{log}"
        );
        assert!(
            log.contains("1 stopped and left queued for the next start")
                && log.contains("queued job(s) kept"),
            "{log}"
        );
    }
    drop(server);

    let server = start(dir.path());
    assert_eq!(
        result(&http, &server.base, &first).await,
        before,
        "the finished result is kept"
    );
    let image_after = http
        .get(format!("{}/api/v1/jobs/{first}/image.png", server.base))
        .send()
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();
    assert_eq!(image_before, image_after);
    for id in &ids {
        let s = wait_for(
            &http,
            &server.base,
            id,
            &["succeeded", "failed"],
            Duration::from_secs(300),
        )
        .await;
        assert_eq!(s, "succeeded");
        let r: Value = serde_json::from_slice(&result(&http, &server.base, id).await).unwrap();
        assert_eq!(r["solver"]["resolution"], 256);
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn jobs_survive_a_killed_server() {
    survive("-KILL").await;
}

#[tokio::test(flavor = "multi_thread")]
async fn jobs_survive_a_sigterm() {
    survive("-TERM").await;
}

#[tokio::test(flavor = "multi_thread")]
async fn a_render_answered_503_survives_a_killed_server() {
    // POST /api/v1/render writes its job's record lazily (its client waits for the answer);
    // once it answers 503 and points to the job, the job is the client's to follow, and a
    // crash right after must not lose it
    let dir = tempfile::tempdir().unwrap();
    let http = reqwest::Client::new();
    // a wait of 1 ms that no solve can beat: the job below takes 0.14 s alone on this machine,
    // under the 200 ms this test waited before, which it beat whenever nothing else ran
    let mut server = start_with(dir.path(), &["--sync-timeout", "1ms"]);
    let res = http
        .post(format!("{}/api/v1/render", server.base))
        .header("content-type", "application/json")
        .body(doc(9, 256).to_string())
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 503);
    let location = res.headers()["location"].to_str().unwrap().to_string();
    let id = location.rsplit('/').next().unwrap().to_string();
    let killed = Command::new("kill")
        .args(["-KILL", &server.child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    server.child.wait().unwrap();
    drop(server);

    let server = start(dir.path());
    let known = http
        .get(format!("{}/api/v1/jobs/{id}", server.base))
        .send()
        .await
        .unwrap()
        .status();
    assert_eq!(known, 200, "the job answered 503 is known after the crash");
    let s = wait_for(
        &http,
        &server.base,
        &id,
        &["succeeded", "failed"],
        Duration::from_secs(300),
    )
    .await;
    assert_eq!(s, "succeeded");
}
