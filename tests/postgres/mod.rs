//! The PostgreSQL the tests use: `WAVRAD_TEST_DATABASE_URL` (a throwaway cluster that
//! `.ci/postgres` starts; `scripts/test` does). Each test gets a database of its own. Without
//! the variable the tests fail.
#![allow(dead_code)]

use std::sync::atomic::{AtomicUsize, Ordering};

/// The cluster's URL; a failure when it is not configured.
pub fn cluster() -> String {
    match std::env::var("WAVRAD_TEST_DATABASE_URL") {
        Ok(url) if !url.trim().is_empty() => url,
        _ => panic!(
            "the PostgreSQL tests need a cluster in WAVRAD_TEST_DATABASE_URL: run scripts/test, \
             which starts one, or eval \"$(.ci/postgres)\" first"
        ),
    }
}

/// A new, empty database on the cluster: its URL.
pub async fn fresh_database() -> String {
    static N: AtomicUsize = AtomicUsize::new(0);
    let cluster = cluster();
    let name = format!(
        "wavrad_test_{}_{}_{}",
        std::process::id(),
        N.fetch_add(1, Ordering::SeqCst),
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .subsec_nanos()
    );
    let (client, connection) = tokio_postgres::connect(&cluster, tokio_postgres::NoTls)
        .await
        .unwrap_or_else(|e| panic!("cannot reach the test cluster {cluster}: {e}"));
    tokio::spawn(connection);
    client
        .batch_execute(&format!("CREATE DATABASE {name}"))
        .await
        .unwrap();
    let (base, _) = cluster.rsplit_once('/').expect("a URL ending in /database");
    format!("{base}/{name}")
}

/// A plain connection to `url` (to look at what the servers wrote).
pub async fn connect(url: &str) -> tokio_postgres::Client {
    let (client, connection) = tokio_postgres::connect(url, tokio_postgres::NoTls)
        .await
        .unwrap();
    tokio::spawn(connection);
    client
}

/// Stops (`stop`) or starts (`start`) the test cluster with pg_ctl as the postgres user.
pub fn pg_ctl(action: &str) {
    let data = std::env::var("WAVRAD_TEST_PGDATA").expect("WAVRAD_TEST_PGDATA (from .ci/postgres)");
    let bin = std::env::var("WAVRAD_TEST_PG_BIN").expect("WAVRAD_TEST_PG_BIN (from .ci/postgres)");
    let mut cmd = std::process::Command::new("runuser");
    cmd.args([
        "-u",
        "postgres",
        "--",
        &format!("{bin}/pg_ctl"),
        "-D",
        &data,
        "-w",
    ]);
    if action == "start" {
        cmd.args(["-l", &format!("{data}/../log")]);
    } else {
        cmd.args(["-m", "fast"]);
    }
    let status = cmd.arg(action).status().unwrap();
    assert!(status.success(), "pg_ctl {action}");
}
