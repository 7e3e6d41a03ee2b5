//! One real server on a loopback port (port 0), the byte-identity of images, and the command
//! line (`render`, `validate`).

mod common;

use common::*;
use futures_util::StreamExt;
use serde_json::{json, Value};
use std::process::Command;
use std::time::Duration;
use wavrad::server::queue::JobState;
use wavrad::server::AppState;

struct Running {
    base: String,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    done: tokio::task::JoinHandle<std::io::Result<()>>,
}

async fn serve(state: AppState) -> Running {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let base = format!("http://{}", listener.local_addr().unwrap());
    let (tx, rx) = tokio::sync::oneshot::channel::<()>();
    let done = tokio::spawn(wavrad::server::run_with(
        listener,
        state,
        async move {
            let _ = rx.await;
        },
        Duration::from_millis(200),
    ));
    Running {
        base,
        stop: Some(tx),
        done,
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn a_real_server_answers_over_tcp_and_shuts_down_with_an_open_event_stream() {
    let dir = tempfile::tempdir().unwrap();
    let state = state(config(dir.path()));
    let mut server = serve(state.clone()).await;
    let http = reqwest::Client::new();
    let base = &server.base;

    let res = http.get(format!("{base}/healthz")).send().await.unwrap();
    assert_eq!(res.status(), 200);

    let res = http
        .post(format!("{base}/api/v1/render"))
        .header("content-type", "application/json")
        .body(scene("flatland-parallel").to_string())
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 200);
    assert_eq!(res.headers()["content-type"], "image/png");
    let png = res.bytes().await.unwrap();
    assert_eq!(&png[..4], b"\x89PNG");

    let res = http
        .post(format!("{base}/api/v1/jobs"))
        .header("content-type", "text/plain")
        .body("{}")
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 415);
    assert_eq!(res.headers()["content-type"], "application/problem+json");

    // Follow a job's events to its end over the socket.
    let res = http
        .post(format!("{base}/api/v1/jobs"))
        .header("content-type", "application/json")
        .body(named("over tcp").to_string())
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 202);
    let status: Value = res.json().await.unwrap();
    let events = http
        .get(format!(
            "{base}{}",
            status["links"]["events"].as_str().unwrap()
        ))
        .send()
        .await
        .unwrap();
    assert_eq!(events.status(), 200);
    let text = String::from_utf8(events.bytes().await.unwrap().to_vec()).unwrap();
    assert!(text.contains("\"state\":\"succeeded\""), "{text}");
    let result: Value = http
        .get(format!(
            "{base}{}",
            status["links"]["result"].as_str().unwrap()
        ))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(result["surfaces"][0]["name"], "bottom");

    // An open SSE stream of a job that would run for 30 s does not hold up the shutdown, and
    // the stopped job stays queued for the next start.
    let res = http
        .post(format!("{base}/api/v1/jobs"))
        .header("content-type", "application/json")
        .body(named("slow at shutdown").to_string())
        .send()
        .await
        .unwrap();
    let slow: Value = res.json().await.unwrap();
    let slow_id = slow["id"].as_str().unwrap().to_string();
    wait_until(&state, &slow_id, |s| s == JobState::Running).await;
    let mut stream = http
        .get(format!("{base}/api/v1/jobs/{slow_id}/events"))
        .send()
        .await
        .unwrap()
        .bytes_stream();
    assert!(stream.next().await.is_some(), "a first event");
    let t = std::time::Instant::now();
    server.stop.take().unwrap().send(()).unwrap();
    tokio::time::timeout(Duration::from_secs(8), &mut server.done)
        .await
        .expect("shut down in time")
        .unwrap()
        .unwrap();
    assert!(t.elapsed() < Duration::from_secs(8));
    while let Some(chunk) = tokio::time::timeout(Duration::from_secs(2), stream.next())
        .await
        .expect("stream ends")
    {
        if chunk.is_err() {
            break;
        }
    }
    drop(state);
    tokio::time::sleep(Duration::from_millis(100)).await;

    // Start again on the same data_dir: finished jobs are served, the stopped one runs again.
    let mut c = config(dir.path());
    c.workers = 1;
    // The old store closes when the last handle of the old server goes (its solver thread
    // lets go right after the stop).
    let mut tries = 0;
    let again = loop {
        match wavrad::server::AppState::start(
            c.clone(),
            test_solver(),
            tokio_util::sync::CancellationToken::new(),
        ) {
            Ok(s) => break s,
            Err(e) if tries < 50 => {
                tries += 1;
                let _ = e;
                tokio::time::sleep(Duration::from_millis(100)).await;
            }
            Err(e) => panic!("reopen: {e}"),
        }
    };
    assert_eq!(
        again
            .queue
            .get(status["id"].as_str().unwrap())
            .unwrap()
            .status()
            .state,
        JobState::Succeeded
    );
    let restored = again
        .queue
        .get(&slow_id)
        .expect("the stopped job is known")
        .status();
    assert!(
        matches!(restored.state, JobState::Queued | JobState::Running),
        "{:?}",
        restored.state
    );
    again.queue.delete(&slow_id).unwrap();
}

