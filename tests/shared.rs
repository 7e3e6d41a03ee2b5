//! Several `wavrad serve` processes on one PostgreSQL database (`WAVRAD_TEST_DATABASE_URL`,
//! see `tests/postgres`): each job solved by one process, every route answering the same from
//! every process, a dead process's job taken over, a DELETE through one process stopping the
//! solve in another, SSE through one process following a solve in another, the same
//! document posted to two processes at once making one job, and synchronous renders answering
//! what every process serves, whichever process solved them.

mod cluster;
mod listening;
mod postgres;

use cluster::{bytes, claimer_pid, long, owner_pid, post, small, start, status, wait_for};
use futures_util::StreamExt;
use std::collections::{BTreeSet, HashMap};
use std::time::{Duration, Instant};

#[tokio::test(flavor = "multi_thread")]
async fn three_processes_solve_fifty_jobs_each_once_and_serve_them_alike() {
    let url = postgres::fresh_database().await;
    let servers = [
        start(&url, &[]).await,
        start(&url, &[]).await,
        start(&url, &[]).await,
    ];
    let http = reqwest::Client::new();
    let mut ids = vec![];
    for i in 0..50 {
        let (code, s) = post(&http, &servers[i % 3].base, &small(&format!("small {i}"))).await;
        assert_eq!(code, 202, "{s}");
        ids.push(s["id"].as_str().unwrap().to_string());
    }
    for id in &ids {
        let s = wait_for(
            &http,
            &servers[0].base,
            id,
            &["succeeded", "failed"],
            Duration::from_secs(180),
        )
        .await;
        assert_eq!(s["state"], "succeeded", "{s}");
    }
    // each solved exactly once: one claim each, 50 solves across the processes
    let db = postgres::connect(&url).await;
    let rows = db
        .query("SELECT id, claims FROM wavrad_jobs", &[])
        .await
        .unwrap();
    assert_eq!(rows.len(), 50);
    for r in &rows {
        assert_eq!(
            r.get::<_, i32>(1),
            1,
            "job {} claimed more than once",
            r.get::<_, String>(0)
        );
    }
    let mut solves = vec![];
    for s in &servers {
        solves.push(s.solves(&http).await);
    }
    assert_eq!(
        solves.iter().sum::<u64>(),
        50,
        "solves per process: {solves:?}"
    );
    assert!(
        solves.iter().all(|n| *n > 0),
        "every process took jobs: {solves:?}"
    );
    // every job, its result and its images read alike from every process
    let expected: BTreeSet<String> = ids.iter().cloned().collect();
    for s in &servers {
        let list: Vec<serde_json::Value> = http
            .get(format!("{}/api/v1/jobs?limit=100", s.base))
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        let listed: BTreeSet<String> = list
            .iter()
            .map(|j| j["id"].as_str().unwrap().to_string())
            .collect();
        assert_eq!(listed, expected);
    }
    for id in &ids {
        let mut first: Option<(Vec<u8>, Vec<u8>, Vec<u8>)> = None;
        for s in &servers {
            let got = (
                bytes(&http, format!("{}/api/v1/jobs/{id}/result", s.base)).await,
                bytes(&http, format!("{}/api/v1/jobs/{id}/image.png", s.base)).await,
                bytes(
                    &http,
                    format!("{}/api/v1/jobs/{id}/surfaces/top.png", s.base),
                )
                .await,
            );
            match &first {
                None => first = Some(got),
                Some(f) => assert!(*f == got, "job {id} differs between processes"),
            }
        }
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn the_same_document_posted_to_two_processes_at_once_is_one_job() {
    let url = postgres::fresh_database().await;
    let (a, b) = (start(&url, &[]).await, start(&url, &[]).await);
    let http = reqwest::Client::new();
    for i in 0..8 {
        let doc = small(&format!("twice {i}"));
        let ((ca, sa), (cb, sb)) =
            tokio::join!(post(&http, &a.base, &doc), post(&http, &b.base, &doc));
        assert!(
            matches!(ca, 200 | 202) && matches!(cb, 200 | 202),
            "{ca} {cb}"
        );
        assert_eq!(sa["id"], sb["id"]);
        let id = sa["id"].as_str().unwrap();
        let s = wait_for(&http, &b.base, id, &["succeeded"], Duration::from_secs(60)).await;
        assert_eq!(s["id"], sa["id"]);
    }
    let db = postgres::connect(&url).await;
    let rows = db
        .query("SELECT claims FROM wavrad_jobs", &[])
        .await
        .unwrap();
    assert_eq!(rows.len(), 8, "one row per document");
    assert!(
        rows.iter().all(|r| r.get::<_, i32>(0) == 1),
        "each solved once"
    );
    assert_eq!(a.solves(&http).await + b.solves(&http).await, 8);
}

/// `POST /api/v1/render` answers the image (or, with `Accept: application/json`, the result)
/// that every process then serves from the database: when the process that took the request
/// solved the job (it answers with the files its solve wrote, not read back) and when another
/// did (its worker busy, the process that took the request reads the answer back).
#[tokio::test(flavor = "multi_thread")]
async fn synchronous_renders_answer_what_every_process_serves() {
    let url = postgres::fresh_database().await;
    let http = reqwest::Client::new();
    let render = |base: String, name: String, json: bool| {
        let http = http.clone();
        async move {
            let mut req = http
                .post(format!("{base}/api/v1/render"))
                .header("content-type", "application/json")
                .body(small(&name).to_string());
            if json {
                req = req.header("accept", "application/json");
            }
            let res = req.send().await.unwrap();
            assert_eq!(res.status(), 200, "{name}");
            let job = res.headers()["content-location"]
                .to_str()
                .unwrap()
                .to_string();
            let file = if json { "result" } else { "image.png" };
            (format!("{job}/{file}"), res.bytes().await.unwrap().to_vec())
        }
    };
    // one process: it solves what it takes
    let servers = [start(&url, &[]).await];
    for (i, json) in [(0, false), (1, true)] {
        let (file, answer) = render(servers[0].base.clone(), format!("here {i}"), json).await;
        let stored = bytes(&http, format!("{}{file}", servers[0].base)).await;
        assert!(stored == answer, "{file} is not the answer");
    }
    assert_eq!(servers[0].solves(&http).await, 2);
    // two: the one that takes the requests is busy with a long job, the other solves them
    let servers = [servers.into_iter().next().unwrap(), start(&url, &[]).await];
    let db = postgres::connect(&url).await;
    let (code, s) = post(&http, &servers[0].base, &long("busy", 512)).await;
    assert_eq!(code, 202);
    let busy_id = s["id"].as_str().unwrap().to_string();
    let busy_pid = claimer_pid(&db, &busy_id).await;
    let (busy, idle) = if servers[0].pid() == busy_pid {
        (&servers[0], &servers[1])
    } else {
        (&servers[1], &servers[0])
    };
    let before = idle.solves(&http).await;
    for (i, json) in [(0, false), (1, true)] {
        let (file, answer) = render(busy.base.clone(), format!("there {i}"), json).await;
        for s in &servers {
            let stored = bytes(&http, format!("{}{file}", s.base)).await;
            assert!(stored == answer, "{file} from {} is not the answer", s.base);
        }
    }
    assert_eq!(
        idle.solves(&http).await,
        before + 2,
        "solved by the idle one"
    );
    let res = http
        .delete(format!("{}/api/v1/jobs/{busy_id}", busy.base))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 204);
}

#[tokio::test(flavor = "multi_thread")]
async fn sse_and_delete_through_one_process_reach_a_solve_in_another() {
    let url = postgres::fresh_database().await;
    let servers = [start(&url, &[]).await, start(&url, &[]).await];
    let http = reqwest::Client::new();
    let db = postgres::connect(&url).await;
    let (code, s) = post(&http, &servers[0].base, &long("long delete", 512)).await;
    assert_eq!(code, 202);
    let id = s["id"].as_str().unwrap().to_string();
    // which process solves it
    let solver_pid = claimer_pid(&db, &id).await;
    let (solver, other) = if servers[0].pid() == solver_pid {
        (&servers[0], &servers[1])
    } else {
        assert_eq!(servers[1].pid(), solver_pid, "a test process holds the job");
        (&servers[1], &servers[0])
    };
    // SSE through the other process: progress of the solve, event after event
    let res = http
        .get(format!("{}/api/v1/jobs/{id}/events", other.base))
        .send()
        .await
        .unwrap();
    assert_eq!(res.status(), 200);
    let mut stream = res.bytes_stream();
    let mut text = String::new();
    let mut events: Vec<(Instant, serde_json::Value)> = vec![];
    let mut deleted_at = None;
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        let chunk = tokio::time::timeout_at(deadline.into(), stream.next())
            .await
            .expect("the event stream goes on and closes when the job ends");
        let Some(chunk) = chunk else { break };
        text.push_str(std::str::from_utf8(&chunk.unwrap()).unwrap());
        while let Some(end) = text.find("\n\n") {
            let block: String = text.drain(..end + 2).collect();
            if let Some(data) = block.lines().find_map(|l| l.strip_prefix("data:")) {
                events.push((Instant::now(), serde_json::from_str(data.trim()).unwrap()));
            }
        }
        let running: Vec<&serde_json::Value> = events
            .iter()
            .map(|(_, e)| e)
            .filter(|e| e["state"] == "running")
            .collect();
        // progress moves: distinct (phase, fraction) pairs, less than two seconds apart
        let distinct: BTreeSet<String> =
            running.iter().map(|e| e["progress"].to_string()).collect();
        if deleted_at.is_none() && distinct.len() >= 4 {
            let times: Vec<Instant> = events
                .iter()
                .filter(|(_, e)| e["state"] == "running")
                .map(|(t, _)| *t)
                .collect();
            for w in times.windows(2) {
                assert!(w[1] - w[0] < Duration::from_secs(2), "events far apart");
            }
            let before = solver.solves(&http).await;
            assert_eq!(before, 0);
            let res = http
                .delete(format!("{}/api/v1/jobs/{id}", other.base))
                .send()
                .await
                .unwrap();
            assert_eq!(res.status(), 204);
            deleted_at = Some(Instant::now());
        }
    }
    let deleted_at = deleted_at.expect("progress events came before the stream ended");
    assert_eq!(
        events.last().unwrap().1["state"],
        "cancelled",
        "the stream ends with the job cancelled"
    );
    // the solve in the other process has stopped within two seconds of the DELETE
    loop {
        if solver.solves(&http).await == 1 {
            break;
        }
        assert!(
            deleted_at.elapsed() < Duration::from_secs(2),
            "the solve still runs: {}",
            solver.log_text()
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    assert!(solver.log_text().contains("the solve stopped"));
    for s in &servers {
        assert_eq!(status(&http, &s.base, &id).await.0, 404);
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn a_killed_process_loses_its_job_to_another_which_finishes_it() {
    let url = postgres::fresh_database().await;
    let mut servers = vec![start(&url, &[]).await, start(&url, &[]).await];
    let http = reqwest::Client::new();
    let db = postgres::connect(&url).await;
    let (code, s) = post(&http, &servers[0].base, &long("long kill", 512)).await;
    assert_eq!(code, 202);
    let id = s["id"].as_str().unwrap().to_string();
    let solver_pid = claimer_pid(&db, &id).await;
    tokio::time::sleep(Duration::from_millis(300)).await;
    let index = servers.iter().position(|s| s.pid() == solver_pid).unwrap();
    let mut victim = servers.remove(index);
    victim.kill9();
    let killed = Instant::now();
    let survivor = &servers[0];
    // the survivor takes it over once the 2 s lease has run out
    loop {
        if owner_pid(&db, &id).await == Some(survivor.pid()) {
            break;
        }
        let (_, s) = status(&http, &survivor.base, &id).await;
        if s["state"] == "succeeded" {
            break;
        }
        assert!(
            killed.elapsed() < Duration::from_secs(5),
            "not taken over within the lease (2 s) and some slack"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let s = wait_for(
        &http,
        &survivor.base,
        &id,
        &["succeeded", "failed"],
        Duration::from_secs(180),
    )
    .await;
    assert_eq!(s["state"], "succeeded", "{s}");
    let claims: i32 = db
        .query_one("SELECT claims FROM wavrad_jobs WHERE id = $1", &[&id])
        .await
        .unwrap()
        .get(0);
    assert_eq!(
        claims, 2,
        "claimed by the killed process, then by the survivor"
    );
    assert_eq!(survivor.solves(&http).await, 1);
    bytes(
        &http,
        format!("{}/api/v1/jobs/{id}/image.png", survivor.base),
    )
    .await;
}

#[tokio::test(flavor = "multi_thread")]
async fn the_queue_is_full_for_every_process_when_the_shared_queue_is() {
    let url = postgres::fresh_database().await;
    // one worker per process: a long job occupies each, then two more wait
    let a = start(&url, &["--queue-capacity", "2"]).await;
    let b = start(&url, &["--queue-capacity", "2"]).await;
    let http = reqwest::Client::new();
    let mut codes = HashMap::new();
    for (i, server) in [&a, &b, &a, &b, &a, &b].iter().enumerate() {
        let (code, _) = post(&http, &server.base, &long(&format!("fill {i}"), 512)).await;
        *codes.entry(code).or_insert(0) += 1;
        tokio::time::sleep(Duration::from_millis(300)).await;
    }
    // two running (one per process), two queued, the rest refused by either process
    assert_eq!(codes.get(&202), Some(&4), "{codes:?}");
    assert_eq!(codes.get(&429), Some(&2), "{codes:?}");
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert_eq!(a.ready(&http).await, 503, "a full shared queue: not ready");
    assert_eq!(b.ready(&http).await, 503);
}
