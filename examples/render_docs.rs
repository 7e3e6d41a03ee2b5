//! Regenerates the reference renders under `docs/`: `cargo run --release --example render_docs`.
//!
//! - `docs/<scene>.png` (256 × 256) and `docs/<scene>-mesh.png` (the elements) for each 3D
//!   scene of `scenes/`, solved with its own settings;
//! - `docs/plates/`: the slides' experiment, B over the top plate of `plates-3d` by the
//!   projection method at n = 4 and 16 with Haar (m = 0), linear (m = 1) and quadratic (m = 2)
//!   Legendre multiwavelets, keeping all, half or a quarter of the kernel coefficients.

use serde_json::json;
use wavrad::job;
use wavrad::progress::Silent;
use wavrad::render::camera::{self, Options};
use wavrad::scene::{parse_document, parse_value, Limits};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let root = env!("CARGO_MANIFEST_DIR");
    for name in ["cornell-box", "plates-3d"] {
        let text = std::fs::read_to_string(format!("{root}/scenes/{name}.json"))?;
        let j = parse_document(&text, &Limits::default())?;
        let t = std::time::Instant::now();
        let out = job::run(&j, &Silent)?;
        let solved = t.elapsed();
        let img = camera::render(&j, &out, 256, 256);
        img.save(format!("{root}/docs/{name}.png"))?;
        let mesh = camera::render_fields(
            &j,
            &out.fields,
            256,
            256,
            Options {
                raw: true,
                mesh: true,
            },
        );
        mesh.save(format!("{root}/docs/{name}-mesh.png"))?;
        let h = out.result.hierarchical.as_ref();
        println!(
            "{name}: solved in {:.0} ms{}",
            solved.as_secs_f64() * 1e3,
            h.map(|h| format!(
                ", {} elements, {} links, {} rays",
                h.elements, h.links, h.rays
            ))
            .unwrap_or_default()
        );
    }
    let text = std::fs::read_to_string(format!("{root}/scenes/plates-3d.json"))?;
    let base: serde_json::Value = serde_json::from_str(&text)?;
    std::fs::create_dir_all(format!("{root}/docs/plates"))?;
    // one exposure for the whole gallery: the brightest point of the finest solution
    let mut white = None;
    for n in [16, 4] {
        for (m, basis) in [(0, "haar"), (1, "llmw"), (2, "qlmw")] {
            for (f, tag) in [(1.0, "all"), (0.5, "half"), (0.25, "quarter")] {
                let mut doc = base.clone();
                doc["solver"] = json!({ "method": "projection", "basis": "wavelet", "order": m, "resolution": n, "keep": { "fraction": f } });
                let j = parse_value(&doc, &Limits::default())?;
                let out = job::run(&j, &Silent)?;
                let top = &out.fields[1];
                let w = *white.get_or_insert_with(|| top.eval(0.5, 0.5)[0] / std::f64::consts::PI);
                camera::surface_image(top, 128, 128, w)
                    .save(format!("{root}/docs/plates/top-n{n}-{basis}-{tag}.png"))?;
                println!(
                    "plates n={n} {basis} keep {tag}: top mean {:.5}, eq. (5) {:.2e}",
                    out.result.surfaces[1].mean[0],
                    out.result.metrics.kernel_relative_error.unwrap_or(f64::NAN)
                );
            }
        }
    }
    Ok(())
}
