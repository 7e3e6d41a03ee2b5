//! The images of a finished job (`spec/scene.md`, "What a finished job yields"), as PNG bytes:
//! `image.png`, `sparsity.png`, `coefficients.png` and one `surfaces/<name>.png` per surface.
//!
//! Everything here is pure — a job and its outcome in, encoded bytes out, no file I/O — and
//! deterministic: the same document gives byte-identical PNGs (no timings, no randomness, a
//! font embedded in the binary).
//!
//! 3D scenes are drawn from the camera by a renderer registered in [`CAMERA`]; until one is
//! registered, a 3D `image.png` is a grid of the per-surface images.

pub mod plot;

use crate::field::Field;
use crate::job::Outcome;
use crate::scene::{Exposure, Job, SceneKind};
use image::{ImageEncoder, Rgb, RgbImage};
use rayon::prelude::*;
use std::sync::OnceLock;

/// The camera renderer for 3D scenes: `(job, outcome, width, height) -> image`.
pub type CameraFn = fn(&Job, &Outcome, u32, u32) -> RgbImage;

/// Set once at start-up by whoever provides the 3D camera renderer.
pub static CAMERA: OnceLock<CameraFn> = OnceLock::new();

/// Width and height of one per-surface image.
const STRIP: (u32, u32) = (512, 48);
const QUAD: (u32, u32) = (256, 256);

/// All images of a job, PNG-encoded.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Images {
    pub image: Vec<u8>,
    pub sparsity: Vec<u8>,
    pub coefficients: Vec<u8>,
    /// `(surface name, png)` in document order.
    pub surfaces: Vec<(String, Vec<u8>)>,
}

impl Images {
    /// `(artifact path, bytes)`: `image.png`, `sparsity.png`, `coefficients.png`,
    /// `surfaces/<name>.png`.
    pub fn files(&self) -> Vec<(String, &[u8])> {
        let mut out = vec![
            ("image.png".to_string(), self.image.as_slice()),
            ("sparsity.png".to_string(), self.sparsity.as_slice()),
            ("coefficients.png".to_string(), self.coefficients.as_slice()),
        ];
        for (name, png) in &self.surfaces {
            out.push((format!("surfaces/{name}.png"), png.as_slice()));
        }
        out
    }
}

/// Renders every image of a finished job.
pub fn render_all(job: &Job, outcome: &Outcome) -> Images {
    let spec = job.output.image;
    let names = job.surface_names();
    let white = white_point(job, &outcome.fields);
    // Independent images, drawn in parallel; each is deterministic on its own.
    let main = || {
        let img = match &job.scene.kind {
            SceneKind::ThreeD(_) => match CAMERA.get() {
                Some(camera) => camera(job, outcome, spec.width, spec.height),
                None => plot::surface_grid(&names, &outcome.fields, white, spec.width, spec.height),
            },
            _ => plot::radiosity(job, &names, &outcome.fields, spec.width, spec.height),
        };
        encode_png(&img)
    };
    let sparsity = || {
        encode_png(&match &outcome.picture {
            Some(p) => plot::sparsity(p),
            None => plot::message(
                640,
                560,
                "No kernel matrix: this method builds links, not a matrix",
            ),
        })
    };
    let coefficients = || encode_png(&plot::coefficients(&outcome.result.coefficients));
    let surfaces = || -> Vec<Vec<u8>> {
        outcome
            .fields
            .par_iter()
            .map(|f| encode_png(&surface_image(f, white, surface_size(f))))
            .collect()
    };
    let ((image, sparsity), (coefficients, surfaces)) = rayon::join(
        || rayon::join(main, sparsity),
        || rayon::join(coefficients, surfaces),
    );
    Images {
        image,
        sparsity,
        coefficients,
        surfaces: names.into_iter().zip(surfaces).collect(),
    }
}

fn surface_size(f: &Field) -> (u32, u32) {
    if f.dims == 2 {
        QUAD
    } else {
        STRIP
    }
}

