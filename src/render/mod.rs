//! The images of a finished job (`docs/job-document.md`, "What a finished job yields"), as PNG bytes:
//! `image.png`, `sparsity.png`, `coefficients.png` and one `surfaces/<name>.png` per surface.
//!
//! Everything here is pure — a job and its outcome in, encoded bytes out, no file I/O — and
//! deterministic: the same document gives byte-identical PNGs (no timings, no randomness, a
//! font embedded in the binary).
//!
//! 3D scenes are drawn from the camera by [`camera`], and written as `scene.glb`, lit, by
//! [`glb`].

pub mod camera;
pub mod glb;
pub mod plot;

use crate::job::Outcome;
use crate::math::field::Field;
use crate::scene::{Exposure, Job, SceneKind};
use image::{ImageEncoder, Rgb, RgbImage};
use rayon::prelude::*;

/// All images of a job, PNG-encoded.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Images {
    image: Vec<u8>,
    sparsity: Vec<u8>,
    coefficients: Vec<u8>,
    /// `(surface name, png)` in document order.
    surfaces: Vec<(String, Vec<u8>)>,
    /// 3d: `scene.glb`, the solved scene as binary glTF.
    pub glb: Option<Vec<u8>>,
}

impl Images {
    /// `(artifact path, bytes)`: `image.png`, `sparsity.png`, `coefficients.png`,
    /// `surfaces/<name>.png` and, for 3d, `scene.glb`.
    pub fn files(&self) -> Vec<(String, &[u8])> {
        let mut out = vec![
            ("image.png".to_string(), self.image.as_slice()),
            ("sparsity.png".to_string(), self.sparsity.as_slice()),
            ("coefficients.png".to_string(), self.coefficients.as_slice()),
        ];
        for (name, png) in &self.surfaces {
            out.push((format!("surfaces/{name}.png"), png.as_slice()));
        }
        if let Some(glb) = &self.glb {
            out.push(("scene.glb".to_string(), glb.as_slice()));
        }
        out
    }
}

/// Renders every image of a finished job.
pub fn render_all(job: &Job, outcome: &Outcome) -> Images {
    let spec = job.output.image;
    let names = job.surface_names();
    // Independent images, drawn in parallel; each is deterministic on its own.
    // the camera image, and for 3d the lit model with the same exposure and camera
    // the 3D scene's patches and BVH, shared by the camera image and the meshes' pictures
    let stage = camera::Stage::of(job);
    let main = || match &job.scene.kind {
        SceneKind::ThreeD(_) => {
            let opts = camera::Options {
                raw: spec.raw,
                mesh: spec.mesh,
            };
            let stage = stage.as_ref().expect("a 3D scene has a stage");
            let shot = stage.shoot(&outcome.fields, spec.width, spec.height, opts, None);
            let view = glb::View {
                camera: shot.camera,
                aspect: spec.width as f64 / spec.height as f64,
            };
            let (mut img, white) = (shot.image, shot.white);
            let (model, ()) = rayon::join(
                || glb::scene(job, &outcome.fields, white, Some(view)),
                // spec: the scene's name is shown in images (the charts have it as a title)
                || {
                    if let Some(name) = job.scene.name.as_deref().filter(|_| spec.width >= 160) {
                        plot::caption(&mut img, name);
                    }
                },
            );
            (encode_png(&img), Some(model))
        }
        _ => (
            encode_png(&plot::radiosity(
                job,
                &names,
                &outcome.fields,
                spec.width,
                spec.height,
            )),
            None,
        ),
    };
    let sparsity = || {
        encode_png(&match &outcome.picture {
            Some(p) => plot::sparsity(p, &names),
            None => plot::message(
                640,
                560,
                "No kernel matrix: this method builds links, not a matrix",
            ),
        })
    };
    let coefficients = || encode_png(&plot::coefficients(&outcome.result.coefficients));
    // one field per surface; a mesh has one per triangle, and its picture is the scene
    // seen by a camera that frames it
    let per_surface: Vec<Result<&Field, std::ops::Range<usize>>> = match &job.scene.kind {
        SceneKind::ThreeD(d) => d
            .surfaces
            .iter()
            .map(|s| match s.shape {
                crate::scene::Shape3::Mesh { .. } => Err(s.patches.clone()),
                _ => Ok(&outcome.fields[s.patches.start]),
            })
            .collect(),
        _ => outcome.fields.iter().map(Ok).collect(),
    };
    let surfaces = || -> Vec<Vec<u8>> {
        per_surface
            .par_iter()
            .zip(&names)
            .map(|(f, name)| {
                let f = match f {
                    Ok(f) => *f,
                    Err(patches) => {
                        let stage = stage.as_ref().expect("a mesh is a 3D surface");
                        return encode_png(&stage.view_of(
                            &outcome.fields,
                            patches.clone(),
                            440,
                            360,
                        ));
                    }
                };
                // each surface on its own scale (the bar says which), unless the document
                // sets one: a wall beside a light is not black, and B that varies by a few
                // per cent is shown from its least value up
                let range = match job.output.image.exposure {
                    Exposure::White(w) => (0.0, w),
                    Exposure::Auto => surface_range(f),
                };
                let title = match &job.scene.name {
                    Some(scene) => format!("{scene}: B over {name}"),
                    None => format!("B over {name}"),
                };
                encode_png(&plot::surface(&title, f, range))
            })
            .collect()
    };
    let (((image, glb), sparsity), (coefficients, surfaces)) = rayon::join(
        || rayon::join(main, sparsity),
        || rayon::join(coefficients, surfaces),
    );
    Images {
        image,
        sparsity,
        coefficients,
        surfaces: names.into_iter().zip(surfaces).collect(),
        glb,
    }
}

