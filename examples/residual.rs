//! The one-bounce residual of a solved scene, near a point: for each cell of a surface there,
//! the solver's mean B against E + ρ ∫ K B, with the solver's own B under the integral (its
//! fields, as `job::Outcome` holds them) and K traced with exact visibility by the independent
//! tracer of `tests/tracer`. The exact solution has a ratio of 1 everywhere, so a cell whose
//! ratio is far from it is one into which the links deliver more (or less) light than the
//! solver's own B sends: an error of the transfer there, told apart from errors it only
//! inherits from its sources (a path-traced reference, `tests/gallery.rs`, sees both). The
//! light gathered is split by the surface it comes from (the emitters' E by light points, as
//! the tracer samples it, apart). Points inside a solid resting on the surface (a covered
//! part) are left out.
//!
//! ```text
//! cargo run --release --example residual -- SCENE SURFACE X,Y,Z RADIUS [grid=N] [key=value ...]
//! ```
//!
//! SCENE is a file under `scenes/` without `.json` (`gallery/meshes-on-a-floor`); the cells
//! are those of SURFACE whose centres lie within RADIUS of (X, Y, Z): the document's grid on a
//! parallelogram (`grid=N` sets it), each triangle of a mesh. Each other `key=value` sets a
//! field of the document's `solver` (`epsilon=2.5e-4`). Each cell takes 20 000 points, each
//! with a light point per emitter and one cosine-distributed direction
//! ([`tracer::Tracer::one_bounce`]; the green channel).

#[path = "../tests/tracer/mod.rs"]
mod tracer;

use rand::{Rng, SeedableRng};
use serde_json::Value;
use std::collections::BTreeMap;
use tracer::{dot, sub, Tracer};
use wavrad::progress::Silent;
use wavrad::scene::{parse_value, Limits};

/// Points (one direction each) per cell.
const POINTS: usize = 20_000;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "residual SCENE SURFACE X,Y,Z RADIUS [grid=N] [key=value ...]";
    assert!(args.len() >= 4, "{usage}");
    let path = format!("{}/scenes/{}.json", env!("CARGO_MANIFEST_DIR"), args[0]);
    let mut doc: Value =
        serde_json::from_str(&std::fs::read_to_string(&path).expect(&path)).expect("JSON");
    let name = &args[1];
    let at: Vec<f64> = args[2]
        .split(',')
        .map(|x| x.parse().expect(usage))
        .collect();
    let at = [at[0], at[1], at[2]];
    let radius: f64 = args[3].parse().expect(usage);
    for kv in &args[4..] {
        let (k, v) = kv.split_once('=').expect(usage);
        let v: Value = serde_json::from_str(v).unwrap_or(Value::String(v.into()));
        if k == "grid" {
            doc["output"]["grid"] = v;
        } else {
            doc["solver"][k] = v;
        }
    }
    let tracer = Tracer::new(&doc);
    let job = parse_value(&doc, &Limits::default()).expect("a valid document");
    let out = wavrad::job::run(&job, &Silent).expect("solves");
    let fields = &out.fields;
    assert_eq!(fields.len(), tracer.quads.len(), "one field a patch");
    let names: Vec<&str> = out
        .result
        .surfaces
        .iter()
        .map(|s| s.name.as_str())
        .collect();
    let surface = names
        .iter()
        .position(|n| n == name)
        .unwrap_or_else(|| panic!("no surface {name}: {names:?}"));
    let grid = doc["output"]["grid"].as_u64().unwrap_or(8) as usize;
    println!("| cell | centre | B | E + ρ ∫ K B | ratio | gathered by source |");
    println!("|---|---|---|---|---|---|");
    for &p in &tracer.surfaces()[surface] {
        let q = &tracer.quads[p];
        let g = if q.tri { 1 } else { grid };
        for cell in 0..g * g {
            let (ci, cj) = (cell % g, cell / g);
            let centre = if q.tri {
                q.at(1.0 / 3.0, 1.0 / 3.0)
            } else {
                q.at((ci as f64 + 0.5) / g as f64, (cj as f64 + 0.5) / g as f64)
            };
            let d = sub(centre, at);
            if dot(d, d).sqrt() > radius {
                continue;
            }
            let mut rng = rand::rngs::SmallRng::seed_from_u64(((p as u64) << 32) ^ cell as u64);
            let (mut b, mut gathered, mut points) = (0.0, 0.0, 0);
            // by document surface; `None`: the emitters' light points
            let mut by: BTreeMap<Option<usize>, f64> = BTreeMap::new();
            let light = |patch: usize, s: f64, t: f64| fields[patch].eval(s, t);
            for _ in 0..POINTS {
                let (mut s, mut t) = (
                    (ci as f64 + rng.random::<f64>()) / g as f64,
                    (cj as f64 + rng.random::<f64>()) / g as f64,
                );
                if q.tri && s + t > 1.0 {
                    (s, t) = (1.0 - s, 1.0 - t);
                }
                // a covered point (inside a solid resting on the surface) takes no part
                let Some((direct, sample)) = tracer.one_bounce(q.at(s, t), p, &mut rng, &light)
                else {
                    continue;
                };
                points += 1;
                b += fields[p].eval(s, t)[1];
                gathered += direct[1];
                *by.entry(None).or_default() += direct[1];
                if let Some((hit, v)) = sample {
                    gathered += v[1];
                    *by.entry(Some(tracer.quads[hit].owner)).or_default() += v[1];
                }
            }
            if points == 0 {
                continue;
            }
            let n = points as f64;
            let (b, rhs) = (b / n, q.emission[1] + q.rho[1] * gathered / n);
            let sources: Vec<String> = by
                .iter()
                .map(|(&o, &v)| (o, q.rho[1] * v / n))
                .filter(|&(_, v)| v > 1e-3 * rhs)
                .map(|(o, v)| match o {
                    Some(o) => format!("{} {v:.4}", names[o]),
                    None => format!("light points {v:.4}"),
                })
                .collect();
            let label = if q.tri {
                format!("triangle {p}")
            } else {
                format!("({ci}, {cj})")
            };
            println!(
                "| {label} | {:.2}, {:.2}, {:.2} | {b:.4} | {rhs:.4} | {:.2} | {} |",
                centre[0],
                centre[1],
                centre[2],
                b / rhs,
                sources.join(", ")
            );
        }
    }
}
