//! One suite for both stores behind [`Store`]: the embedded redb store and PostgreSQL (on the
//! cluster of `WAVRAD_TEST_DATABASE_URL`, see `tests/postgres`). Records, files, removal,
//! insertion by content id with a capacity, listing, and the queue's claims under leases:
//! oldest first, each job to one owner even when many claim at once, renewals and results only
//! by the owner, a lapsed lease taken over, a released job queued again, expiry, and eviction
//! beyond a size (`max_store_bytes`): the first finished first, never a queued or running job.

mod postgres;

use serde_json::json;
use std::collections::HashSet;
use std::sync::Arc;
use std::time::Duration;
use wavrad::server::queue::{JobState, JobStatus, ProgressInfo};
use wavrad::server::store::embedded::Embedded;
use wavrad::server::store::{Inserted, Record, Store};

fn record(id: &str, created_ms: u64) -> Record {
    let status: JobStatus = serde_json::from_value(json!({
        "id": id, "state": "queued", "scene": id, "kind": "flatland",
        "created_ms": created_ms, "started_ms": null, "finished_ms": null,
        "progress": {"phase": "queued", "fraction": 0.0}, "error": null,
        "links": {"self": "s", "events": "e", "result": "r", "image": "i", "sparsity": "p",
                  "coefficients": "c", "surfaces": {"top": "t"}}
    }))
    .unwrap();
    Record {
        document: json!({"scene": {"name": id}, "n": created_ms}),
        status,
    }
}

fn finished(mut r: Record, state: JobState, at: u64) -> Record {
    r.status.state = state;
    r.status.finished_ms = Some(at);
    r.status.progress = ProgressInfo {
        phase: "done".into(),
        fraction: 1.0,
    };
    r
}

const LONG: Duration = Duration::from_secs(60);

fn records_files_and_removal(store: &dyn Store) {
    let a = finished(record("a", 1), JobState::Succeeded, 10);
    store
        .put_finished(&a, &[("x.png".into(), b"png".as_slice())])
        .unwrap();
    store.put_job(&record("ab", 2)).unwrap();
    store.put_job_lazily(&record("abc", 3)).unwrap();
    store.sync().unwrap();
    let b = finished(record("ab", 2), JobState::Succeeded, 11);
    store
        .put_finished(&b, &[("y".into(), b"y".as_slice())])
        .unwrap();
    let mut all = store.jobs().unwrap();
    all.sort_by(|x, y| x.status.id.cmp(&y.status.id));
    assert_eq!(all, vec![a.clone(), b.clone(), record("abc", 3)]);
    assert_eq!(store.job("ab").unwrap(), Some(b));
    assert_eq!(store.job("zz").unwrap(), None);
    assert_eq!(
        store.file("a", "x.png").unwrap().as_deref(),
        Some(b"png".as_slice())
    );
    assert_eq!(store.file("a", "y").unwrap(), None);
    assert!(store.remove("a").unwrap());
    assert!(!store.remove("a").unwrap(), "gone already");
    assert_eq!(
        store.file("a", "x.png").unwrap(),
        None,
        "files go with their job"
    );
    assert_eq!(
        store.file("ab", "y").unwrap().as_deref(),
        Some(b"y".as_slice()),
        "a job whose id starts with another's keeps its files"
    );
    store.ping().unwrap();
}

fn insertion_listing_and_counts(store: &dyn Store) {
    assert_eq!(
        store.insert(&record("j1", 100), 2, true).unwrap(),
        Inserted::New
    );
    assert_eq!(
        store.insert(&record("j2", 200), 2, true).unwrap(),
        Inserted::New
    );
    assert_eq!(
        store.insert(&record("j1", 999), 2, true).unwrap(),
        Inserted::Existing(Box::new(record("j1", 100))),
        "the same id is the same job, full queue or not"
    );
    assert_eq!(
        store.insert(&record("j3", 300), 2, true).unwrap(),
        Inserted::Full
    );
    assert_eq!(store.job("j3").unwrap(), None, "a refused job is not kept");
    store
        .put_job(&finished(record("j0", 300), JobState::Failed, 5))
        .unwrap();
    let ids: Vec<String> = store.list(10).unwrap().into_iter().map(|s| s.id).collect();
    assert_eq!(ids, ["j0", "j2", "j1"], "newest first, then by id");
    assert_eq!(store.list(1).unwrap().len(), 1);
    let c = store.counts().unwrap();
    assert_eq!((c.queued, c.failed, c.running), (2, 1, 0));
}

