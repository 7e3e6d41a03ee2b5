//! `scene.glb` export speed: about 10⁵ triangles from quadtree fields with T-junctions
//! everywhere (leaves refined to the finest level along a diagonal, coarse elsewhere, order 1),
//! meshed without T-vertices and written as GLB. Figure in `benches/README.md`; target under 1 s.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use std::hint::black_box;
use wavrad::math::field::{Field, Leaf};
use wavrad::render::glb;

/// A quadtree of `res × res` finest cells, split down to the finest level where a cell is
/// within its own size of the diagonal s = t, with order-1 coefficients that vary by leaf.
fn field(res: usize) -> Field {
    fn split(s: usize, t: usize, size: usize, res: usize, out: &mut Vec<Leaf>) {
        let near = (s as i64 - t as i64).unsigned_abs() as usize <= size;
        if size > 1 && near {
            let h = size / 2;
            for (ds, dt) in [(0, 0), (h, 0), (0, h), (h, h)] {
                split(s + ds, t + dt, h, res, out);
            }
            return;
        }
        let r = res as f64;
        let v = 1.0 + ((s * 7 + t * 13) % 17) as f64 / 17.0;
        out.push(Leaf {
            s: [s as f64 / r, (s + size) as f64 / r],
            t: [t as f64 / r, (t + size) as f64 / r],
            coeffs: vec![[v, 0.8 * v, 0.6 * v], [0.1; 3], [0.05; 3], [0.01; 3]],
            upper: false,
        });
    }
    let mut leaves = Vec::new();
    split(0, 0, res, res, &mut leaves);
    Field::from_leaves(2, 1, res, leaves)
}

fn export(c: &mut Criterion) {
    // five squares of side 10, each a quadtree of 512 × 512 finest cells refined along its
    // diagonal: about 10⁵ triangles
    let f = field(512);
    let faces: Vec<[[f64; 3]; 4]> = (0..5)
        .map(|k| {
            let z = k as f64 * 10.0;
            [
                [0.0, 0.0, z],
                [10.0, 0.0, z],
                [10.0, 10.0, z],
                [0.0, 10.0, z],
            ]
        })
        .collect();
    let meshes = |white: f64| -> Vec<glb::LitMesh> {
        faces
            .iter()
            .enumerate()
            .map(|(k, q)| glb::parallelogram(&format!("face {k}"), q, &f, white))
            .collect()
    };
    let triangles: usize = meshes(1.0).iter().map(|m| m.triangles.len()).sum();
    let bytes = glb::write(Some("bench"), &meshes(1.0), 1.0, None).len();
    eprintln!(
        "{} leaves per face, {triangles} triangles, {bytes} bytes of GLB",
        f.leaves.len()
    );
    let mut g = c.benchmark_group("scene.glb");
    g.sample_size(10);
    g.throughput(Throughput::Elements(triangles as u64));
    g.bench_function("mesh and write", |b| {
        b.iter(|| black_box(glb::write(Some("bench"), &meshes(0.5), 0.5, None)))
    });
    g.finish();
}

criterion_group!(benches, export);
criterion_main!(benches);
