//! Helpers shared by the numerical tests: documents, solves and error measures.
#![allow(dead_code)]

use serde_json::{json, Value};
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

/// The walls of a 5 × 4 × 2.7 room (x × z × y), each a parallelogram's corners facing in:
/// floor, ceiling, south (z = 0), north, east (x = 5) and west (x = 0).
pub fn room_walls() -> [(&'static str, [[f64; 3]; 4]); 6] {
    let (w, d, h) = (5.0, 4.0, 2.7);
    [
        (
            "floor",
            [[0.0, 0.0, 0.0], [0.0, 0.0, d], [w, 0.0, d], [w, 0.0, 0.0]],
        ),
        (
            "ceiling",
            [[0.0, h, 0.0], [w, h, 0.0], [w, h, d], [0.0, h, d]],
        ),
        (
            "south",
            [[0.0, 0.0, 0.0], [w, 0.0, 0.0], [w, h, 0.0], [0.0, h, 0.0]],
        ),
        (
            "north",
            [[0.0, 0.0, d], [0.0, h, d], [w, h, d], [w, 0.0, d]],
        ),
        ("east", [[w, 0.0, 0.0], [w, 0.0, d], [w, h, d], [w, h, 0.0]]),
        (
            "west",
            [[0.0, 0.0, 0.0], [0.0, h, 0.0], [0.0, h, d], [0.0, 0.0, d]],
        ),
    ]
}

/// The walls of [`room_walls`], each a mesh of `w × h` cells of triangles of reflectance `rho`.
pub fn meshed_walls(w: usize, h: usize, rho: f64) -> Vec<Value> {
    room_walls()
        .iter()
        .map(|(name, c)| serde_json::json!({"name": name, "mesh": grid_mesh(*c, w, h), "reflectance": rho}))
        .collect()
}

/// The window of [`room_walls`] in its west wall, as `scenes/models/room.obj` has it: y from
/// y0 to y1, z from z0 to z1.
pub const WINDOW: (f64, f64, f64, f64) = (0.81, 2.295, 1.2, 2.8);

/// A `w × h` grid of a parallelogram's corners as one mesh of triangles, facing as the
/// parallelogram does.
pub fn grid_mesh(c: [[f64; 3]; 4], w: usize, h: usize) -> Value {
    let at = |i: usize, j: usize| {
        let (s, t) = (i as f64 / w as f64, j as f64 / h as f64);
        [0, 1, 2].map(|k| c[0][k] + s * (c[1][k] - c[0][k]) + t * (c[3][k] - c[0][k]))
    };
    let positions: Vec<[f64; 3]> = (0..=h)
        .flat_map(|j| (0..=w).map(move |i| (i, j)))
        .map(|(i, j)| at(i, j))
        .collect();
    let mut triangles = Vec::new();
    for j in 0..h {
        for i in 0..w {
            let a = j * (w + 1) + i;
            let (b, c, d) = (a + 1, a + w + 2, a + w + 1);
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    serde_json::json!({"positions": positions, "triangles": triangles})
}

/// Thirty books standing 3 mm apart on the floor of [`room_walls`], 2 cm from its east wall
/// (x = 5) from z = 1.2, as one mesh: boxes 0.23 m deep, 2–5 cm wide and 0.2–0.36 m tall,
/// without bottoms (the floor closes them), every face counter-clockwise from outside.
pub fn row_of_books() -> Value {
    // (width, height)
    const BOOKS: [(f64, f64); 30] = [
        (0.0271, 0.287),
        (0.0311, 0.297),
        (0.0388, 0.21),
        (0.0204, 0.334),
        (0.0278, 0.237),
        (0.0499, 0.275),
        (0.0451, 0.276),
        (0.0392, 0.224),
        (0.039, 0.339),
        (0.0357, 0.319),
        (0.0401, 0.21),
        (0.0427, 0.295),
        (0.029, 0.205),
        (0.046, 0.276),
        (0.0416, 0.341),
        (0.0414, 0.347),
        (0.0318, 0.328),
        (0.0333, 0.35),
        (0.0464, 0.216),
        (0.0241, 0.235),
        (0.049, 0.27),
        (0.0388, 0.248),
        (0.0352, 0.262),
        (0.0305, 0.294),
        (0.0375, 0.345),
        (0.0405, 0.349),
        (0.0457, 0.359),
        (0.0401, 0.226),
        (0.0458, 0.354),
        (0.0471, 0.291),
    ];
    let (mut positions, mut triangles): (Vec<[f64; 3]>, Vec<[usize; 3]>) = (vec![], vec![]);
    let mut z = 1.2;
    for (w, h) in BOOKS {
        let (x0, x1, z0, z1) = (4.75, 4.98, z, z + w);
        let at = |x: f64, y: f64, z: f64| [x, y, z];
        // top, the two sides across z, the front and the back, counter-clockwise from outside
        for face in [
            [at(x0, h, z0), at(x0, h, z1), at(x1, h, z1), at(x1, h, z0)],
            [
                at(x0, 0.0, z0),
                at(x0, h, z0),
                at(x1, h, z0),
                at(x1, 0.0, z0),
            ],
            [
                at(x0, 0.0, z1),
                at(x1, 0.0, z1),
                at(x1, h, z1),
                at(x0, h, z1),
            ],
            [
                at(x0, 0.0, z0),
                at(x0, 0.0, z1),
                at(x0, h, z1),
                at(x0, h, z0),
            ],
            [
                at(x1, 0.0, z0),
                at(x1, h, z0),
                at(x1, h, z1),
                at(x1, 0.0, z1),
            ],
        ] {
            let base = positions.len();
            positions.extend(face);
            triangles.push([base, base + 1, base + 2]);
            triangles.push([base, base + 2, base + 3]);
        }
        z += w + 0.003;
    }
    serde_json::json!({"positions": positions, "triangles": triangles})
}

/// A 4 × 3 × 4 room with a flush light in the middle of its ceiling (an emission region), one
/// coloured wall and one tinted one, nothing inside, solved with `solver` on an 8 × 8 grid.
pub fn room_lit_through_its_ceiling(solver: Value) -> Value {
    let wall = |name: &str, corners: Value, rho: Value| json!({ "name": name, "corners": corners, "reflectance": rho });
    json!({
        "scene": { "kind": "3d", "surfaces": [
            wall("floor", json!([[0, 0, 0], [0, 0, 4], [4, 0, 4], [4, 0, 0]]), json!(0.6)),
            { "name": "ceiling", "corners": [[0, 3, 0], [4, 3, 0], [4, 3, 4], [0, 3, 4]],
              "reflectance": 0.8, "emission": 20.0,
              "emission_region": { "s": [0.4, 0.6], "t": [0.4, 0.6] } },
            wall("back", json!([[0, 0, 4], [0, 3, 4], [4, 3, 4], [4, 0, 4]]), json!([0.7, 0.6, 0.3])),
            wall("front", json!([[0, 0, 0], [4, 0, 0], [4, 3, 0], [0, 3, 0]]), json!(0.5)),
            wall("left", json!([[4, 0, 0], [4, 0, 4], [4, 3, 4], [4, 3, 0]]), json!([0.2, 0.3, 0.7])),
            wall("right", json!([[0, 0, 0], [0, 3, 0], [0, 3, 4], [0, 0, 4]]), json!(0.7)),
        ]},
        "solver": solver,
        "output": { "grid": 8 }
    })
}
