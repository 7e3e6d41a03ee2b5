//! The import speed goal: a model of 10⁵ triangles turned into a job document in under a
//! second, as OBJ + MTL and as GLB (both made here: a 10 × 10 grid of objects, each a
//! 32 × 16 grid of quads: 102 400 triangles). Figures in `benches/README.md`.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use serde_json::json;
use std::hint::black_box;
use wavrad::import::{import, Format, Model};
use wavrad::scene::Limits;

const OBJECTS: usize = 10;
const NU: usize = 32;
const NV: usize = 16;
const TRIANGLES: usize = OBJECTS * OBJECTS * NU * NV * 2;

/// The positions and triangles (0-based) of object (a, b): a gently curved grid.
fn object(a: usize, b: usize) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let mut p = Vec::new();
    for i in 0..=NU {
        for j in 0..=NV {
            let (x, z) = (
                a as f32 + i as f32 / NU as f32,
                b as f32 + j as f32 / NV as f32,
            );
            p.push([x, 0.1 * (x * 3.0).sin() * (z * 2.0).cos(), z]);
        }
    }
    let at = |i: usize, j: usize| (i * (NV + 1) + j) as u32;
    let mut t = Vec::new();
    for i in 0..NU {
        for j in 0..NV {
            t.push([at(i, j), at(i, j + 1), at(i + 1, j + 1)]);
            t.push([at(i, j), at(i + 1, j + 1), at(i + 1, j)]);
        }
    }
    (p, t)
}

fn obj() -> (String, String) {
    let mut text = String::from("mtllib grid.mtl\n");
    let mut base = 1;
    for a in 0..OBJECTS {
        for b in 0..OBJECTS {
            let (p, t) = object(a, b);
            text += &format!("o tile-{a}-{b}\nusemtl m{}\n", (a + b) % 4);
            for v in &p {
                text += &format!("v {} {} {}\n", v[0], v[1], v[2]);
            }
            for f in &t {
                text += &format!("f {} {} {}\n", f[0] + base, f[1] + base, f[2] + base);
            }
            base += p.len() as u32;
        }
    }
    let mtl = "newmtl m0\nKd 0.7 0.7 0.7\nKe 1 1 1\nnewmtl m1\nKd 0.5 0.2 0.2\n\
               newmtl m2\nKd 0.2 0.5 0.2\nnewmtl m3\nKd 0.2 0.2 0.5\n";
    (text, mtl.to_string())
}

/// A GLB of the same objects: one mesh and node each, positions and u32 indices in one buffer.
fn glb() -> Vec<u8> {
    let mut bin: Vec<u8> = Vec::new();
    let (mut views, mut accessors, mut meshes, mut nodes) = (vec![], vec![], vec![], vec![]);
    for a in 0..OBJECTS {
        for b in 0..OBJECTS {
            let (p, t) = object(a, b);
            let (lo, hi) = p
                .iter()
                .fold(([f32::MAX; 3], [f32::MIN; 3]), |(lo, hi), v| {
                    (
                        [0, 1, 2].map(|c| lo[c].min(v[c])),
                        [0, 1, 2].map(|c| hi[c].max(v[c])),
                    )
                });
            let start = bin.len();
            bin.extend(p.iter().flatten().flat_map(|x| x.to_le_bytes()));
            views.push(json!({"buffer": 0, "byteOffset": start, "byteLength": bin.len() - start}));
            accessors.push(json!({"bufferView": views.len() - 1, "componentType": 5126,
                "count": p.len(), "type": "VEC3", "min": lo, "max": hi}));
            let start = bin.len();
            bin.extend(t.iter().flatten().flat_map(|i| i.to_le_bytes()));
            views.push(json!({"buffer": 0, "byteOffset": start, "byteLength": bin.len() - start}));
            accessors.push(json!({"bufferView": views.len() - 1, "componentType": 5125,
                "count": t.len() * 3, "type": "SCALAR"}));
            meshes.push(
                json!({"primitives": [{"attributes": {"POSITION": accessors.len() - 2},
                "indices": accessors.len() - 1, "material": (a + b) % 2}]}),
            );
            nodes.push(json!({"name": format!("tile-{a}-{b}"), "mesh": meshes.len() - 1}));
        }
    }
    let doc = json!({
        "asset": {"version": "2.0"}, "scene": 0,
        "scenes": [{"nodes": (0..nodes.len()).collect::<Vec<_>>()}],
        "nodes": nodes, "meshes": meshes, "accessors": accessors, "bufferViews": views,
        "buffers": [{"byteLength": bin.len()}],
        "materials": [
            {"pbrMetallicRoughness": {"baseColorFactor": [0.7, 0.7, 0.7, 1]}, "emissiveFactor": [1, 1, 1]},
            {"pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.2, 0.2, 1]}}
        ]
    });
    let mut chunk = doc.to_string().into_bytes();
    while !chunk.len().is_multiple_of(4) {
        chunk.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let mut out = Vec::new();
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend(((12 + 8 + chunk.len() + 8 + bin.len()) as u32).to_le_bytes());
    out.extend((chunk.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(chunk);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(bin);
    out
}

fn bench(c: &mut Criterion) {
    let (text, mtl) = obj();
    let glb = glb();
    let limits = Limits::default();
    let files = move |name: &str| (name == "grid.mtl").then(|| mtl.as_bytes().to_vec());
    let mut g = c.benchmark_group("import 102 400 triangles");
    g.sample_size(10);
    g.throughput(Throughput::Elements(TRIANGLES as u64));
    for (name, format, bytes) in [
        ("obj + mtl", Format::Obj, text.as_bytes()),
        ("glb", Format::Glb, glb.as_slice()),
    ] {
        let model = Model {
            file: "grid",
            format,
            bytes,
        };
        let once = import(model, &files, &limits).expect("imports");
        assert_eq!(once.triangles, TRIANGLES);
        assert!(once.warnings.is_empty(), "{:?}", once.warnings);
        g.bench_function(name, |b| {
            b.iter(|| black_box(import(model, &files, &limits).expect("imports")))
        });
        // and the document as JSON text, as the server answers it
        g.bench_function(format!("{name}, serialised"), |b| {
            b.iter(|| {
                let doc = import(model, &files, &limits).expect("imports").document;
                black_box(serde_json::to_vec(&doc).expect("serialises"))
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