fn claims_and_leases(store: &dyn Store) {
    for (id, t) in [("c2", 20), ("c1", 10), ("c3", 30)] {
        assert_eq!(
            store.insert(&record(id, t), 100, true).unwrap(),
            Inserted::New
        );
    }
    // oldest first, each to one owner
    let first = store.claim("p1", LONG).unwrap().unwrap();
    assert_eq!(first.status.id, "c1");
    assert_eq!(first.status.state, JobState::Running);
    assert!(first.status.started_ms.is_some());
    assert_eq!(
        store.job("c1").unwrap().unwrap().status.state,
        JobState::Running
    );
    let second = store.claim("p2", LONG).unwrap().unwrap();
    assert_eq!(second.status.id, "c2");
    // renewals and results by the owner only
    let mut progress = second.status.clone();
    progress.progress = ProgressInfo {
        phase: "solve".into(),
        fraction: 0.5,
    };
    assert!(store.renew("p2", LONG, &progress).unwrap());
    assert_eq!(
        store.job("c2").unwrap().unwrap().status.progress.fraction,
        0.5
    );
    assert!(!store.renew("p1", LONG, &progress).unwrap(), "not p1's job");
    let done = finished(second.clone(), JobState::Succeeded, 50);
    let files = [("result.json".to_string(), b"{}".as_slice())];
    assert!(!store.finish("p1", &done, &files).unwrap(), "not p1's job");
    assert_eq!(store.file("c2", "result.json").unwrap(), None);
    assert!(store.finish("p2", &done, &files).unwrap());
    assert!(!store.finish("p2", &done, &files).unwrap(), "written once");
    assert_eq!(store.job("c2").unwrap().unwrap(), done);
    assert_eq!(
        store.file("c2", "result.json").unwrap().as_deref(),
        Some(b"{}".as_slice())
    );
    assert!(!store.renew("p2", LONG, &done.status).unwrap(), "finished");
    // a lapsed lease is taken over; the first owner can neither renew nor finish
    let short = store
        .claim("p3", Duration::from_millis(300))
        .unwrap()
        .unwrap();
    assert_eq!(short.status.id, "c3");
    assert_eq!(store.claim("p4", LONG).unwrap(), None, "c1 and c3 are held");
    std::thread::sleep(Duration::from_millis(600));
    let taken = store.claim("p4", LONG).unwrap().unwrap();
    assert_eq!(taken.status.id, "c3");
    assert!(!store.renew("p3", LONG, &short.status).unwrap());
    assert!(!store
        .finish("p3", &finished(short, JobState::Succeeded, 60), &[])
        .unwrap());
    // released: queued again, claimed again
    store.release("p4", "c3").unwrap();
    let again = store.job("c3").unwrap().unwrap();
    assert_eq!(again.status.state, JobState::Queued);
    assert_eq!(again.status.started_ms, None);
    store.release("p1", "c3").unwrap(); // not p1's: nothing happens
    assert_eq!(store.claim("p5", LONG).unwrap().unwrap().status.id, "c3");
    // a deleted job: its owner learns it at the next renewal
    assert!(store.remove("c1").unwrap());
    assert!(!store.renew("p1", LONG, &first.status).unwrap());
    assert!(!store
        .finish("p1", &finished(first, JobState::Succeeded, 70), &files)
        .unwrap());
    assert_eq!(store.file("c1", "result.json").unwrap(), None);
    // expiry: finished at or before the time given
    assert_eq!(store.expire(49).unwrap(), 0);
    assert_eq!(store.expire(50).unwrap(), 1);
    assert_eq!(store.job("c2").unwrap(), None);
    assert_eq!(store.file("c2", "result.json").unwrap(), None);
}

