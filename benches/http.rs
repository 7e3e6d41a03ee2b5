//! The HTTP layer: small flatland jobs per second through `POST /api/v1/render`, and the
//! overhead of the service (HTTP, queue, images, store) over calling `wavrad::job::run`
//! directly for a job that takes about 50 ms to solve. Figures: `benches/README.md`.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use serde_json::{json, Value};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

fn doc(order: usize, resolution: usize) -> Value {
    let text = std::fs::read_to_string(format!(
        "{}/scenes/flatland-parallel.json",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap();
    let mut d: Value = serde_json::from_str(&text).unwrap();
    d["solver"]["order"] = json!(order);
    d["solver"]["resolution"] = json!(resolution);
    d
}

/// The ~50 ms job: order 3, 64 cells per segment (512 unknowns).
const MEDIUM: (usize, usize) = (3, 64);
const SMALL: (usize, usize) = (1, 8);

static COUNTER: AtomicUsize = AtomicUsize::new(0);

/// A document no run has sent before (a new name), so that every request is solved.
fn fresh(base: &Value) -> String {
    let mut d = base.clone();
    d["scene"]["name"] = json!(format!("bench {}", COUNTER.fetch_add(1, Ordering::Relaxed)));
    d.to_string()
}

fn bench(c: &mut Criterion) {
    let rt = tokio::runtime::Runtime::new().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut config = wavrad::server::Config::with_data_dir(dir.path());
    config.workers = 2;
    config.queue_capacity = 1024;
    let listener = rt
        .block_on(tokio::net::TcpListener::bind("127.0.0.1:0"))
        .unwrap();
    let base = format!("http://{}", listener.local_addr().unwrap());
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let server = rt.spawn(wavrad::server::run(listener, config, async move {
        let _ = stopped.await;
    }));
    let http = reqwest::Client::new();
    let render = |body: String, accept: &'static str| {
        let http = http.clone();
        let url = format!("{base}/api/v1/render");
        async move {
            let res = http
                .post(url)
                .header("content-type", "application/json")
                .header("accept", accept)
                .body(body)
                .send()
                .await
                .unwrap();
            assert_eq!(res.status(), 200);
            res.bytes().await.unwrap()
        }
    };

    let small = doc(SMALL.0, SMALL.1);
    let mut group = c.benchmark_group("http");
    group.throughput(Throughput::Elements(1));
    group.sample_size(30);
    group.bench_function("small flatland job, POST /api/v1/render (png)", |b| {
        b.iter(|| rt.block_on(render(fresh(&small), "image/png")))
    });
    group.bench_function("small flatland job, POST /api/v1/render (json)", |b| {
        b.iter(|| rt.block_on(render(fresh(&small), "application/json")))
    });
    let small_job = wavrad::scene::parse_value(&small, &wavrad::scene::Limits::default()).unwrap();
    group.bench_function("small flatland job, job::run + render_all directly", |b| {
        b.iter(|| {
            let outcome = wavrad::job::run(&small_job, &wavrad::progress::Silent).unwrap();
            wavrad::render::render_all(&small_job, &outcome)
        })
    });
    group.bench_function("small flatland job, job::run directly", |b| {
        b.iter(|| wavrad::job::run(&small_job, &wavrad::progress::Silent).unwrap())
    });
    group.finish();

    let medium = doc(MEDIUM.0, MEDIUM.1);
    let job = wavrad::scene::parse_value(&medium, &wavrad::scene::Limits::default()).unwrap();
    let mut group = c.benchmark_group("overhead");
    group
        .sample_size(20)
        .measurement_time(Duration::from_secs(12));
    group.bench_function("job::run directly", |b| {
        b.iter(|| wavrad::job::run(&job, &wavrad::progress::Silent).unwrap())
    });
    group.bench_function("job::run + render::render_all directly", |b| {
        b.iter(|| {
            let outcome = wavrad::job::run(&job, &wavrad::progress::Silent).unwrap();
            wavrad::render::render_all(&job, &outcome)
        })
    });
    group.bench_function("POST /api/v1/render (json)", |b| {
        b.iter(|| rt.block_on(render(fresh(&medium), "application/json")))
    });
    group.bench_function("POST /api/v1/render (png)", |b| {
        b.iter(|| rt.block_on(render(fresh(&medium), "image/png")))
    });
    group.finish();

    stop.send(()).unwrap();
    rt.block_on(server).unwrap().unwrap();
}

criterion_group!(benches, bench);
criterion_main!(benches);
