//! The furnished room (`scenes/models/room.obj`, 11 860 triangles in 27 objects) at the
//! document defaults against the independent path tracer of `tests/tracer`: every object's
//! mean, the gap to the reference in percent and in the reference's standard errors. The
//! table of `benches/README.md` is its output:
//!
//! ```text
//! cargo run --release --example furnished_room -- [SAMPLES_PER_OBJECT] [only=PREFIX,...] [key=value ...]
//! ```
//!
//! SAMPLES_PER_OBJECT (default 2¹⁸) are the reference's paths per object; `only` keeps the
//! objects whose names start with one of the prefixes, to take the room apart
//! (`only=floor,ceiling,wall,window,lamp`); each other `key=value` sets a field of the
//! document's `solver` (`epsilon=5e-4`). The reference's seed is fixed, so two builds compared
//! on the same arguments differ by their solvers alone.

#[path = "../tests/tracer/mod.rs"]
mod tracer;

use serde_json::Value;
use std::path::Path;
use std::time::Instant;
use wavrad::import::{import, Format, Model};
use wavrad::progress::Silent;
use wavrad::scene::{parse_value, Limits};

fn main() {
    let mut samples = 1usize << 18;
    let mut solver: Vec<(String, Value)> = Vec::new();
    let mut only: Option<Vec<String>> = None;
    for a in std::env::args().skip(1) {
        if let Some(prefixes) = a.strip_prefix("only=") {
            only = Some(prefixes.split(',').map(String::from).collect());
        } else if let Some((k, v)) = a.split_once('=') {
            let v = serde_json::from_str(v).unwrap_or(Value::String(v.into()));
            solver.push((k.into(), v));
        } else {
            samples = a.parse().expect("SAMPLES_PER_OBJECT is a number");
        }
    }
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/models/room.obj");
    let bytes = std::fs::read(&path).expect("scenes/models/room.obj");
    let folder = path.parent().unwrap().to_path_buf();
    let files = move |name: &str| std::fs::read(folder.join(name)).ok();
    let model = Model {
        file: "room.obj",
        format: Format::Obj,
        bytes: &bytes,
    };
    let mut doc = import(model, &files, &Limits::default())
        .expect("the room imports")
        .document;
    for (k, v) in solver {
        doc["solver"][k] = v;
    }
    if let Some(prefixes) = only {
        let surfaces = doc["scene"]["surfaces"]
            .as_array_mut()
            .expect("the document's surfaces");
        surfaces.retain(|s| {
            let name = s["name"].as_str().unwrap_or_default();
            prefixes.iter().any(|p| name.starts_with(p.as_str()))
        });
        assert!(
            !surfaces.is_empty(),
            "no object's name starts with {prefixes:?}"
        );
    }
    let t = Instant::now();
    let reference = tracer::Tracer::new(&doc).surface_means(samples, 0x200e);
    let traced = t.elapsed().as_secs_f64();
    eprintln!("reference: {traced:.1} s");
    let job = parse_value(&doc, &Limits::default()).expect("a valid document");
    let t = Instant::now();
    let out = wavrad::job::run(&job, &Silent).expect("solves");
    let solved = t.elapsed().as_secs_f64();
    println!(
        "solver {} · solved in {solved:.1} s · reference {samples} paths per object in {traced:.1} s",
        doc["solver"]
    );
    println!("| object | solver | reference | gap % | gap / σ |");
    println!("|---|---|---|---|---|");
    let mut worst: f64 = 0.0;
    for (s, (mean, err)) in out.result.surfaces.iter().zip(&reference) {
        // the channel with the largest relative gap
        let (c, gap) = (0..3)
            .map(|c| (c, (s.mean[c] - mean[c]) / mean[c].abs().max(1e-12)))
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
            .unwrap();
        if err[c] == 0.0 {
            // an emitter that reflects nothing: B = E in both
            println!("| {} | {:.4} | {:.4} | — | — |", s.name, s.mean[c], mean[c]);
            continue;
        }
        worst = worst.max(gap.abs());
        println!(
            "| {} | {:.4} | {:.4} ± {:.4} | {:+.2} | {:+.1} |",
            s.name,
            s.mean[c],
            mean[c],
            err[c],
            100.0 * gap,
            (s.mean[c] - mean[c]) / err[c]
        );
    }
    println!("largest gap of an object's mean: {:.2} %", 100.0 * worst);
}