/// Eight threads claim 40 jobs at once: every job exactly once.
fn concurrent_claims(store: Arc<dyn Store>) {
    for i in 0..40 {
        assert_eq!(
            store
                .insert(&record(&format!("k{i:02}"), i), 100, true)
                .unwrap(),
            Inserted::New
        );
    }
    let handles: Vec<_> = (0..8)
        .map(|t| {
            let store = store.clone();
            std::thread::spawn(move || {
                let mut got = vec![];
                while let Some(r) = store.claim(&format!("t{t}"), LONG).unwrap() {
                    got.push(r.status.id);
                }
                got
            })
        })
        .collect();
    let all: Vec<String> = handles
        .into_iter()
        .flat_map(|h| h.join().unwrap())
        .collect();
    let unique: HashSet<&String> = all.iter().collect();
    assert_eq!(all.len(), 40, "{all:?}");
    assert_eq!(unique.len(), 40);
    assert_eq!(store.counts().unwrap().running, 40);
}

/// The bytes of a job as the stores count them: its record (document and status as JSON;
/// either store may write them a little differently, so only bounds are checked) and its
/// files.
fn eviction_beyond_a_size(store: &dyn Store) {
    assert_eq!(store.stored_bytes().unwrap(), 0);
    assert_eq!(
        store.evict(0).unwrap(),
        Vec::<String>::new(),
        "nothing there"
    );
    let kb = vec![7u8; 1000];
    let files = |n: usize| -> Vec<(String, &[u8])> {
        (0..n)
            .map(|i| (format!("f{i}.png"), kb.as_slice()))
            .collect()
    };
    // created in one order, finished in another: the first finished goes first
    store
        .put_finished(
            &finished(record("late", 1), JobState::Succeeded, 30),
            &files(3),
        )
        .unwrap();
    store
        .put_finished(
            &finished(record("early", 2), JobState::Failed, 10),
            &files(1),
        )
        .unwrap();
    store
        .put_finished(
            &finished(record("mid", 3), JobState::Succeeded, 20),
            &files(2),
        )
        .unwrap();
    // a queued job and a running one with files of their own (never forgotten)
    assert_eq!(
        store.insert(&record("q", 4), 100, true).unwrap(),
        Inserted::New
    );
    assert_eq!(
        store.insert(&record("r", 0), 100, true).unwrap(),
        Inserted::New
    );
    assert_eq!(store.claim("p", LONG).unwrap().unwrap().status.id, "r");
    let total = store.stored_bytes().unwrap();
    let records = total - 6000;
    assert!(
        (5 * 200..5 * 2000).contains(&records),
        "6000 bytes of files and five records of a few hundred bytes: {total}"
    );
    assert_eq!(
        store.evict(total).unwrap(),
        Vec::<String>::new(),
        "within the limit"
    );
    assert_eq!(
        store.evict(total - 1).unwrap(),
        ["early"],
        "the first finished first"
    );
    assert_eq!(store.job("early").unwrap(), None);
    assert_eq!(
        store.file("early", "f0.png").unwrap(),
        None,
        "files go with their job"
    );
    let after = store.stored_bytes().unwrap();
    assert!(
        total - after > 1000 && total - after < 1000 + 2000,
        "{total} → {after}"
    );
    // "mid" (2000 bytes of files) is enough to come within after − 1500
    assert_eq!(store.evict(after - 1500).unwrap(), ["mid"]);
    assert_eq!(
        store.evict(0).unwrap(),
        ["late"],
        "every finished job, and no other"
    );
    let mut left: Vec<String> = store
        .jobs()
        .unwrap()
        .into_iter()
        .map(|r| r.status.id)
        .collect();
    left.sort();
    assert_eq!(
        left,
        ["q", "r"],
        "queued and running jobs stay, whatever the limit"
    );
    assert!(store.stored_bytes().unwrap() > 0);
    assert_eq!(store.evict(0).unwrap(), Vec::<String>::new());
    // once the running job has finished it may go; the queued one still stays
    let running = store.job("r").unwrap().unwrap();
    assert!(store
        .finish("p", &finished(running, JobState::Succeeded, 40), &files(1))
        .unwrap());
    assert_eq!(store.evict(0).unwrap(), ["r"]);
    assert_eq!(
        store.job("q").unwrap().unwrap().status.state,
        JobState::Queued
    );
    assert!(store.remove("q").unwrap());
    assert_eq!(
        store.stored_bytes().unwrap(),
        0,
        "nothing counted for forgotten jobs"
    );
}

