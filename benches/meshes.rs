//! How the hierarchical solve grows with the triangles: a closed room (six parallelograms and a
//! light in the ceiling) with floating icospheres, at the document defaults (order 1,
//! ε = 1e-3), from about 10² to 10⁵ triangles. Each scene is solved by a `wavrad render`
//! process of its own, so that its peak resident memory is its own; the table of
//! `benches/README.md` ("Meshes: links against triangles") is what this prints.
//!
//! `cargo bench --bench meshes` runs 10², 10³ and 10⁴; `WAVRAD_BENCH_MESH_SIZES=4,5` (10^k) picks
//! others (`6`: 10⁶ triangles as 200 spheres of level 4), `WAVRAD_BENCH_MESH_TIMEOUT` (seconds,
//! 900 by default) bounds each solve.

use serde_json::{json, Value};
use std::process::Command;
use std::time::{Duration, Instant};

#[path = "../tests/icosphere/mod.rs"]
mod icosphere;

/// The icosphere of `level` subdivisions (20 · 4^level triangles), radius `r` about `c`,
/// facing out.
fn icosphere(level: u32, c: [f64; 3], r: f64) -> Value {
    let mut mesh = icosphere::sphere(level as usize);
    for p in mesh["positions"].as_array_mut().expect("positions") {
        for (k, x) in p.as_array_mut().expect("a point").iter_mut().enumerate() {
            *x = json!(c[k] + r * x.as_f64().expect("a coordinate"));
        }
    }
    mesh
}

/// A 10 m room with `spheres` icospheres of `level` on a grid at mid-height.
fn scene(spheres: usize, level: u32) -> Value {
    let quad = |name: &str, c: [[f64; 3]; 4], rho: f64| json!({"name": name, "corners": c, "reflectance": rho});
    let s = 10.0;
    let mut surfaces = vec![
        quad(
            "floor",
            [[0.0, 0.0, 0.0], [0.0, 0.0, s], [s, 0.0, s], [s, 0.0, 0.0]],
            0.6,
        ),
        quad(
            "ceiling",
            [[0.0, s, 0.0], [s, s, 0.0], [s, s, s], [0.0, s, s]],
            0.7,
        ),
        quad(
            "back",
            [[0.0, 0.0, s], [0.0, s, s], [s, s, s], [s, 0.0, s]],
            0.6,
        ),
        quad(
            "front",
            [[0.0, 0.0, 0.0], [s, 0.0, 0.0], [s, s, 0.0], [0.0, s, 0.0]],
            0.6,
        ),
        quad(
            "left",
            [[0.0, 0.0, 0.0], [0.0, s, 0.0], [0.0, s, s], [0.0, 0.0, s]],
            0.5,
        ),
        quad(
            "right",
            [[s, 0.0, 0.0], [s, 0.0, s], [s, s, s], [s, s, 0.0]],
            0.5,
        ),
        json!({"name": "light",
               "corners": [[4.0, s - 0.01, 4.0], [6.0, s - 0.01, 4.0], [6.0, s - 0.01, 6.0], [4.0, s - 0.01, 6.0]],
               "reflectance": 0.0, "emission": 20.0}),
    ];
    let side = (spheres as f64).sqrt().ceil() as usize;
    let step = s / side as f64;
    for k in 0..spheres {
        let (i, j) = (k % side, k / side);
        let c = [step * (i as f64 + 0.5), 4.0, step * (j as f64 + 0.5)];
        surfaces.push(json!({
            "name": format!("ball-{k}"),
            "mesh": icosphere(level, c, 0.3 * step),
            "reflectance": [0.7, 0.5, 0.3],
        }));
    }
    json!({
        "scene": {"kind": "3d", "name": format!("{spheres} icospheres of level {level} in a room"), "surfaces": surfaces},
        "solver": {"method": "hierarchical"},
        "output": {"grid": 4},
    })
}

/// Peak resident memory of a finished child, from `wait4`'s rusage (kilobytes).
fn run(doc: &Value, timeout: Duration) -> Option<(f64, u64, Value)> {
    let dir = std::env::temp_dir().join(format!("wavrad-mesh-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).ok()?;
    let path = dir.join("scene.json");
    std::fs::write(&path, doc.to_string()).ok()?;
    let out = dir.join("out");
    let t = Instant::now();
    let status = Command::new("timeout")
        .arg(timeout.as_secs().to_string())
        .arg("/usr/bin/time")
        .arg("-f")
        .arg("%M")
        .arg("-o")
        .arg(dir.join("rss"))
        .arg(env!("CARGO_BIN_EXE_wavrad"))
        .arg("render")
        .arg("--out")
        .arg(&out)
        .arg(&path)
        .status()
        .ok()?;
    let seconds = t.elapsed().as_secs_f64();
    if !status.success() {
        return None;
    }
    let rss: u64 = std::fs::read_to_string(dir.join("rss"))
        .ok()?
        .trim()
        .parse()
        .ok()?;
    let result: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("result.json")).ok()?).ok()?;
    Some((seconds, rss, result))
}

fn main() {
    let sizes: Vec<u32> = std::env::var("WAVRAD_BENCH_MESH_SIZES")
        .ok()
        .map(|s| s.split(',').filter_map(|x| x.trim().parse().ok()).collect())
        .unwrap_or_else(|| vec![2, 3, 4]);
    let timeout = Duration::from_secs(
        std::env::var("WAVRAD_BENCH_MESH_TIMEOUT")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(900),
    );
    println!("| triangles | spheres × level | time | peak memory | elements | links | rays |");
    println!("|---|---|---|---|---|---|---|");
    for k in sizes {
        // 20 · 4^level triangles a sphere
        let (spheres, level) = match k {
            2 => (1, 1),
            3 => (1, 3),
            4 => (8, 3),
            5 => (81, 3),
            // a document holds at most 256 surfaces (`Limits::max_surfaces`): 10⁶ as 200
            // spheres of 5 120
            _ => (200, 4),
        };
        let triangles = spheres * 20 * 4usize.pow(level);
        match run(&scene(spheres, level), timeout) {
            Some((seconds, rss, result)) => {
                let h = &result["hierarchical"];
                println!(
                    "| {triangles} | {spheres} × {level} | {seconds:.1} s | {:.0} MB | {} | {} | {} |",
                    rss as f64 / 1024.0,
                    h["elements"],
                    h["links"],
                    h["rays"]
                );
            }
            None => println!(
                "| {triangles} | {spheres} × {level} | did not finish in {} s | | | | |",
                timeout.as_secs()
            ),
        }
    }
}
