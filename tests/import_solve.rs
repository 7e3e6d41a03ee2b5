//! The round trip that matters: the Cornell box imported from the files an independent writer
//! made (`tests/fixtures/import/`: OBJ + MTL and GLB, by trimesh) solves to the solution of
//! the hand-written `scenes/cornell-box.json`, every surface's mean within 0.3 %. A block is one
//! object (one `mesh` surface) in the fixtures and five parallelograms in the document: its
//! mean is compared with the area-weighted mean of the five.
//!
//! The imported model is solved at the document's settings (ε = 1e-3); the parallelograms'
//! solution it must match is the hand-written document's at ε = 6.25e-5, where the two
//! agree within 0.04 % on every surface: that is the solution both converge to. Against the
//! hand-written document at ε = 1e-3 instead, the test would ask the meshes to repeat the
//! parallelograms' own error there (their ceiling is 0.39 % below their limit) rather than
//! to be right: a mesh solution whose ceiling was 0.08 % from the limit failed it by 0.31 %,
//! and one 0.42 % from the limit passed by 0.04 %.

mod common;

use serde_json::Value;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::OnceLock;
use wavrad::import::{import, Format, Model};
use wavrad::progress::Silent;
use wavrad::scene::{parse_value, Limits};

fn area(corners: &Value) -> f64 {
    let c: Vec<[f64; 3]> = corners
        .as_array()
        .unwrap()
        .iter()
        .map(|p| [0, 1, 2].map(|i| p[i].as_f64().unwrap()))
        .collect();
    let (u, v) = (
        [0, 1, 2].map(|i| c[1][i] - c[0][i]),
        [0, 1, 2].map(|i| c[3][i] - c[0][i]),
    );
    let n = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt()
}

fn object_of(name: &str) -> String {
    for block in ["tall", "short"] {
        if name.starts_with(&format!("{block}-")) {
            return format!("{block}-block");
        }
    }
    name.to_string()
}

/// The means of a solved document by surface name.
fn solve(doc: &Value) -> BTreeMap<String, [f64; 3]> {
    let job = parse_value(doc, &Limits::default()).expect("a valid document");
    let outcome = wavrad::job::run(&job, &Silent).expect("solves");
    outcome
        .result
        .surfaces
        .iter()
        .map(|s| (s.name.clone(), s.mean))
        .collect()
}

/// The ε of the parallelograms' solution that the imported model is held to.
const REFERENCE_EPSILON: f64 = 6.25e-5;

/// The hand-written document's surface means at [`REFERENCE_EPSILON`], solved once for both
/// tests.
fn reference() -> &'static BTreeMap<String, [f64; 3]> {
    static REFERENCE: OnceLock<BTreeMap<String, [f64; 3]>> = OnceLock::new();
    REFERENCE.get_or_init(|| {
        let mut hand = common::scene("cornell-box");
        hand["solver"]["epsilon"] = REFERENCE_EPSILON.into();
        solve(&hand)
    })
}

fn check(file: &str) {
    let hand = common::scene("cornell-box");
    let want_by_surface = reference();
    // the hand-written means by object, area-weighted
    let mut want: BTreeMap<String, ([f64; 3], f64)> = BTreeMap::new();
    for s in hand["scene"]["surfaces"].as_array().unwrap() {
        let name = s["name"].as_str().unwrap();
        let a = area(&s["corners"]);
        let e = want.entry(object_of(name)).or_insert(([0.0; 3], 0.0));
        for (sum, b) in e.0.iter_mut().zip(want_by_surface[name]) {
            *sum += a * b;
        }
        e.1 += a;
    }
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/import")
        .join(file);
    let bytes = std::fs::read(&path).unwrap();
    let folder = path.parent().unwrap().to_path_buf();
    let files = move |name: &str| std::fs::read(folder.join(name)).ok();
    let model = Model {
        file,
        format: Format::from_file_name(file).unwrap(),
        bytes: &bytes,
    };
    let mut doc = import(model, &files, &Limits::default()).unwrap().document;
    // the same solver (at the document's ε) and output as the hand-written document
    doc["solver"] = hand["solver"].clone();
    doc["output"] = hand["output"].clone();
    let got = solve(&doc);
    assert_eq!(got.len(), want.len());
    let mut worst = 0.0f64;
    for (object, (sum, a)) in &want {
        let w = sum.map(|x| x / a);
        let g = got[object];
        for c in 0..3 {
            let error = (g[c] - w[c]).abs() / w[c].abs().max(1e-12);
            worst = worst.max(error);
            assert!(
                error <= 3e-3,
                "{file}: {object} channel {c}: {} against {} ({:.3} %)",
                g[c],
                w[c],
                100.0 * error
            );
        }
    }
    eprintln!(
        "{file}: the largest gap of an object's mean {:.3} %",
        100.0 * worst
    );
}

#[test]
fn the_imported_obj_cornell_box_solves_as_the_hand_written_one() {
    check("cornell-box.obj");
}

#[test]
fn the_imported_glb_cornell_box_solves_as_the_hand_written_one() {
    check("cornell-box.glb");
}