async fn all_images(doc: &Value) -> Vec<(String, Vec<u8>)> {
    let dir = tempfile::tempdir().unwrap();
    let state = state(config(dir.path()));
    let entry = match state.queue.submit(
        doc.clone(),
        wavrad::scene::parse_value(doc, &wavrad::scene::Limits::default()).unwrap(),
        true,
    ) {
        Ok(wavrad::server::queue::Submitted::New(e)) => e,
        _ => panic!("a new job"),
    };
    let done = wait_until(&state, &entry.id, |s| s.is_final()).await;
    assert_eq!(done.state, JobState::Succeeded);
    let mut names = vec![
        "image.png".to_string(),
        "sparsity.png".into(),
        "coefficients.png".into(),
    ];
    names.extend(
        done.links
            .surfaces
            .keys()
            .map(|s| format!("surfaces/{s}.png")),
    );
    names
        .into_iter()
        .map(|n| {
            let bytes = state.queue.file(&entry.id, &n).unwrap().unwrap();
            (n, bytes)
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread")]
async fn the_same_document_gives_byte_identical_pngs_and_the_command_line_writes_the_same() {
    for name in ["flatland-parallel", "fredholm-degenerate", "plates-3d"] {
        let mut doc = scene(name);
        if name == "plates-3d" {
            // Small enough to be quick wherever 3D solves are available.
            doc["solver"] = json!({"order": 0, "resolution": 4, "basis": "scaling"});
        }
        let parsed = wavrad::scene::parse_value(&doc, &wavrad::scene::Limits::default()).unwrap();
        if wavrad::job::run(&parsed, &wavrad::progress::Silent).is_err() {
            continue; // this build does not solve this kind
        }
        let first = all_images(&doc).await;
        let second = all_images(&doc).await;
        assert_eq!(first.len(), second.len());
        for ((n1, b1), (n2, b2)) in first.iter().zip(&second) {
            assert_eq!(n1, n2);
            assert!(b1 == b2, "{name}: {n1} differs between two runs");
        }
        let out = tempfile::tempdir().unwrap();
        let docfile = out.path().join("doc.json");
        std::fs::write(&docfile, doc.to_string()).unwrap();
        let status = Command::new(env!("CARGO_BIN_EXE_wavrad"))
            .args([
                "render",
                docfile.to_str().unwrap(),
                "--out",
                out.path().join("out").to_str().unwrap(),
            ])
            .status()
            .unwrap();
        assert!(status.success());
        for (n, bytes) in &first {
            let written = std::fs::read(out.path().join("out").join(n)).unwrap();
            assert!(
                &written == bytes,
                "{name}: {n} from the command line differs from the server's"
            );
        }
        let result: Value =
            serde_json::from_slice(&std::fs::read(out.path().join("out/result.json")).unwrap())
                .unwrap();
        assert_eq!(result["kind"], parsed.scene.kind.name());
    }
}

#[test]
fn validate_and_render_exit_codes() {
    let bin = env!("CARGO_BIN_EXE_wavrad");
    let dir = tempfile::tempdir().unwrap();
    let good = format!(
        "{}/scenes/flatland-parallel.json",
        env!("CARGO_MANIFEST_DIR")
    );
    let out = Command::new(bin)
        .args(["validate", &good])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0));

    let mut doc = scene("flatland-parallel");
    doc["scene"]["surfaces"][0]["reflectance"] = json!(2);
    doc["solver"]["basis"] = json!("nope");
    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, doc.to_string()).unwrap();
    let out = Command::new(bin)
        .args(["validate", bad.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(
        text.lines()
            .any(|l| l.starts_with("/scene/surfaces/0/reflectance: ")),
        "{text}"
    );
    assert!(
        text.lines().any(|l| l.starts_with("/solver/basis: ")),
        "{text}"
    );
    let out = Command::new(bin)
        .args([
            "render",
            bad.to_str().unwrap(),
            "--out",
            dir.path().join("o").to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));

    let missing = dir.path().join("missing.json");
    let out = Command::new(bin)
        .args(["validate", missing.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));

    // ρK has spectral radius 3: the iteration diverges.
    let diverging = json!({"scene": {"kind": "fredholm", "domain": [0, 1], "kernel": "3", "source": "1"},
        "solver": {"basis": "scaling", "order": 0, "resolution": 4}});
    let path = dir.path().join("diverging.json");
    std::fs::write(&path, diverging.to_string()).unwrap();
    let out = Command::new(bin)
        .args([
            "render",
            path.to_str().unwrap(),
            "--out",
            dir.path().join("d").to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(3),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    let out = Command::new(bin)
        .args(["serve", "--help"])
        .output()
        .unwrap();
    let help = String::from_utf8(out.stdout).unwrap();
    for flag in [
        "--addr",
        "--max-body-bytes",
        "--max-surfaces",
        "--max-order",
        "--max-resolution",
        "--max-basis-functions",
        "--max-image-pixels",
        "--queue-capacity",
        "--workers",
        "--job-timeout",
        "--sync-timeout",
        "--result-ttl",
        "--data-dir",
    ] {
        assert!(help.contains(flag), "{flag} missing from --help");
        let env = format!(
            "WAVRAD_{}",
            flag.trim_start_matches("--")
                .replace('-', "_")
                .to_uppercase()
        );
        assert!(help.contains(&env), "{env} missing from --help");
    }
}
