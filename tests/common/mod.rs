//! Helpers shared by the integration tests: configurations, documents and solvers that can be
//! told to be slow or to panic.
#![allow(dead_code)]

use serde_json::{json, Value};
use std::sync::Arc;
use std::time::Duration;
use wavrad::job::JobError;
use wavrad::progress::{Phase, Progress};
use wavrad::server::queue::{JobState, JobStatus, SolveFn};
use wavrad::server::{AppState, Config};

pub fn scene(name: &str) -> Value {
    let path = format!("{}/scenes/{name}.json", env!("CARGO_MANIFEST_DIR"));
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// flatland-parallel under another name (another document, so another job).
pub fn named(name: &str) -> Value {
    let mut doc = scene("flatland-parallel");
    doc["scene"]["name"] = json!(name);
    doc
}

pub fn config(dir: &std::path::Path) -> Config {
    let mut c = Config::with_data_dir(dir);
    c.workers = 2;
    c.queue_capacity = 8;
    c.sync_timeout = Duration::from_secs(20);
    c
}

/// The real solver, except for scenes named `slow …` (reports progress and waits for a
/// cancel, for up to 30 s, then solves), `busy …` (the same, but busy in parallel loops on
/// its pool the whole time, as a big solve is) and `panic …` (panics).
pub fn test_solver() -> SolveFn {
    Arc::new(|job, progress: &dyn Progress| {
        let name = job.scene.name.clone().unwrap_or_default();
        if name.starts_with("panic") {
            panic!("deliberate panic for {name}");
        }
        // `slow` sleeps between its checks, `busy` keeps its pool's threads at work
        let busy = name.starts_with("busy");
        if busy || name.starts_with("slow") {
            let start = std::time::Instant::now();
            while start.elapsed() < Duration::from_secs(30) {
                progress.report(Phase::Solve, start.elapsed().as_secs_f64() / 30.0);
                if progress.cancelled() {
                    return Err(JobError::Cancelled);
                }
                if busy {
                    // twenty seconds of small tasks, as in a solve's loop over matrix rows
                    use rayon::prelude::*;
                    (0..40_000).into_par_iter().for_each(|_| {
                        if !progress.cancelled() {
                            std::thread::sleep(Duration::from_millis(1));
                        }
                    });
                } else {
                    std::thread::sleep(Duration::from_millis(5));
                }
            }
        }
        wavrad::job::run(job, progress)
    })
}

pub fn state(config: Config) -> AppState {
    AppState::start(
        config,
        test_solver(),
        tokio_util::sync::CancellationToken::new(),
    )
    .unwrap()
}

/// Waits (on the job's watch channel, not by polling) until the job is in `pred`'s state.
pub async fn wait_until(state: &AppState, id: &str, pred: impl Fn(JobState) -> bool) -> JobStatus {
    let mut rx = state.queue.get(id).expect("job known").subscribe();
    let s = tokio::time::timeout(Duration::from_secs(60), rx.wait_for(|s| pred(s.state)))
        .await
        .expect("in time")
        .expect("job still known")
        .clone();
    s
}