/// The range of B that a surface's own image spans: from 0, or from its least value when that
/// is more than half its greatest (a strip whose B varies by 10 % would be one grey from 0), to
/// its greatest.
fn surface_range(f: &Field) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for leaf in &f.leaves {
        for i in 0..=4 {
            for j in 0..=(if f.dims == 2 { 4 } else { 0 }) {
                let s = leaf.s[0] + (leaf.s[1] - leaf.s[0]) * i as f64 / 4.0;
                let t = leaf.t[0] + (leaf.t[1] - leaf.t[0]) * j as f64 / 4.0;
                for v in f.eval_leaf(leaf, s, t) {
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
            }
        }
    }
    if !(hi > 0.0 && hi.is_finite()) {
        return (0.0, 1.0);
    }
    // a uniform surface (a light that reflects nothing): at the middle of its scale, not at
    // white on the white page
    if hi - lo <= 1e-9 * hi {
        return (0.0, 2.0 * hi);
    }
    if lo > 0.5 * hi && hi > lo {
        (lo, hi)
    } else {
        (0.0, hi)
    }
}

/// B to a display colour: linear scale to `white`, clamped, sRGB-like gamma: the level
/// round(255 x^(1/2.2)) of x = B / white.
fn tone(v: [f64; 3], white: f64) -> Rgb<u8> {
    let c = |x: f64| gamma_level((x / white).clamp(0.0, 1.0));
    Rgb([c(v[0]), c(v[1]), c(v[2])])
}

/// round(255 x^(1/2.2)) for x in [0, 1], as the count of the levels' lower edges
/// ((k − ½) / 255)^2.2 at or below x: `powf` for every channel of every pixel was 7 % of the
/// room with 7 × 7 boxes' whole `wavrad render` (a picture of each of its 252 surfaces), the
/// search over the edges 4 %.
fn gamma_level(x: f64) -> u8 {
    static EDGES: std::sync::OnceLock<[f64; 255]> = std::sync::OnceLock::new();
    let edges = EDGES.get_or_init(|| std::array::from_fn(|k| ((k as f64 + 0.5) / 255.0).powf(2.2)));
    edges.partition_point(|&e| e <= x) as u8
}