fn suite(make: &dyn Fn() -> Arc<dyn Store>) {
    eviction_beyond_a_size(&*make());
    records_files_and_removal(&*make());
    insertion_listing_and_counts(&*make());
    claims_and_leases(&*make());
    concurrent_claims(make());
}

#[test]
fn the_embedded_store_passes_the_suite() {
    let dirs = std::sync::Mutex::new(vec![]);
    suite(&|| {
        let dir = tempfile::tempdir().unwrap();
        let store = Arc::new(Embedded::open(dir.path()).unwrap());
        dirs.lock().unwrap().push(dir);
        store
    });
}

#[test]
fn the_embedded_store_keeps_its_records_across_a_reopen() {
    let dir = tempfile::tempdir().unwrap();
    let store = Embedded::open(dir.path()).unwrap();
    store
        .put_finished(&record("a", 1), &[("f".into(), b"x".as_slice())])
        .unwrap();
    drop(store);
    let store = Embedded::open(dir.path()).unwrap();
    assert_eq!(store.jobs().unwrap(), vec![record("a", 1)]);
    assert_eq!(
        store.file("a", "f").unwrap().as_deref(),
        Some(b"x".as_slice())
    );
}

/// A database written before the stores kept sizes: its sizes are filled in when it is
/// opened, so that the jobs already there count toward `max_store_bytes`.
#[test]
fn the_embedded_store_counts_the_jobs_of_a_database_without_sizes() {
    let dir = tempfile::tempdir().unwrap();
    {
        let db = redb::Database::create(dir.path().join("wavrad.redb")).unwrap();
        let txn = db.begin_write().unwrap();
        let r = finished(record("old", 1), JobState::Succeeded, 5);
        let bytes = serde_json::to_vec(&r).unwrap();
        txn.open_table(redb::TableDefinition::<&str, &[u8]>::new("jobs"))
            .unwrap()
            .insert("old", bytes.as_slice())
            .unwrap();
        txn.open_table(redb::TableDefinition::<&str, &[u8]>::new("files"))
            .unwrap()
            .insert("old/image.png", [1u8; 500].as_slice())
            .unwrap();
        txn.commit().unwrap();
    }
    let store = Embedded::open(dir.path()).unwrap();
    let total = store.stored_bytes().unwrap();
    assert!(total > 500 && total < 2500, "{total}");
    assert_eq!(store.evict(0).unwrap(), ["old"]);
    assert_eq!(store.stored_bytes().unwrap(), 0);
}

#[test]
fn postgres_passes_the_suite() {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    suite(&|| {
        runtime.block_on(async {
            let url = postgres::fresh_database().await;
            let store = wavrad::server::store::postgres::Postgres::connect(&url, 8)
                .await
                .unwrap();
            Arc::new(store) as Arc<dyn Store>
        })
    });
}

#[test]
fn postgres_refuses_a_bad_url_and_an_unreachable_database_clearly() {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let err = runtime
        .block_on(wavrad::server::store::postgres::Postgres::connect(
            "postgres://nobody@127.0.0.1:1/none",
            2,
        ))
        .err()
        .expect("no database listens on port 1");
    assert!(err.to_string().starts_with("database:"), "{err}");
    let err = runtime
        .block_on(wavrad::server::store::postgres::Postgres::connect(
            "postgres://x@127.0.0.1:notaport/db",
            2,
        ))
        .err()
        .unwrap();
    assert!(err.to_string().contains("does not parse"), "{err}");
}

#[test]
fn migrations_run_once_when_processes_start_together() {
    let runtime = tokio::runtime::Runtime::new().unwrap();
    runtime.block_on(async {
        let url = postgres::fresh_database().await;
        let tasks: Vec<_> = (0..4)
            .map(|_| {
                let url = url.clone();
                tokio::spawn(async move {
                    wavrad::server::store::postgres::Postgres::connect(&url, 2)
                        .await
                        .unwrap()
                })
            })
            .collect();
        for t in tasks {
            t.await.unwrap();
        }
        let client = postgres::connect(&url).await;
        let n: i64 = client
            .query_one("SELECT count(*) FROM wavrad_migrations", &[])
            .await
            .unwrap()
            .get(0);
        assert_eq!(n, 2, "each of the two migrations once");
    });
}
