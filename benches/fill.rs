//! Matrix fill for two unoccluded facing unit segments (the slides' flatland scene 1),
//! m = 0 … 2, n = 16 … 1024: kernel evaluations per second (criterion reports the throughput).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use wavrad::flatland::projection as flatland;
use wavrad::methods::projection::Discretization;
use wavrad::progress::Silent;
use wavrad::scene::{parse_value, Limits, SceneKind};

fn segments() -> Vec<wavrad::scene::Segment> {
    let doc = serde_json::json!({"scene": {"kind": "flatland", "surfaces": [
        {"name": "bottom", "segment": [[0, 0], [1, 0]], "reflectance": 0.5, "emission": 1},
        {"name": "top", "segment": [[1, 1], [0, 1]], "reflectance": 0.8}]}});
    match parse_value(&doc, &Limits::default()).unwrap().scene.kind {
        SceneKind::Flatland(s) => s,
        _ => unreachable!(),
    }
}

fn fill(c: &mut Criterion) {
    let geo = flatland::Geometry::new(&segments());
    let mut group = c.benchmark_group("fill");
    group.sample_size(10);
    for order in 0..=2 {
        for cells in [16, 64, 256, 1024] {
            let disc = Discretization {
                order,
                cells,
                quadrature: order + 2,
            };
            let (_, evals) = flatland::matrix(&geo, disc, &Silent).unwrap();
            group.throughput(Throughput::Elements(evals));
            group.bench_with_input(
                BenchmarkId::new(format!("m{order}"), cells),
                &disc,
                |b, &disc| b.iter(|| flatland::matrix(&geo, disc, &Silent).unwrap()),
            );
        }
    }
    group.finish();
}

criterion_group!(benches, fill);
criterion_main!(benches);
