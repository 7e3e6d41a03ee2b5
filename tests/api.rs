//! Every route and every error case of `docs/api.md`, through the router (`oneshot`).

mod common;

use axum::body::{Body, Bytes};
use axum::http::{header, HeaderMap, Request, StatusCode};
use axum::Router;
use common::*;
use serde_json::{json, Value};
use std::time::{Duration, Instant};
use tower::ServiceExt;
use wavrad::server::queue::JobState;
use wavrad::server::{app, AppState};

async fn call(app: &Router, req: Request<Body>) -> (StatusCode, HeaderMap, Bytes) {
    let res = app.clone().oneshot(req).await.unwrap();
    let (parts, body) = res.into_parts();
    let bytes = axum::body::to_bytes(body, usize::MAX).await.unwrap();
    (parts.status, parts.headers, bytes)
}

fn post(uri: &str, body: impl Into<Body>) -> Request<Body> {
    Request::post(uri)
        .header(header::CONTENT_TYPE, "application/json")
        .body(body.into())
        .unwrap()
}

fn get(uri: &str) -> Request<Body> {
    Request::get(uri).body(Body::empty()).unwrap()
}

fn delete(uri: &str) -> Request<Body> {
    Request::delete(uri).body(Body::empty()).unwrap()
}

fn json(bytes: &Bytes) -> Value {
    serde_json::from_slice(bytes)
        .unwrap_or_else(|e| panic!("not JSON ({e}): {}", String::from_utf8_lossy(bytes)))
}

/// Asserts a problem document with this status.
fn problem(status: StatusCode, headers: &HeaderMap, body: &Bytes, expected: StatusCode) -> Value {
    assert_eq!(status, expected, "{}", String::from_utf8_lossy(body));
    assert_eq!(headers[header::CONTENT_TYPE], "application/problem+json");
    let p = json(body);
    assert_eq!(p["status"], expected.as_u16());
    for key in ["type", "title", "detail"] {
        assert!(p[key].is_string(), "{key} missing in {p}");
    }
    p
}

fn setup(f: impl FnOnce(&mut wavrad::server::Config)) -> (tempfile::TempDir, AppState, Router) {
    let dir = tempfile::tempdir().unwrap();
    let mut c = config(dir.path());
    f(&mut c);
    let s = state(c);
    let router = app(s.clone());
    (dir, s, router)
}

async fn submit(router: &Router, doc: &Value) -> (StatusCode, HeaderMap, Value) {
    let (st, h, b) = call(router, post("/api/v1/jobs", doc.to_string())).await;
    (st, h, json(&b))
}

#[tokio::test(flavor = "multi_thread")]
async fn a_job_runs_and_yields_its_result_and_images() {
    let (_dir, state, router) = setup(|_| {});
    let doc = scene("flatland-parallel");
    let (st, h, status) = submit(&router, &doc).await;
    assert_eq!(st, StatusCode::ACCEPTED);
    let id = status["id"].as_str().unwrap().to_string();
    assert_eq!(h[header::LOCATION], format!("/api/v1/jobs/{id}"));
    assert!(["queued", "running"].contains(&status["state"].as_str().unwrap()));
    wait_until(&state, &id, |s| s.is_final()).await;

    let (st, _, b) = call(&router, get(&format!("/api/v1/jobs/{id}"))).await;
    assert_eq!(st, StatusCode::OK);
    let status = json(&b);
    assert_eq!(status["state"], "succeeded");
    assert_eq!(status["progress"]["phase"], "done");
    assert_eq!(status["progress"]["fraction"], 1.0);

    let (st, h, b) = call(&router, get(&format!("/api/v1/jobs/{id}/result"))).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(h[header::CONTENT_TYPE], "application/json");
    let result = json(&b);
    assert_eq!(result["kind"], "flatland");
    assert_eq!(result["surfaces"].as_array().unwrap().len(), 2);
    let direct = wavrad::job::run(
        &wavrad::scene::parse_value(&doc, &wavrad::scene::Limits::default()).unwrap(),
        &wavrad::progress::Silent,
    )
    .unwrap();
    assert_eq!(
        result["surfaces"][1]["mean"][0].as_f64().unwrap(),
        direct.result.surfaces[1].mean[0]
    );

    for path in [
        "image.png",
        "sparsity.png",
        "coefficients.png",
        "surfaces/top.png",
        "surfaces/bottom.png",
    ] {
        let (st, h, b) = call(&router, get(&format!("/api/v1/jobs/{id}/{path}"))).await;
        assert_eq!(st, StatusCode::OK, "{path}");
        assert_eq!(h[header::CONTENT_TYPE], "image/png");
        assert_eq!(&b[..8], b"\x89PNG\r\n\x1a\n");
        assert!(h[header::CACHE_CONTROL]
            .to_str()
            .unwrap()
            .contains("immutable"));
        let etag = h[header::ETAG].to_str().unwrap().to_string();
        // the tag itself, one of a list, and its weak form all match; another tag does not
        for (sent, want) in [
            (etag.clone(), StatusCode::NOT_MODIFIED),
            (format!("\"0\", {etag}"), StatusCode::NOT_MODIFIED),
            (format!("W/{etag}"), StatusCode::NOT_MODIFIED),
            ("\"0\"".to_string(), StatusCode::OK),
        ] {
            let again = Request::get(format!("/api/v1/jobs/{id}/{path}"))
                .header(header::IF_NONE_MATCH, &sent)
                .body(Body::empty())
                .unwrap();
            let (st, _, b) = call(&router, again).await;
            assert_eq!(st, want, "{path}, If-None-Match: {sent}");
            assert_eq!(b.is_empty(), want == StatusCode::NOT_MODIFIED);
        }
    }
    let img = image::load_from_memory(
        &call(&router, get(&format!("/api/v1/jobs/{id}/image.png")))
            .await
            .2,
    )
    .unwrap();
    assert_eq!((img.width(), img.height()), (512, 512));

    // The same document again: the same job, finished at once.
    let (st, h, again) = submit(&router, &doc).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(again["id"], id);
    assert_eq!(again["state"], "succeeded");
    assert_eq!(h[header::LOCATION], format!("/api/v1/jobs/{id}"));

    let (st, _, b) = call(&router, get("/api/v1/jobs")).await;
    assert_eq!(st, StatusCode::OK);
    let list = json(&b);
    assert_eq!(list.as_array().unwrap().len(), 1);
    assert_eq!(list[0]["id"], id);

    let (st, _, _) = call(&router, delete(&format!("/api/v1/jobs/{id}"))).await;
    assert_eq!(st, StatusCode::NO_CONTENT);
    let (st, h, b) = call(&router, get(&format!("/api/v1/jobs/{id}"))).await;
    problem(st, &h, &b, StatusCode::NOT_FOUND);
}

