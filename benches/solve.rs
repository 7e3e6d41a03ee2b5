//! The sparse solve: one Jacobi sweep over three channels costs time proportional to the kept
//! entries. Flatland scene 1 at n = 256, m = 1 in the wavelet basis, keeping the top N entries.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use wavrad::methods::compress;
use wavrad::methods::projection::Discretization;
use wavrad::methods::solve::{self, Settings};
use wavrad::progress::Silent;
use wavrad::scene::{parse_value, Iteration, Keep, Limits};

fn sweeps(c: &mut Criterion) {
    let doc: serde_json::Value =
        serde_json::from_str(include_str!("../scenes/flatland-parallel.json")).unwrap();
    let job = parse_value(&doc, &Limits::default()).unwrap();
    let disc = Discretization {
        order: 1,
        cells: 256,
        quadrature: 3,
    };
    let mut system = wavrad::job::system(&job, disc, &Silent).unwrap();
    compress::to_wavelet(&mut system, &Silent).unwrap();
    let ranking = compress::Ranking::new(&system.matrix.data, &Silent).unwrap();
    let rho: Vec<[f64; 3]> = (0..system.size())
        .map(|i| system.reflectance[system.surface_of(i)])
        .collect();
    let settings = Settings {
        iteration: Iteration::Jacobi,
        tolerance: 1e-300,
        max_iterations: 20,
    };
    let mut group = c.benchmark_group("solve_20_sweeps");
    group.sample_size(10);
    for top in [1 << 12, 1 << 14, 1 << 16, 1 << 18, 1 << 20] {
        let kept = compress::threshold(&system.matrix, Keep::Top(top), &ranking);
        group.throughput(Throughput::Elements(20 * kept.csr.nnz() as u64));
        group.bench_with_input(BenchmarkId::new("jacobi", top), &kept, |b, kept| {
            b.iter(|| solve::solve(&kept.csr, &rho, &system.emission, settings, &Silent).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, sweeps);
criterion_main!(benches);
