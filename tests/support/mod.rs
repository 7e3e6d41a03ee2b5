//! Helpers shared by the numerical tests: documents, solves and error measures.
#![allow(dead_code)]

use serde_json::Value;
use wavrad::job::{self, Outcome};
use wavrad::progress::Silent;
use wavrad::scene::{parse_value, Job, Limits};

pub fn job(doc: Value) -> Job {
    parse_value(&doc, &Limits::default()).unwrap_or_else(|e| panic!("{e}"))
}

pub fn run(doc: Value) -> Outcome {
    job::run(&job(doc), &Silent).unwrap()
}

pub fn scene_file(name: &str) -> Value {
    let path = format!("{}/scenes/{name}.json", env!("CARGO_MANIFEST_DIR"));
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The closed unit cube seen from inside, every face emitting E and reflecting ρ: B = E/(1 − ρ)
/// everywhere.
pub fn furnace_cube(e: f64, rho: f64) -> Value {
    let faces = [
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]],
        [[0, 0, 1], [0, 1, 1], [1, 1, 1], [1, 0, 1]],
        [[0, 0, 0], [0, 1, 0], [0, 1, 1], [0, 0, 1]],
        [[1, 0, 0], [1, 0, 1], [1, 1, 1], [1, 1, 0]],
        [[0, 0, 0], [0, 0, 1], [1, 0, 1], [1, 0, 0]],
        [[0, 1, 0], [1, 1, 0], [1, 1, 1], [0, 1, 1]],
    ];
    let surfaces: Vec<Value> = faces
        .iter()
        .enumerate()
        .map(|(i, c)| {
            serde_json::json!({ "name": format!("f{i}"), "corners": c, "reflectance": rho, "emission": e })
        })
        .collect();
    serde_json::json!({ "scene": { "kind": "3d", "surfaces": surfaces } })
}

/// The document with its `solver` and `output` replaced.
pub fn with_solver(doc: &Value, solver: Value, output: Value) -> Value {
    let mut d = doc.clone();
    d["solver"] = solver;
    d["output"] = output;
    d
}

/// The cell means of every surface, one channel, in order.
pub fn cell_means(o: &Outcome, channel: usize) -> Vec<f64> {
    o.result
        .surfaces
        .iter()
        .flat_map(|s| s.cells.iter().map(move |c| c[channel]))
        .collect()
}

/// ‖a − b‖ / ‖b‖.
pub fn relative_l2(a: &[f64], b: &[f64]) -> f64 {
    let d: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
    (d / b.iter().map(|y| y * y).sum::<f64>()).sqrt()
}

/// Imports a model file as `wavrad import` does, reading the files it names from its folder.
pub fn import_file(
    path: &std::path::Path,
) -> Result<wavrad::import::Imported, wavrad::import::ImportError> {
    use wavrad::import::{import, Format, Model};
    let bytes = std::fs::read(path).unwrap();
    let folder = path.parent().unwrap().to_path_buf();
    let files = move |name: &str| std::fs::read(folder.join(name)).ok();
    let name = path.file_name().unwrap().to_string_lossy().to_string();
    let model = Model {
        file: &name,
        format: Format::from_file_name(&name).unwrap(),
        bytes: &bytes,
    };
    import(model, &files, &Limits::default())
}

/// The `name` of each surface of a document, in order.
pub fn surface_names(doc: &Value) -> Vec<&str> {
    doc["scene"]["surfaces"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["name"].as_str().unwrap())
        .collect()
}