#[tokio::test(flavor = "multi_thread")]
async fn jobs_are_listed_newest_first() {
    let (_dir, state, router) = setup(|_| {});
    let mut ids = Vec::new();
    for name in ["first", "second", "third"] {
        let (_, _, s) = submit(&router, &named(name)).await;
        ids.push(s["id"].as_str().unwrap().to_string());
        tokio::time::sleep(Duration::from_millis(3)).await; // distinct creation milliseconds
    }
    for id in &ids {
        wait_until(&state, id, |s| s.is_final()).await;
    }
    let list = json(&call(&router, get("/api/v1/jobs?limit=2")).await.2);
    let got: Vec<&str> = list
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["id"].as_str().unwrap())
        .collect();
    assert_eq!(got, vec![ids[2].as_str(), ids[1].as_str()]);
}

#[tokio::test(flavor = "multi_thread")]
async fn bad_bodies_get_their_own_status_as_problem_documents() {
    let (_dir, _state, router) = setup(|c| c.max_body_bytes = 4096);
    for uri in ["/api/v1/jobs", "/api/v1/render"] {
        // 400: not JSON, not UTF-8.
        let (st, h, b) = call(&router, post(uri, "{ not json")).await;
        problem(st, &h, &b, StatusCode::BAD_REQUEST);
        let (st, h, b) = call(&router, post(uri, vec![b'"', 0xff, 0xfe, b'"'])).await;
        problem(st, &h, &b, StatusCode::BAD_REQUEST);
        // 415: wrong or missing content type.
        let req = Request::post(uri)
            .header(header::CONTENT_TYPE, "text/plain")
            .body(Body::from("{}"))
            .unwrap();
        let (st, h, b) = call(&router, req).await;
        problem(st, &h, &b, StatusCode::UNSUPPORTED_MEDIA_TYPE);
        let req = Request::post(uri).body(Body::from("{}")).unwrap();
        let (st, h, b) = call(&router, req).await;
        problem(st, &h, &b, StatusCode::UNSUPPORTED_MEDIA_TYPE);
        // 413: larger than max_body_bytes, with and without a Content-Length.
        // Each says which limit, and how to raise it.
        let big = json!({"scene": {"kind": "fredholm", "name": "x".repeat(5000)}}).to_string();
        let too_large = |p: &Value| {
            let detail = p["detail"].as_str().unwrap();
            assert!(
                detail.contains("max_body_bytes (4096 bytes)")
                    && detail.contains("--max-body-bytes"),
                "{detail}"
            );
        };
        let (st, h, b) = call(&router, post(uri, big.clone())).await;
        too_large(&problem(st, &h, &b, StatusCode::PAYLOAD_TOO_LARGE));
        let mut req = post(uri, big.clone());
        req.headers_mut()
            .insert(header::CONTENT_LENGTH, big.len().into());
        let (st, h, b) = call(&router, req).await;
        too_large(&problem(st, &h, &b, StatusCode::PAYLOAD_TOO_LARGE));
        let chunks = futures_util::stream::iter(
            big.into_bytes()
                .chunks(1000)
                .map(|c| Ok::<_, std::io::Error>(c.to_vec()))
                .collect::<Vec<_>>(),
        );
        let (st, h, b) = call(&router, post(uri, Body::from_stream(chunks))).await;
        too_large(&problem(st, &h, &b, StatusCode::PAYLOAD_TOO_LARGE));
        // 422: every path at fault.
        let mut doc = scene("flatland-parallel");
        doc["scene"]["surfaces"][1]["reflectance"] = json!(1.5);
        doc["solver"]["order"] = json!(-1);
        doc["solver"]["typo"] = json!(true);
        let (st, h, b) = call(&router, post(uri, doc.to_string())).await;
        let p = problem(st, &h, &b, StatusCode::UNPROCESSABLE_ENTITY);
        let paths: Vec<&str> = p["errors"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| e["path"].as_str().unwrap())
            .collect();
        for expected in [
            "/scene/surfaces/1/reflectance",
            "/solver/order",
            "/solver/typo",
        ] {
            assert!(paths.contains(&expected), "{expected} not in {paths:?}");
        }
        // 422: a name given twice in one object, which a parsed value would hide (the last
        // one wins there), beside the other errors
        let good = scene("flatland-parallel").to_string();
        let twice = good.replacen(
            "\"solver\":{",
            "\"solver\":{\"tolerance\":1e-6,\"tolerance\":1e-9,",
            1,
        );
        assert_ne!(twice, good, "the document has a solver object");
        for (text, more) in [
            (twice.clone(), None),
            (
                twice.replacen("\"order\":1", "\"order\":-1", 1),
                Some("/solver/order"),
            ),
        ] {
            let (st, h, b) = call(&router, post(uri, text)).await;
            let p = problem(st, &h, &b, StatusCode::UNPROCESSABLE_ENTITY);
            let errors = p["errors"].as_array().unwrap();
            assert!(
                errors.iter().any(|e| e["path"] == "/solver/tolerance"
                    && e["message"].as_str().unwrap().contains("more than once")),
                "{errors:?}"
            );
            assert_eq!(errors.len(), 1 + more.iter().count(), "{errors:?}");
        }
        // 422: a number too large for f64 is valid JSON and not finite, so its path is at
        // fault; so is a body nested deeper than any document (at the root)
        let text = scene("flatland-parallel").to_string().replacen(
            "\"reflectance\":0.8",
            "\"reflectance\":1e999",
            1,
        );
        assert!(text.contains("1e999"));
        let (st, h, b) = call(&router, post(uri, text)).await;
        let p = problem(st, &h, &b, StatusCode::UNPROCESSABLE_ENTITY);
        assert_eq!(
            p["errors"][0]["path"], "/scene/surfaces/1/reflectance",
            "{p}"
        );
        let deep = format!("{}{}", "[".repeat(200), "]".repeat(200));
        let (st, h, b) = call(&router, post(uri, deep)).await;
        let p = problem(st, &h, &b, StatusCode::UNPROCESSABLE_ENTITY);
        assert_eq!(p["errors"][0]["path"], "", "{p}");
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn the_job_id_hashes_numbers_as_written() {
    // the canonical JSON sorts keys and keeps numbers as they are written: 0.8 and 8e-1 are
    // different documents, a different order of keys is the same one
    let (_dir, _state, router) = setup(|_| {});
    let text = scene("flatland-parallel").to_string();
    assert!(text.contains("\"reflectance\":0.8"));
    let mut ids = Vec::new();
    for t in [
        text.clone(),
        text.replacen("\"reflectance\":0.8", "\"reflectance\":8e-1", 1),
        text.replacen("\"reflectance\":0.8", "\"reflectance\":0.80", 1),
    ] {
        let (st, _, b) = call(&router, post("/api/v1/jobs", t)).await;
        assert!(st == StatusCode::ACCEPTED || st == StatusCode::OK, "{st}");
        ids.push(json(&b)["id"].as_str().unwrap().to_string());
    }
    assert!(
        ids[0] != ids[1] && ids[1] != ids[2] && ids[0] != ids[2],
        "{ids:?}"
    );
    let mut reordered: Value = serde_json::from_str(&text).unwrap();
    let solver = reordered["solver"].take();
    reordered.as_object_mut().unwrap().remove("solver");
    reordered["solver"] = solver;
    let (_, _, b) = call(&router, post("/api/v1/jobs", reordered.to_string())).await;
    assert_eq!(json(&b)["id"], ids[0]);
}

#[tokio::test(flavor = "multi_thread")]
async fn a_document_larger_than_the_basis_limit_is_refused_before_any_work() {
    let (_dir, state, router) = setup(|c| c.max_basis_functions = 100);
    let mut doc = scene("flatland-parallel");
    doc["solver"]["resolution"] = json!(64); // 2 surfaces × 64 cells × 2 = 256 unknowns
    let (st, h, b) = call(&router, post("/api/v1/jobs", doc.to_string())).await;
    let p = problem(st, &h, &b, StatusCode::UNPROCESSABLE_ENTITY);
    assert!(!p["errors"].as_array().unwrap().is_empty());
    assert!(state.queue.list(10).is_empty(), "no job was created");
}

#[tokio::test(flavor = "multi_thread")]
async fn unknown_jobs_and_routes_are_404() {
    let (_dir, _state, router) = setup(|_| {});
    let id = "0123456789abcdef0123456789abcdef";
    for path in [
        "",
        "/events",
        "/result",
        "/image.png",
        "/sparsity.png",
        "/coefficients.png",
        "/surfaces/top.png",
    ] {
        let (st, h, b) = call(&router, get(&format!("/api/v1/jobs/{id}{path}"))).await;
        problem(st, &h, &b, StatusCode::NOT_FOUND);
    }
    let (st, h, b) = call(&router, delete(&format!("/api/v1/jobs/{id}"))).await;
    problem(st, &h, &b, StatusCode::NOT_FOUND);
    let (st, h, b) = call(&router, get("/no/such/route")).await;
    problem(st, &h, &b, StatusCode::NOT_FOUND);
}

#[tokio::test(flavor = "multi_thread")]
async fn workers_solve_jobs_at_once_beside_a_busy_one() {
    // two workers: a small job finishes while a big one keeps every core busy in parallel
    // loops (with one pool shared by the workers it waited for the big one to end)
    let (_dir, state, router) = setup(|c| c.workers = 2);
    let (st, _, s) = submit(&router, &named("busy big")).await;
    assert_eq!(st, StatusCode::ACCEPTED);
    let busy = s["id"].as_str().unwrap().to_string();
    wait_until(&state, &busy, |s| s == JobState::Running).await;
    let t = Instant::now();
    let (_, _, s) = submit(&router, &named("small")).await;
    let small = s["id"].as_str().unwrap().to_string();
    let done = wait_until(&state, &small, |s| s.is_final()).await;
    assert_eq!(done.state, JobState::Succeeded);
    assert!(t.elapsed() < Duration::from_secs(5), "{:?}", t.elapsed());
    assert_eq!(
        state.queue.get(&busy).unwrap().status().state,
        JobState::Running
    );
    let (st, _, _) = call(&router, delete(&format!("/api/v1/jobs/{busy}"))).await;
    assert_eq!(st, StatusCode::NO_CONTENT);
}

#[tokio::test(flavor = "multi_thread")]
async fn artifacts_before_success_are_409_and_a_running_job_cancels_within_a_second() {
    let (_dir, state, router) = setup(|_| {});
    let (st, _, s) = submit(&router, &named("slow one")).await;
    assert_eq!(st, StatusCode::ACCEPTED);
    let id = s["id"].as_str().unwrap().to_string();
    let running = wait_until(&state, &id, |s| s == JobState::Running).await;
    assert_eq!(running.state, JobState::Running);
    for path in [
        "/result",
        "/image.png",
        "/sparsity.png",
        "/coefficients.png",
        "/surfaces/top.png",
    ] {
        let (st, h, b) = call(&router, get(&format!("/api/v1/jobs/{id}{path}"))).await;
        problem(st, &h, &b, StatusCode::CONFLICT);
    }
    let (_, _, b) = call(
        &router,
        get(&format!("/api/v1/jobs/{id}/surfaces/nope.png")),
    )
    .await;
    assert_eq!(json(&b)["status"], 404);
    let (_, _, b) = call(&router, get(&format!("/api/v1/jobs/{id}/other.png"))).await;
    assert_eq!(json(&b)["status"], 404);

    let entry = state.queue.get(&id).unwrap();
    let t = Instant::now();
    let (st, _, _) = call(&router, delete(&format!("/api/v1/jobs/{id}"))).await;
    assert_eq!(st, StatusCode::NO_CONTENT);
    // The solver thread lets go of the job when its solve has stopped.
    while std::sync::Arc::strong_count(&entry) > 1 {
        assert!(
            t.elapsed() < Duration::from_secs(1),
            "the solve did not stop within a second"
        );
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    assert_eq!(entry.status().state, JobState::Cancelled);
    let (st, _, _) = call(&router, get(&format!("/api/v1/jobs/{id}"))).await;
    assert_eq!(st, StatusCode::NOT_FOUND);
}

#[tokio::test(flavor = "multi_thread")]
async fn a_full_queue_answers_429_with_retry_after_and_readyz_503() {
    let (_dir, state, router) = setup(|c| {
        c.workers = 1;
        c.queue_capacity = 1;
    });
    let (_, _, s) = submit(&router, &named("slow running")).await;
    wait_until(&state, s["id"].as_str().unwrap(), |s| {
        s == JobState::Running
    })
    .await;
    let (st, _, _) = submit(&router, &named("slow waiting")).await;
    assert_eq!(st, StatusCode::ACCEPTED);
    let (st, h, b) = call(
        &router,
        post("/api/v1/jobs", named("slow refused").to_string()),
    )
    .await;
    problem(st, &h, &b, StatusCode::TOO_MANY_REQUESTS);
    assert!(
        h[header::RETRY_AFTER]
            .to_str()
            .unwrap()
            .parse::<u64>()
            .unwrap()
            > 0
    );
    let (st, h, b) = call(
        &router,
        post("/api/v1/render", named("slow refused").to_string()),
    )
    .await;
    problem(st, &h, &b, StatusCode::SERVICE_UNAVAILABLE);
    assert!(h.contains_key(header::RETRY_AFTER));
    let (st, _, _) = call(&router, get("/readyz")).await;
    assert_eq!(st, StatusCode::SERVICE_UNAVAILABLE);
    let (st, _, _) = call(&router, get("/healthz")).await;
    assert_eq!(st, StatusCode::OK);
    for s in state.queue.list(10) {
        state.queue.delete(&s.id).unwrap();
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn a_panicking_solve_fails_its_job_alone() {
    let (_dir, state, router) = setup(|_| {});
    let (_, _, s) = submit(&router, &named("panic please")).await;
    let failed = wait_until(&state, s["id"].as_str().unwrap(), |s| s.is_final()).await;
    assert_eq!(failed.state, JobState::Failed);
    let error = failed.error.unwrap();
    assert!(error.detail.contains("panicked"), "{}", error.detail);
    let (st, h, b) = call(&router, get(&format!("/api/v1/jobs/{}/result", failed.id))).await;
    problem(st, &h, &b, StatusCode::CONFLICT);
    // The pool and the server go on.
    let (_, _, s) = submit(&router, &named("after the panic")).await;
    let ok = wait_until(&state, s["id"].as_str().unwrap(), |s| s.is_final()).await;
    assert_eq!(ok.state, JobState::Succeeded);
    let (st, h, b) = call(
        &router,
        post("/api/v1/render", named("panic sync").to_string()),
    )
    .await;
    let p = problem(st, &h, &b, StatusCode::INTERNAL_SERVER_ERROR);
    assert!(p["detail"].as_str().unwrap().contains("panicked"));
}

#[tokio::test(flavor = "multi_thread")]
async fn a_solve_past_job_timeout_fails() {
    let (_dir, state, router) = setup(|c| c.job_timeout = Duration::from_millis(300));
    let (_, _, s) = submit(&router, &named("slow timeout")).await;
    let failed = wait_until(&state, s["id"].as_str().unwrap(), |s| s.is_final()).await;
    assert_eq!(failed.state, JobState::Failed);
    assert_eq!(failed.error.unwrap().kind, "/problems/timeout");
}

#[tokio::test(flavor = "multi_thread")]
async fn unsupported_solves_fail_with_a_problem() {
    let (_dir, state, router) = setup(|_| {});
    let mut doc = scene("flatland-parallel");
    doc["solver"]["method"] = json!("hierarchical");
    let (_, _, s) = submit(&router, &doc).await;
    let done = wait_until(&state, s["id"].as_str().unwrap(), |s| s.is_final()).await;
    // Either this build solves it or it says why not; the server keeps serving.
    if done.state == JobState::Failed {
        assert!(!done.error.unwrap().detail.is_empty());
    } else {
        assert_eq!(done.state, JobState::Succeeded);
    }
    assert_eq!(call(&router, get("/healthz")).await.0, StatusCode::OK);
}

#[tokio::test(flavor = "multi_thread")]
async fn events_stream_the_status_until_the_job_ends() {
    let (_dir, state, router) = setup(|_| {});
    let (_, _, s) = submit(&router, &named("events")).await;
    let id = s["id"].as_str().unwrap();
    let (st, h, b) = call(&router, get(&format!("/api/v1/jobs/{id}/events"))).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(h[header::CONTENT_TYPE], "text/event-stream");
    let text = String::from_utf8(b.to_vec()).unwrap();
    let statuses: Vec<Value> = text
        .lines()
        .filter_map(|l| l.strip_prefix("data: "))
        .map(|d| serde_json::from_str(d).unwrap())
        .collect();
    assert!(text.contains("event: status"));
    assert_eq!(statuses.last().unwrap()["state"], "succeeded");
    assert!(statuses.iter().all(|s| s["id"] == id));
    // A finished job: one event, then the stream closes.
    let (_, _, b) = call(&router, get(&format!("/api/v1/jobs/{id}/events"))).await;
    assert_eq!(String::from_utf8_lossy(&b).matches("data: ").count(), 1);
    assert_eq!(
        state.queue.get(id).unwrap().status().state,
        JobState::Succeeded
    );
}

#[tokio::test(flavor = "multi_thread")]
async fn render_answers_png_or_json_at_once() {
    let (_dir, _state, router) = setup(|_| {});
    let doc = scene("fredholm-degenerate");
    let (st, h, png) = call(&router, post("/api/v1/render", doc.to_string())).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(h[header::CONTENT_TYPE], "image/png");
    assert_eq!(&png[..4], b"\x89PNG");
    let req = Request::post("/api/v1/render")
        .header(header::CONTENT_TYPE, "application/json")
        .header(header::ACCEPT, "application/json")
        .body(Body::from(doc.to_string()))
        .unwrap();
    let (st, h, b) = call(&router, req).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(h[header::CONTENT_TYPE], "application/json");
    assert_eq!(json(&b)["kind"], "fredholm");
}

#[tokio::test(flavor = "multi_thread")]
async fn render_answers_503_past_the_sync_timeout() {
    let (_dir, state, router) = setup(|c| c.sync_timeout = Duration::from_millis(200));
    let (st, h, b) = call(
        &router,
        post("/api/v1/render", named("slow sync").to_string()),
    )
    .await;
    problem(st, &h, &b, StatusCode::SERVICE_UNAVAILABLE);
    assert!(h.contains_key(header::RETRY_AFTER));
    // the job it goes on as
    let id = wavrad::server::queue::job_id(&named("slow sync"));
    assert_eq!(h[header::LOCATION], format!("/api/v1/jobs/{id}").as_str());
    for s in state.queue.list(10) {
        state.queue.delete(&s.id).unwrap();
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn load_is_shed_beyond_the_concurrency_limit() {
    let (_dir, state, router) = setup(|c| c.max_concurrent_requests = 1);
    let r = router.clone();
    let busy = tokio::spawn(async move {
        call(&r, post("/api/v1/render", named("slow busy").to_string())).await
    });
    let id = wavrad::server::queue::job_id(&named("slow busy"));
    loop {
        if state.queue.get(&id).is_some() {
            break;
        }
        tokio::task::yield_now().await;
    }
    let (st, h, b) = call(&router, get("/api/v1/jobs")).await;
    problem(st, &h, &b, StatusCode::SERVICE_UNAVAILABLE);
    assert!(h.contains_key(header::RETRY_AFTER));
    // the probes answer all the same: the server is alive, only busy
    assert_eq!(call(&router, get("/healthz")).await.0, StatusCode::OK);
    assert_eq!(call(&router, get("/metrics")).await.0, StatusCode::OK);
    state.queue.delete(&id).unwrap();
    let _ = busy.await;
    assert_eq!(call(&router, get("/healthz")).await.0, StatusCode::OK);
}

#[tokio::test(flavor = "multi_thread")]
async fn finished_results_expire_after_result_ttl() {
    let (_dir, state, router) = setup(|c| c.result_ttl = Duration::from_millis(300));
    let (_, _, s) = submit(&router, &named("short-lived")).await;
    let id = s["id"].as_str().unwrap().to_string();
    wait_until(&state, &id, |s| s.is_final()).await;
    let deadline = Instant::now() + Duration::from_secs(10);
    while call(&router, get(&format!("/api/v1/jobs/{id}"))).await.0 == StatusCode::OK {
        assert!(Instant::now() < deadline, "not expired");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let (st, _, _) = call(&router, get(&format!("/api/v1/jobs/{id}/result"))).await;
    assert_eq!(st, StatusCode::NOT_FOUND);
}

/// With a store limit of one byte every finished job is over it: each is forgotten as soon as
/// it has finished and then answers as an expired job does (404), while the job queued behind
/// it, and then running, is kept.
#[tokio::test(flavor = "multi_thread")]
async fn finished_jobs_beyond_max_store_bytes_are_forgotten_and_unfinished_ones_kept() {
    let (_dir, state, router) = setup(|c| {
        c.max_store_bytes = 1;
        c.workers = 1;
        c.job_timeout = Duration::from_millis(1500);
    });
    let gone = |id: String| {
        let router = router.clone();
        async move {
            let deadline = Instant::now() + Duration::from_secs(10);
            while call(&router, get(&format!("/api/v1/jobs/{id}"))).await.0 == StatusCode::OK {
                assert!(Instant::now() < deadline, "not forgotten");
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
            let (st, _, _) = call(&router, get(&format!("/api/v1/jobs/{id}"))).await;
            assert_eq!(st, StatusCode::NOT_FOUND);
            let (st, _, _) = call(&router, get(&format!("/api/v1/jobs/{id}/result"))).await;
            assert_eq!(st, StatusCode::NOT_FOUND);
        }
    };
    // two jobs that run until job_timeout fails them, one after the other on one worker
    let (_, _, s) = submit(&router, &named("slow first")).await;
    let first = s["id"].as_str().unwrap().to_string();
    wait_until(&state, &first, |s| s == JobState::Running).await;
    let (_, _, s) = submit(&router, &named("slow second")).await;
    let second = s["id"].as_str().unwrap().to_string();
    let (st, _, s) = call(&router, get(&format!("/api/v1/jobs/{second}"))).await;
    assert_eq!(
        (st, json(&s)["state"].as_str()),
        (StatusCode::OK, Some("queued"))
    );
    let done = wait_until(&state, &first, |s| s.is_final()).await;
    assert_eq!(done.state, JobState::Failed);
    gone(first).await;
    let (st, _, s) = call(&router, get(&format!("/api/v1/jobs/{second}"))).await;
    assert_eq!(
        st,
        StatusCode::OK,
        "a queued or running job is never forgotten"
    );
    assert!(
        ["queued", "running"].contains(&json(&s)["state"].as_str().unwrap()),
        "{s:?}"
    );
    wait_until(&state, &second, |s| s.is_final()).await;
    gone(second).await;
}

#[tokio::test(flavor = "multi_thread")]
async fn operations_routes() {
    let (_dir, state, router) = setup(|_| {});
    let (st, _, b) = call(&router, get("/healthz")).await;
    assert_eq!((st, &b[..]), (StatusCode::OK, &b"ok\n"[..]));
    assert_eq!(call(&router, get("/readyz")).await.0, StatusCode::OK);

    let (_, _, s) = submit(&router, &named("metrics")).await;
    wait_until(&state, s["id"].as_str().unwrap(), |s| s.is_final()).await;
    let (st, _, b) = call(&router, get("/metrics")).await;
    assert_eq!(st, StatusCode::OK);
    let text = String::from_utf8(b.to_vec()).unwrap();
    for needle in [
        "wavrad_jobs{state=\"succeeded\"} 1",
        "wavrad_queue_depth 0",
        "wavrad_solve_seconds_count 1",
        "wavrad_http_requests_total{method=\"POST\",route=\"/api/v1/jobs\",status=\"202\"} 1",
    ] {
        assert!(text.contains(needle), "{needle} not in\n{text}");
    }

    let (st, _, b) = call(&router, get("/api/v1/openapi.json")).await;
    assert_eq!(st, StatusCode::OK);
    let api = json(&b);
    assert!(api["openapi"].as_str().unwrap().starts_with("3."));
    for path in [
        "/api/v1/jobs",
        "/api/v1/jobs/{id}",
        "/api/v1/jobs/{id}/events",
        "/api/v1/jobs/{id}/result",
        "/api/v1/jobs/{id}/{artifact}",
        "/api/v1/jobs/{id}/surfaces/{file}",
        "/api/v1/render",
        "/api/v1/openapi.json",
        "/healthz",
        "/readyz",
        "/metrics",
        "/",
    ] {
        assert!(
            api["paths"][path].is_object(),
            "{path} missing from the OpenAPI document"
        );
    }
    assert!(api["paths"]["/api/v1/jobs"]["post"]["responses"]["422"].is_object());
    let render = &api["paths"]["/api/v1/render"]["post"]["responses"];
    for status in ["200", "409", "422", "503", "504"] {
        assert!(render[status].is_object(), "render lacks {status}");
    }
    for answer in ["image/png", "application/json"] {
        assert!(render["200"]["content"][answer].is_object(), "{answer}");
    }
    // the content type /metrics is served with, and the load shedding of every route but
    // the probes and /metrics
    let (_, h, _) = call(&router, get("/metrics")).await;
    let served = h[header::CONTENT_TYPE].to_str().unwrap();
    assert!(api["paths"]["/metrics"]["get"]["responses"]["200"]["content"][served].is_object());
    for (path, method) in [
        ("/api/v1/jobs", "post"),
        ("/api/v1/jobs/{id}", "get"),
        ("/api/v1/jobs/{id}", "delete"),
        ("/", "get"),
    ] {
        assert!(
            api["paths"][path][method]["responses"]["503"].is_object(),
            "{method} {path}"
        );
    }
    assert!(api["paths"]["/healthz"]["get"]["responses"]["503"].is_null());
    let png = &api["paths"]["/api/v1/jobs/{id}/{artifact}"]["get"]["responses"];
    assert!(png["304"].is_object());
    let schema = &png["200"]["content"]["image/png"]["schema"];
    let schema = match schema["$ref"].as_str() {
        Some(r) => &api["components"]["schemas"][r.rsplit('/').next().unwrap()],
        None => schema,
    };
    assert_eq!(
        (schema["type"].as_str(), schema["format"].as_str()),
        (Some("string"), Some("binary")),
        "{schema}"
    );
    // only the scene is required, and no part may be null
    let schemas = &api["components"]["schemas"];
    let document = &schemas["JobDocument"];
    assert_eq!(document["required"], json!(["scene"]));
    for part in ["scene", "solver", "output"] {
        let r = document["properties"][part]["$ref"]
            .as_str()
            .unwrap_or_default();
        let schema = &schemas[r.rsplit('/').next().unwrap()];
        // an object, or one of several objects (the scene's kinds); never null
        let kinds: Vec<&Value> = match schema["oneOf"].as_array() {
            Some(alts) => alts.iter().map(|a| &a["type"]).collect(),
            None => vec![&schema["type"]],
        };
        assert!(!kinds.is_empty(), "{part}: {schema}");
        for t in kinds {
            assert_eq!(t, &json!("object"), "{part}: {schema}");
        }
    }
    // the result is described field by field, from the type it is serialised from
    let result = &schemas["JobResult"];
    for field in [
        "surfaces",
        "coefficients",
        "metrics",
        "timings_ms",
        "warnings",
    ] {
        assert!(result["properties"][field].is_object(), "{field}: {result}");
    }

    let (st, h, b) = call(&router, get("/")).await;
    assert_eq!(st, StatusCode::OK);
    assert!(h[header::CONTENT_TYPE]
        .to_str()
        .unwrap()
        .starts_with("text/html"));
    let html = String::from_utf8(b.to_vec()).unwrap();
    // the form's order goes as high as this server allows
    let max_order = format!("max=\"{}\"", state.config.max_order);
    assert!(html.contains(&max_order), "{max_order}");
    for id in [
        "scene-select",
        "doc",
        "method",
        "basis",
        "order",
        "resolution",
        "keep-kind",
        "submit",
        "progress",
        "image",
        "sparsity",
        "coefficients",
        "surfaces-body",
        "metrics",
        "errors",
    ] {
        assert!(html.contains(&format!("id=\"{id}\"")), "#{id} missing");
    }
    assert_eq!(call(&router, get("/static/app.js")).await.0, StatusCode::OK);
    assert_eq!(
        call(&router, get("/static/style.css")).await.0,
        StatusCode::OK
    );
    // the page offers every example scene the project ships, as shipped
    let names = json(&call(&router, get("/scenes/index.json")).await.2);
    let mut shipped: Vec<String> =
        std::fs::read_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes"))
            .unwrap()
            .filter_map(|e| {
                let name = e.unwrap().file_name().into_string().unwrap();
                name.strip_suffix(".json").map(str::to_string)
            })
            .collect();
    shipped.sort();
    let mut offered: Vec<String> = serde_json::from_value(names).unwrap();
    offered.sort();
    assert_eq!(offered, shipped);
    for name in &shipped {
        let (st, _, b) = call(&router, get(&format!("/scenes/{name}.json"))).await;
        assert_eq!(st, StatusCode::OK, "{name}");
        assert_eq!(json(&b), scene(name));
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn the_list_limit_says_what_is_allowed_and_when_it_was_capped() {
    let (_dir, state, router) = setup(|_| {});
    let (_, _, s) = submit(&router, &named("one")).await;
    wait_until(&state, s["id"].as_str().unwrap(), |s| s.is_final()).await;
    for bad in ["-1", "ten", "1.5", ""] {
        let (st, h, b) = call(&router, get(&format!("/api/v1/jobs?limit={bad}"))).await;
        assert_eq!(st, StatusCode::BAD_REQUEST, "limit={bad}");
        assert_eq!(h[header::CONTENT_TYPE], "application/problem+json");
        let p = json(&b);
        let detail = p["detail"].as_str().unwrap();
        assert!(
            detail.starts_with("limit is a whole number from 0 to 1000"),
            "{detail}"
        );
        assert!(detail.contains(&format!("found \"{bad}\"")), "{detail}");
    }
    let (st, h, b) = call(&router, get("/api/v1/jobs?limit=2000")).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(h["limit-capped"], "2000; applied=1000");
    assert_eq!(h[header::LINK], "</api/v1/jobs?limit=1000>; rel=\"self\"");
    assert_eq!(json(&b).as_array().unwrap().len(), 1);
    // within the limit: no such header
    for ok in [
        "/api/v1/jobs?limit=1000",
        "/api/v1/jobs?limit=0",
        "/api/v1/jobs",
    ] {
        let (st, h, _) = call(&router, get(ok)).await;
        assert_eq!(st, StatusCode::OK, "{ok}");
        assert!(h.get("limit-capped").is_none(), "{ok}");
        assert!(h.get(header::LINK).is_none(), "{ok}");
    }
}

#[tokio::test(flavor = "multi_thread")]
async fn surface_names_are_percent_encoded_in_links() {
    let (_dir, state, router) = setup(|_| {});
    let mut doc = named("spaces");
    doc["scene"]["surfaces"][1]["name"] = json!("top wall");
    let (_, _, s) = submit(&router, &doc).await;
    let id = s["id"].as_str().unwrap().to_string();
    let link = s["links"]["surfaces"]["top wall"]
        .as_str()
        .unwrap()
        .to_string();
    assert_eq!(link, format!("/api/v1/jobs/{id}/surfaces/top%20wall.png"));
    wait_until(&state, &id, |s| s.is_final()).await;
    let (st, h, _) = call(&router, get(&link)).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(h[header::CONTENT_TYPE], "image/png");
}

#[tokio::test(flavor = "multi_thread")]
async fn scene_glb_of_3d_jobs_409_until_done_404_for_other_kinds() {
    let (_dir, state, router) = setup(|_| {});
    // a 3d job held running: 409
    let mut slow = scene("plates-3d");
    slow["scene"]["name"] = json!("slow plates");
    let (_, _, s) = submit(&router, &slow).await;
    let id = s["id"].as_str().unwrap().to_string();
    assert_eq!(s["links"]["model"], format!("/api/v1/jobs/{id}/scene.glb"));
    wait_until(&state, &id, |s| s == JobState::Running).await;
    let (st, h, b) = call(&router, get(&format!("/api/v1/jobs/{id}/scene.glb"))).await;
    problem(st, &h, &b, StatusCode::CONFLICT);
    let (st, _, _) = call(&router, delete(&format!("/api/v1/jobs/{id}"))).await;
    assert_eq!(st, StatusCode::NO_CONTENT);

    // a finished 3d job: binary glTF, cached like the images
    let (_, _, s) = submit(&router, &scene("plates-3d")).await;
    let id = s["id"].as_str().unwrap().to_string();
    let done = wait_until(&state, &id, |s| s.is_final()).await;
    assert_eq!(done.state, JobState::Succeeded);
    let (st, h, b) = call(&router, get(&format!("/api/v1/jobs/{id}/scene.glb"))).await;
    assert_eq!(st, StatusCode::OK);
    assert_eq!(h[header::CONTENT_TYPE], "model/gltf-binary");
    assert_eq!(&b[..4], b"glTF");
    assert_eq!(
        u32::from_le_bytes(b[8..12].try_into().unwrap()) as usize,
        b.len()
    );
    let etag = h[header::ETAG].clone();
    let (st, _, _) = call(
        &router,
        Request::get(format!("/api/v1/jobs/{id}/scene.glb"))
            .header(header::IF_NONE_MATCH, etag)
            .body(Body::empty())
            .unwrap(),
    )
    .await;
    assert_eq!(st, StatusCode::NOT_MODIFIED);

    // flatland: none, before and after it has finished
    let (_, _, s) = submit(&router, &scene("flatland-parallel")).await;
    let id = s["id"].as_str().unwrap().to_string();
    assert!(s["links"].get("model").is_none());
    wait_until(&state, &id, |s| s.is_final()).await;
    let (st, h, b) = call(&router, get(&format!("/api/v1/jobs/{id}/scene.glb"))).await;
    problem(st, &h, &b, StatusCode::NOT_FOUND);
    let (st, h, b) = call(
        &router,
        get("/api/v1/jobs/0123456789abcdef0123456789abcdef/scene.glb"),
    )
    .await;
    problem(st, &h, &b, StatusCode::NOT_FOUND);
}

/// The page's 3D view needs nothing from elsewhere: every module that `view3d.js` imports,
/// through the page's import map and the relative imports of three.js, is served by the
/// binary as JavaScript, and three.js's licence beside it.
#[tokio::test(flavor = "multi_thread")]
async fn the_3d_view_and_every_module_it_imports_are_served() {
    let (_dir, _state, router) = setup(|_| {});
    let html = String::from_utf8(call(&router, get("/")).await.2.to_vec()).unwrap();
    for id in ["model-file", "view3d", "view3d-panel", "model-link"] {
        assert!(html.contains(&format!("id=\"{id}\"")), "#{id} missing");
    }
    let map_start = html
        .find(r#"<script type="importmap">"#)
        .expect("an import map");
    let map_text = &html[map_start + 25..];
    let map: Value =
        serde_json::from_str(&map_text[..map_text.find("</script>").unwrap()]).unwrap();
    let three = map["imports"]["three"].as_str().unwrap().to_string();
    let mut todo = vec!["/static/view3d.js".to_string()];
    let mut seen = std::collections::BTreeSet::new();
    while let Some(url) = todo.pop() {
        if !seen.insert(url.clone()) {
            continue;
        }
        let (st, h, b) = call(&router, get(&url)).await;
        assert_eq!(st, StatusCode::OK, "{url}");
        assert!(
            h[header::CONTENT_TYPE]
                .to_str()
                .unwrap()
                .starts_with("text/javascript"),
            "{url}"
        );
        let text = String::from_utf8(b.to_vec()).unwrap();
        // import … from "x", import "x" and export … from "x", as written or minified,
        // left out in comments (the examples in three.js's documentation)
        let code: String = text
            .lines()
            .filter(|l| {
                let t = l.trim_start();
                !(t.starts_with("//") || t.starts_with('*') || t.starts_with("/*"))
            })
            .collect::<Vec<_>>()
            .join("\n");
        let mut rest = code.as_str();
        while let Some(i) = rest.find("from") {
            rest = &rest[i + 4..];
            let t = rest.trim_start();
            let Some(q) = t.chars().next().filter(|c| *c == '"' || *c == '\'') else {
                continue;
            };
            let Some(end) = t[1..].find(q) else { continue };
            let spec = &t[1..1 + end];
            let dir = &url[..url.rfind('/').unwrap() + 1];
            let target = if spec == "three" {
                three.clone()
            } else if let Some(r) = spec.strip_prefix("./") {
                format!("{dir}{r}")
            } else if spec.starts_with("../") {
                let mut base: Vec<&str> = dir.trim_end_matches('/').split('/').collect();
                let mut s = spec;
                while let Some(r) = s.strip_prefix("../") {
                    base.pop();
                    s = r;
                }
                format!("{}/{s}", base.join("/"))
            } else if spec.starts_with('/') && !spec.starts_with("//") {
                spec.to_string()
            } else {
                // not from elsewhere; any other word after "from" is not a module
                assert!(
                    !spec.contains("//") && !spec.starts_with("http"),
                    "{url} imports {spec}"
                );
                continue;
            };
            todo.push(target);
        }
    }
    for needed in [
        "/static/view3d.js",
        "/static/vendor/three/build/three.module.min.js",
        "/static/vendor/three/build/three.core.min.js",
        "/static/vendor/three/examples/jsm/loaders/GLTFLoader.js",
        "/static/vendor/three/examples/jsm/utils/BufferGeometryUtils.js",
        "/static/vendor/three/examples/jsm/controls/OrbitControls.js",
    ] {
        assert!(seen.contains(needed), "{needed} not reached: {seen:?}");
    }
    let (st, _, b) = call(&router, get("/static/vendor/three/LICENSE")).await;
    assert_eq!(st, StatusCode::OK);
    assert!(String::from_utf8_lossy(&b).contains("MIT License"));
    let (st, _, _) = call(&router, get("/static/vendor/three/build/nope.js")).await;
    assert_eq!(st, StatusCode::NOT_FOUND);
}
