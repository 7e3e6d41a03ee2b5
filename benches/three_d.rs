//! The 3D speed goals: the Cornell box by the hierarchical method (solve, and solve + a
//! 512 × 512 image), the gallery's rooms with 3 × 3 and 7 × 7 boxes at the document defaults,
//! visibility rays through the BVH, building the BVHs of 10⁵ triangles, and projection against hierarchical on the parallel plates
//! as the resolution grows. Figures in `benches/README.md`.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use rayon::prelude::*;
use std::hint::black_box;
use wavrad::job;
use wavrad::progress::Silent;
use wavrad::render::camera;
use wavrad::scene::{parse_document, parse_value, Job, Limits, SceneKind};
use wavrad::three_d::bvh::Bvh;
use wavrad::three_d::geometry::Parallelogram;
use wavrad::three_d::visibility::SplitMix;

fn scene(name: &str) -> String {
    std::fs::read_to_string(format!("{}/scenes/{name}.json", env!("CARGO_MANIFEST_DIR")))
        .expect("scene")
}

fn cornell() -> Job {
    parse_document(&scene("cornell-box"), &Limits::default()).expect("valid")
}

fn cornell_box(c: &mut Criterion) {
    let j = cornell();
    let mut g = c.benchmark_group("cornell-box");
    g.sample_size(10);
    g.bench_function("hierarchical solve", |b| {
        b.iter(|| black_box(job::run(&j, &Silent).expect("solves")))
    });
    g.bench_function("hierarchical solve + 512x512 image", |b| {
        b.iter(|| {
            let out = job::run(&j, &Silent).expect("solves");
            black_box(camera::render(&j, &out, 512, 512))
        })
    });
    g.finish();
}

fn gallery(c: &mut Criterion) {
    let mut g = c.benchmark_group("gallery at the defaults");
    g.sample_size(10);
    for name in ["room-3x3", "room-7x7"] {
        let j =
            parse_document(&scene(&format!("gallery/{name}")), &Limits::default()).expect("valid");
        g.bench_function(format!("{name} hierarchical solve"), |b| {
            b.iter(|| black_box(job::run(&j, &Silent).expect("solves")))
        });
    }
    g.finish();
}

fn rays(c: &mut Criterion) {
    let j = cornell();
    let SceneKind::ThreeD(quads) = &j.scene.kind else {
        unreachable!()
    };
    let geo: Vec<Parallelogram> = quads
        .iter()
        .map(|q| Parallelogram::new(&q.corners))
        .collect();
    let bvh = Bvh::occluders(&geo);
    // segments between random points of random pairs of surfaces, as the visibility tests cast
    let mut rng = SplitMix(7);
    let n = 1 << 20;
    let segs: Vec<([f64; 3], [f64; 3], [usize; 2])> = (0..n)
        .map(|_| {
            let i = (rng.next_u64() % geo.len() as u64) as usize;
            let k = (rng.next_u64() % geo.len() as u64) as usize;
            let a = geo[i].at(rng.next_f64(), rng.next_f64());
            let b = geo[k].at(rng.next_f64(), rng.next_f64());
            (a, b, [i, k])
        })
        .collect();
    let mut g = c.benchmark_group("visibility");
    g.sample_size(10);
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("rays through the BVH (cornell box, all cores)", |b| {
        b.iter(|| {
            segs.par_iter()
                .filter(|(a, e, skip)| bvh.occluded(*a, *e, *skip))
                .count()
        })
    });
    // the camera's walk: the nearest hit along each segment's direction, whole scene
    let all = Bvh::new(&geo);
    g.bench_function("first hits through the BVH (cornell box, all cores)", |b| {
        b.iter(|| {
            segs.par_iter()
                .filter(|(a, e, _)| {
                    let d = [e[0] - a[0], e[1] - a[1], e[2] - a[2]];
                    all.first_hit(*a, d, 1e-9, f64::INFINITY, [usize::MAX; 2])
                        .is_some()
                })
                .count()
        })
    });
    g.finish();
}

fn growth(c: &mut Criterion) {
    let base: serde_json::Value = serde_json::from_str(&scene("plates-3d")).expect("json");
    let mut g = c.benchmark_group("plates-3d growth");
    g.sample_size(10);
    for n in [8usize, 16, 32] {
        for method in ["projection", "hierarchical"] {
            if method == "projection" && n > 16 {
                continue;
            }
            let mut doc = base.clone();
            doc["solver"] = serde_json::json!({ "method": method, "order": 0, "resolution": n, "epsilon": 1e-3 });
            let j = parse_value(&doc, &Limits::default()).expect("valid");
            g.bench_function(format!("{method} n={n}"), |b| {
                b.iter(|| black_box(job::run(&j, &Silent).expect("solves")))
            });
        }
    }
    g.finish();
}

/// Building the BVHs of a flat mesh of 100 352 triangles (a 224 × 224 grid of squares, each
/// two triangles) over a plane, the worst case of the occluders' test: every triangle has the
/// whole scene on its front.
fn bvh_build(c: &mut Criterion) {
    let n = 224;
    let corner = |i: usize, j: usize| [i as f64 / n as f64 * 10.0, 0.0, j as f64 / n as f64 * 10.0];
    let mut geo = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let (a, b, c, d) = (
                corner(i, j),
                corner(i, j + 1),
                corner(i + 1, j),
                corner(i + 1, j + 1),
            );
            // (p0, p1, p2) as a triangle patch: corners p0, p1, p1 + p2 − p0, p2
            for [p0, p1, p2] in [[a, b, d], [a, d, c]] {
                let far = [0, 1, 2].map(|k| p1[k] + p2[k] - p0[k]);
                let mut q = Parallelogram::new(&[p0, p1, far, p2]);
                q.tri = true;
                geo.push(q);
            }
        }
    }
    let mut g = c.benchmark_group("bvh");
    g.sample_size(10);
    g.throughput(Throughput::Elements(geo.len() as u64));
    g.bench_function("build, 100 352 coplanar triangles", |b| {
        b.iter(|| black_box(Bvh::new(&geo)))
    });
    g.bench_function("occluders, 100 352 coplanar triangles", |b| {
        b.iter(|| black_box(Bvh::occluders(&geo)))
    });
    g.finish();
}

criterion_group!(benches, cornell_box, gallery, rays, growth, bvh_build);
criterion_main!(benches);