/// PNG bytes of an image (fast deflate, adaptive filter: deterministic for the same pixels).
fn encode_png(img: &RgbImage) -> Vec<u8> {
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new_with_quality(
        &mut out,
        image::codecs::png::CompressionType::Fast,
        image::codecs::png::FilterType::Adaptive,
    )
    .write_image(
        img.as_raw(),
        img.width(),
        img.height(),
        image::ExtendedColorType::Rgb8,
    )
    .expect("encoding a PNG into memory cannot fail");
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn surface_images_map_b_to_colour_with_t_upwards() {
        // B = 0 on the lower half (t < 1/2), a quarter of white above: down the middle of
        // the plot, the grey of a quarter comes before (above) the black
        let mut local = vec![[0.0; 3]; 4];
        local[2] = [0.25; 3];
        local[3] = [0.25; 3];
        let f = Field::uniform_square(0, 2, &local);
        let img = plot::surface("", &f, (0.0, 1.0));
        let x = (img.width() - 100) / 2;
        let rows = |v: u8| -> Vec<u32> {
            (0..img.height())
                .filter(|&y| img.get_pixel(x, y).0 == [v; 3])
                .collect()
        };
        let (grey, black) = (rows(136), rows(0));
        assert!(
            grey.len() > 100 && black.len() > 100,
            "{} {}",
            grey.len(),
            black.len()
        );
        assert!(grey.iter().max() < black.iter().min());
        assert_eq!(tone([0.25, 2.0, -1.0], 1.0).0, [136, 255, 0]);
    }

    /// The levels of the power itself at 2²⁰ + 1 points of [0, 1], and within one level on the
    /// levels' edges, where the two roundings may differ.
    #[test]
    fn the_gamma_levels_are_those_of_the_power() {
        let power = |x: f64| (x.powf(1.0 / 2.2) * 255.0).round() as u8;
        let n = 1 << 20;
        let wrong: Vec<f64> = (0..=n)
            .map(|i| i as f64 / n as f64)
            .filter(|&x| gamma_level(x) != power(x))
            .collect();
        assert!(wrong.is_empty(), "{wrong:?}");
        for k in 0..255 {
            let edge = ((k as f64 + 0.5) / 255.0).powf(2.2);
            assert_eq!(gamma_level(edge), k as u8 + 1);
            assert!(power(edge).abs_diff(k as u8 + 1) <= 1, "{k}");
        }
    }

    #[test]
    fn charts_are_deterministic() {
        let c = crate::result::Coefficients {
            basis_size: 4,
            matrix_entries: 16,
            kept_entries: 8,
            sparsity_ratio: 0.5,
            cut: 1e-3,
            sorted_magnitudes: vec![1.0, 0.1, 1e-3, 1e-6, 0.0],
            sorted_ranks: vec![0, 4, 8, 12, 15],
        };
        let a = encode_png(&plot::coefficients(&c));
        let b = encode_png(&plot::coefficients(&c));
        assert_eq!(a, b);
        let p = crate::methods::compress::MagnitudePicture {
            side: 4,
            values: (0..16).map(|i| 10f64.powi(-(i % 5))).collect(),
            block: 1,
            cut: 1e-3,
            links: false,
        };
        let names = ["a".to_string(), "b".to_string()];
        let s = plot::sparsity(&p, &names);
        assert_eq!(encode_png(&s), encode_png(&plot::sparsity(&p, &names)));
        // Entries below the cut are white; the largest is the top of the colour map.
        let colors: std::collections::HashSet<[u8; 3]> = s.pixels().map(|p| p.0).collect();
        let top = plot::viridis(1.0);
        assert!(colors.contains(&[top.0, top.1, top.2]));
    }
}
