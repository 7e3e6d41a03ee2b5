//! ε-convergence of the hierarchical method on the gallery (`scenes/gallery/`, and the Cornell
//! box), against the independent path tracer of `tests/tracer` (the same reference and the
//! same measure as `tests/gallery.rs`): for each scene and each ε, the worst surface mean and
//! the worst cell (grid 4) off the reference beyond four of its standard errors, the worst
//! surface mean as it is, the links and the solve's wall time. The table of
//! `benches/README.md` is its output:
//!
//! ```text
//! cargo run --release --example epsilon_table -- [--min-epsilon E] [--size-with-epsilon] [SCENE...]
//! ```
//!
//! With `--size-with-epsilon`, `min_element_size` shrinks with ε: the scene's default size at
//! ε = 1e-3, times ε / 1e-3 (halved with each halving of ε), the convergence of the refinement
//! issue's requirement; without it, the default size at every ε.
//!
//! SCENE is a file name under `scenes/` without `.json` (`gallery/room-3x3`); the default is the
//! Cornell box and every gallery scene. ε runs over 4e-3, 2e-3, … 1.25e-4, down to
//! `--min-epsilon`; a scene whose solve fails (the link budget) ends its rows there.

#[path = "../tests/tracer/mod.rs"]
mod tracer;

use serde_json::{json, Value};
use std::time::Instant;
use wavrad::progress::Silent;
use wavrad::scene::{parse_value, Limits};

/// Paths per cell of the reference, as `tests/gallery.rs` takes it at the defaults.
const PER_SIDE: usize = 128;

fn main() {
    let mut args = std::env::args().skip(1).peekable();
    let mut min_epsilon = 1.25e-4;
    let mut size_with_epsilon = false;
    let mut names = Vec::new();
    while let Some(a) = args.next() {
        if a == "--size-with-epsilon" {
            size_with_epsilon = true;
        } else if a == "--min-epsilon" {
            min_epsilon = args
                .next()
                .and_then(|v| v.parse().ok())
                .expect("--min-epsilon takes a number");
        } else {
            names.push(a);
        }
    }
    if names.is_empty() {
        names.push("cornell-box".to_string());
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/gallery");
        let mut gallery: Vec<String> = std::fs::read_dir(dir)
            .expect("scenes/gallery")
            .filter_map(|e| {
                let name = e.ok()?.file_name().to_string_lossy().to_string();
                Some(format!("gallery/{}", name.strip_suffix(".json")?))
            })
            .collect();
        gallery.sort();
        names.extend(gallery);
    }
    println!(
        "| scene | ε | worst surface mean beyond 4σ (raw) | worst cell beyond 4σ | links | solve |"
    );
    println!("|---|---|---|---|---|---|");
    for name in names {
        let path = format!("{}/scenes/{name}.json", env!("CARGO_MANIFEST_DIR"));
        let doc: Value = serde_json::from_str(&std::fs::read_to_string(&path).expect(&path))
            .expect("a JSON document");
        let doc = with_grid_4(doc);
        let t = Instant::now();
        let reference = tracer::reference(&doc, PER_SIDE);
        eprintln!("{name}: reference in {:.0} s", t.elapsed().as_secs_f64());
        let tracer = tracer::Tracer::new(&doc);
        let default_size = size_with_epsilon.then(|| default_size(&doc));
        let mut epsilon = 4e-3;
        while epsilon >= min_epsilon * 0.99 {
            let mut d = doc.clone();
            d["solver"]["method"] = json!("hierarchical");
            d["solver"]["epsilon"] = json!(epsilon);
            if let Some(size) = default_size {
                d["solver"]["min_element_size"] = json!(size * epsilon / 1e-3);
            }
            let job = parse_value(&d, &Limits::default()).expect("a valid document");
            let t = Instant::now();
            let out = match wavrad::job::run(&job, &Silent) {
                Ok(out) => out,
                Err(e) => {
                    println!("| {name} | {epsilon:.3e} | {e} | | | |");
                    break;
                }
            };
            let seconds = t.elapsed().as_secs_f64();
            let g = tracer.gaps(&out.result.surfaces, &reference, 4.0);
            let raw = tracer.gaps(&out.result.surfaces, &reference, 0.0);
            println!(
                "| {name} | {epsilon:.3e} | {:.2} % {} ({:.2} %) | {:.2} % {} | {} | {seconds:.1} s |",
                100.0 * g.surface.0,
                g.surface.1,
                100.0 * raw.surface.0,
                100.0 * g.cell.0,
                g.cell.1,
                out.result.hierarchical.as_ref().map_or(0, |h| h.links),
            );
            epsilon /= 2.0;
        }
    }
}

/// The `min_element_size` the solver chooses for the document: the one its result reports,
/// from a solve at ε = 4e-3 (the default size does not depend on ε).
fn default_size(doc: &Value) -> f64 {
    let mut d = doc.clone();
    d["solver"]["method"] = json!("hierarchical");
    d["solver"]["epsilon"] = json!(4e-3);
    let job = parse_value(&d, &Limits::default()).expect("a valid document");
    let out = wavrad::job::run(&job, &Silent).expect("solves");
    let result = serde_json::to_value(&out.result).expect("the result as JSON");
    result["hierarchical"]["min_element_size"]
        .as_f64()
        .expect("the hierarchy's min_element_size")
}

/// The document with the 4 × 4 grid of the gallery's cell bound.
fn with_grid_4(mut doc: Value) -> Value {
    if !doc["output"].is_object() {
        doc["output"] = json!({});
    }
    doc["output"]["grid"] = json!(4);
    doc
}
