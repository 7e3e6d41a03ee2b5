//! Regenerates the reference renders under `docs/`: `cargo run --release --example render_docs`.
//!
//! Each scene of `scenes/` with kind `3d` is solved with its own settings and rendered at
//! 256 × 256; `docs/<scene>.png` is written, with `docs/<scene>-mesh.png` showing the elements.

use wavrad::job;
use wavrad::progress::Silent;
use wavrad::render::camera::{self, Options};
use wavrad::scene::{parse_document, Limits};

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
        let mesh = camera::render_fields(&j, &out.fields, 256, 256, Options { raw: true, mesh: true });
        mesh.save(format!("{root}/docs/{name}-mesh.png"))?;
        let h = out.result.hierarchical.as_ref();
        println!(
            "{name}: solved in {:.0} ms{}",
            solved.as_secs_f64() * 1e3,
            h.map(|h| format!(", {} elements, {} links, {} rays", h.elements, h.links, h.rays))
                .unwrap_or_default()
        );
    }
    Ok(())
}
