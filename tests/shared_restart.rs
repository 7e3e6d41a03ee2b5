//! The database restarted under two `wavrad serve` processes while jobs run: `readyz` answers
//! 503 while it is down and 200 again after, the processes reconnect by themselves, and every
//! job completes, each claimed once (the outage is shorter than the lease, so no solve was
//! taken over, and none ran twice at once). A test binary of its own: it stops the cluster
//! that the other PostgreSQL tests use.

mod cluster;
mod listening;
mod postgres;

use cluster::{long, post, small, start, wait_for};
use std::time::{Duration, Instant};

/// The cluster is down while this lives; started again when it goes, even at a failure, so
/// that the tests after this one find it.
struct Down;

impl Drop for Down {
    fn drop(&mut self) {
        postgres::pg_ctl("start");
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn processes_ride_out_a_database_restart() {
    let url = postgres::fresh_database().await;
    let lease = ["--lease", "20s"];
    let servers = [start(&url, &lease).await, start(&url, &lease).await];
    let http = reqwest::Client::new();
    let mut ids = vec![];
    // one long job per process running across the outage, and small ones queued behind them
    for (i, doc) in [
        long("restart long 0", 256),
        long("restart long 1", 256),
        small("restart small 0"),
        small("restart small 1"),
        small("restart small 2"),
        small("restart small 3"),
    ]
    .iter()
    .enumerate()
    {
        let (code, s) = post(&http, &servers[i % 2].base, doc).await;
        assert_eq!(code, 202, "{s}");
        ids.push(s["id"].as_str().unwrap().to_string());
    }
    wait_for(
        &http,
        &servers[0].base,
        &ids[0],
        &["running"],
        Duration::from_secs(30),
    )
    .await;
    postgres::pg_ctl("stop");
    let down = Down;
    let stopped = Instant::now();
    for s in &servers {
        while s.ready(&http).await != 503 {
            assert!(
                stopped.elapsed() < Duration::from_secs(10),
                "readyz still 200 with the database down"
            );
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }
    // a queued job's status cannot be read now: 503 with Retry-After, not a hang or a 500
    let res = http
        .get(format!("{}/api/v1/jobs/{}", servers[1].base, ids[5]))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 503);
    assert!(res.headers().contains_key("retry-after"));
    tokio::time::sleep(Duration::from_secs(1)).await;
    drop(down);
    let started = Instant::now();
    for s in &servers {
        while s.ready(&http).await != 200 {
            assert!(
                started.elapsed() < Duration::from_secs(15),
                "not ready again after the restart: {}",
                s.log_text()
            );
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }
    for id in &ids {
        let s = wait_for(
            &http,
            &servers[1].base,
            id,
            &["succeeded", "failed"],
            Duration::from_secs(180),
        )
        .await;
        assert_eq!(s["state"], "succeeded", "{s}");
    }
    let db = postgres::connect(&url).await;
    for id in &ids {
        let claims: i32 = db
            .query_one("SELECT claims FROM wavrad_jobs WHERE id = $1", &[id])
            .await
            .unwrap()
            .get(0);
        assert_eq!(claims, 1, "job {id}");
    }
    let solves = servers[0].solves(&http).await + servers[1].solves(&http).await;
    assert_eq!(solves, 6);
}