/// The value of B that maps to white: the document's exposure, or the brightest sampled value.
pub fn white_point(job: &Job, fields: &[Field]) -> f64 {
    match job.output.image.exposure {
        Exposure::White(w) => w,
        Exposure::Auto => {
            let mut max = 0.0f64;
            for f in fields {
                for leaf in &f.leaves {
                    for i in 0..=4 {
                        for j in 0..=(if f.dims == 2 { 4 } else { 0 }) {
                            let s = leaf.s[0] + (leaf.s[1] - leaf.s[0]) * i as f64 / 4.0;
                            let t = leaf.t[0] + (leaf.t[1] - leaf.t[0]) * j as f64 / 4.0;
                            let v = f.eval_leaf(leaf, s, t);
                            max = max.max(v[0]).max(v[1]).max(v[2]);
                        }
                    }
                }
            }
            if max > 0.0 && max.is_finite() {
                max
            } else {
                1.0
            }
        }
    }
}

/// B to a display colour: linear scale to `white`, clamped, sRGB-like gamma.
pub fn tone(v: [f64; 3], white: f64) -> Rgb<u8> {
    let c = |x: f64| {
        let x = (x / white).clamp(0.0, 1.0);
        (x.powf(1.0 / 2.2) * 255.0).round() as u8
    };
    Rgb([c(v[0]), c(v[1]), c(v[2])])
}

/// B over one surface: a strip along s (1D) or the unit square with t upwards (2D).
pub fn surface_image(f: &Field, white: f64, (w, h): (u32, u32)) -> RgbImage {
    if f.dims == 2 {
        RgbImage::from_fn(w, h, |x, y| {
            let s = (x as f64 + 0.5) / w as f64;
            let t = 1.0 - (y as f64 + 0.5) / h as f64;
            tone(f.eval(s, t), white)
        })
    } else {
        let row: Vec<Rgb<u8>> = (0..w)
            .map(|x| tone(f.eval((x as f64 + 0.5) / w as f64, 0.0), white))
            .collect();
        RgbImage::from_fn(w, h, |x, _| row[x as usize])
    }
}

/// PNG bytes of an image (fast deflate, adaptive filter: deterministic for the same pixels).
pub fn encode_png(img: &RgbImage) -> Vec<u8> {
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

    /// A constant 2D field: order 0, `cells²` cells, every cell `v` (φ_0 = 1 on a unit cell).
    fn flat_square(cells: usize, v: [f64; 3]) -> Field {
        Field::uniform_square(0, cells, &vec![v; cells * cells])
    }

    #[test]
    fn a_3d_image_without_a_camera_tiles_every_surface() {
        let fields = vec![
            flat_square(2, [1.0, 0.0, 0.0]),
            flat_square(2, [0.0, 0.0, 1.0]),
        ];
        let names = vec!["red".to_string(), "blue".to_string()];
        let img = plot::surface_grid(&names, &fields, 1.0, 200, 100);
        assert_eq!((img.width(), img.height()), (200, 100));
        // Two columns, one row: the middle of each tile has its surface's colour.
        assert_eq!(img.get_pixel(50, 60).0, [255, 0, 0]);
        assert_eq!(img.get_pixel(150, 60).0, [0, 0, 255]);
    }

    #[test]
    fn surface_images_map_b_to_colour_with_t_upwards() {
        // B = 1 on the lower half (t < 1/2), 0 above.
        let mut local = vec![[0.0; 3]; 4];
        local[0] = [1.0; 3];
        local[1] = [1.0; 3];
        let f = Field::uniform_square(0, 2, &local);
        let img = surface_image(&f, 1.0, (10, 10));
        assert_eq!(img.get_pixel(5, 9).0, [255, 255, 255]);
        assert_eq!(img.get_pixel(5, 0).0, [0, 0, 0]);
        assert_eq!(tone([0.25, 2.0, -1.0], 1.0).0, [136, 255, 0]);
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
        let p = crate::compress::MagnitudePicture {
            side: 4,
            values: (0..16).map(|i| 10f64.powi(-(i % 5))).collect(),
            block: 1,
            cut: 1e-3,
        };
        let s = plot::sparsity(&p);
        assert_eq!(encode_png(&s), encode_png(&plot::sparsity(&p)));
        // Entries below the cut are white; the largest is the top of the colour map.
        let colors: std::collections::HashSet<[u8; 3]> = s.pixels().map(|p| p.0).collect();
        let top = plot::viridis(1.0);
        assert!(colors.contains(&[top.0, top.1, top.2]));
    }
}
