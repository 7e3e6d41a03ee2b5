//! Projection against hierarchical on the parallel plates as the resolution grows: time,
//! stored kernel coefficients (memory) and eq. (6) against one finer reference solution.
//! `cargo run --release --example growth_table` prints the table of `benches/README.md`.

use serde_json::json;
use wavrad::job;
use wavrad::metrics;
use wavrad::progress::Silent;
use wavrad::scene::{parse_value, Keep, Limits};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let text = std::fs::read_to_string(format!(
        "{}/scenes/plates-3d.json",
        env!("CARGO_MANIFEST_DIR")
    ))?;
    let base: serde_json::Value = serde_json::from_str(&text)?;
    let with =
        |solver: serde_json::Value| -> Result<wavrad::scene::Job, Box<dyn std::error::Error>> {
            let mut doc = base.clone();
            doc["solver"] = solver;
            Ok(parse_value(&doc, &Limits::default())?)
        };
    let reference = job::solve_job(
        &with(json!({ "order": 1, "resolution": 32 }))?,
        1,
        Some(32),
        Keep::All,
        &job::Rules::DEFAULT,
        &Silent,
    )?;
    let measure = job::surface_measures(&with(json!({}))?);
    println!("| method | setting | time (ms) | leaves or cells | stored coefficients | memory (MB) | eq. (6) |");
    println!("|---|---|---|---|---|---|---|");
    let rows = [
        (
            "projection",
            json!({ "order": 0, "resolution": 8 }),
            "n = 8",
        ),
        (
            "projection",
            json!({ "order": 0, "resolution": 16 }),
            "n = 16",
        ),
        (
            "projection",
            json!({ "order": 0, "resolution": 32 }),
            "n = 32",
        ),
        (
            "hierarchical",
            json!({ "method": "hierarchical", "order": 0, "resolution": 64, "epsilon": 4e-3 }),
            "m = 0, ε = 4e-3",
        ),
        (
            "hierarchical",
            json!({ "method": "hierarchical", "order": 0, "resolution": 64, "epsilon": 1e-3 }),
            "m = 0, ε = 1e-3",
        ),
        (
            "hierarchical",
            json!({ "method": "hierarchical", "order": 0, "resolution": 64, "epsilon": 2.5e-4 }),
            "m = 0, ε = 2.5e-4",
        ),
        (
            "hierarchical",
            json!({ "method": "hierarchical", "order": 1, "resolution": 64, "epsilon": 1e-3 }),
            "m = 1, ε = 1e-3",
        ),
    ];
    for (method, solver, setting) in rows {
        let j = with(solver)?;
        let t = std::time::Instant::now();
        let sol = job::solve_job(
            &j,
            j.solver.order,
            Some(j.solver.resolution),
            Keep::All,
            &job::Rules::DEFAULT,
            &Silent,
        )?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let (mut d, mut n) = (0.0, 0.0);
        for (i, f) in sol.fields.iter().enumerate() {
            let (di, ni) = metrics::l2_difference(f, &reference.fields[i], measure[i]);
            d += di;
            n += ni;
        }
        let leaves: usize = sol.fields.iter().map(|f| f.leaves.len()).sum();
        // what each method stores: the dense matrix, or the links' coefficients
        let stored = if method == "projection" {
            sol.matrix_entries
        } else {
            sol.kept_entries
        };
        println!(
            "| {method} | {setting} | {ms:.0} | {leaves} | {stored} | {:.2} | {:.2e} |",
            stored as f64 * 8.0 / 1e6,
            d / n
        );
    }
    Ok(())
}
