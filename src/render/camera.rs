//! Camera images of a solved 3D scene: for every pixel the first surface hit through the
//! [`Bvh`], and B there, shown as radiance L = B / π (the surfaces are Lambertian, spec eq. (3)),
//! scaled by an exposure and encoded in sRGB.
//!
//! - Anti-aliasing: adaptive supersampling (Whitted 1980, "An improved illumination model for
//!   shaded display", §4): one ray through each pixel's centre, and four more on a rotated grid
//!   (fixed offsets, so the image is deterministic) for the pixels whose centre differs from a
//!   neighbour's by a silhouette, a crease, a light's outline or a visible step
//!   ([`Seen::edge`]). Inside a surface, where B is smooth, the four samples' mean is the
//!   centre's to second order: 6 % of the pixels of an icosphere's picture in a room, 1 % of
//!   the room's, are supersampled, and a picture casts a third of the rays.
//! - Solutions are shown smooth by default, as radiosity renderers do (Cohen and Wallace,
//!   "Radiosity and Realistic Image Synthesis", §9.2): B is interpolated bilinearly between the
//!   centres of the finest cells, which for order 0 replaces the flat patches and for higher
//!   orders hides the jumps between elements of different levels; [`Options::raw`] shows the
//!   elements as they are.
//! - The back of a surface is black (one-sided surfaces); missed rays are black.

use crate::job::Outcome;
use crate::math::field::Field;
use crate::scene::{Camera, Exposure, Job, SceneKind};
use crate::three_d::bvh::Bvh;
use crate::three_d::geometry::{
    add, bounding_box, cross, dot, norm, normalize, scale, sub, Parallelogram, V3,
};
use image::{Rgb, RgbImage};
use rayon::prelude::*;

/// Rotated-grid sample offsets within a pixel.
const SAMPLES: [[f64; 2]; 4] = [
    [0.375, 0.125],
    [0.875, 0.375],
    [0.625, 0.875],
    [0.125, 0.625],
];

/// How to show the solution.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Options {
    /// Show the elements as they are (flat patches at order 0) instead of interpolating.
    pub raw: bool,
    /// Draw the leaves' outlines.
    pub mesh: bool,
}

/// The scene of `job` from its camera (or one framing the whole scene), with B from `outcome`,
/// shown as `output.image` asks (`raw`, `mesh`).
pub fn render(job: &Job, outcome: &Outcome, width: u32, height: u32) -> RgbImage {
    let spec = job.output.image;
    let opts = Options {
        raw: spec.raw,
        mesh: spec.mesh,
    };
    render_fields(job, &outcome.fields, width, height, opts)
}

/// [`render`] from the fields themselves, with options.
pub fn render_fields(
    job: &Job,
    fields: &[Field],
    width: u32,
    height: u32,
    opts: Options,
) -> RgbImage {
    shoot(job, fields, width, height, opts).image
}

/// A camera image with what it took to make it: the exposure and the camera, which
/// `scene.glb` shares with `image.png`.
#[derive(Debug, Clone)]
pub struct Shot {
    pub(super) image: RgbImage,
    /// The radiance (B/π) shown as white.
    pub white: f64,
    /// The camera, the document's or the one framed automatically.
    pub camera: Camera,
}

/// [`render`] with its exposure and camera.
pub fn shoot(job: &Job, fields: &[Field], width: u32, height: u32, opts: Options) -> Shot {
    match Stage::of(job) {
        Some(stage) => stage.shoot(fields, width, height, opts, None),
        None => Shot {
            image: RgbImage::new(width, height),
            white: 1.0,
            camera: Camera {
                eye: [0.0, 0.0, -1.0],
                look_at: [0.0; 3],
                up: [0.0, 1.0, 0.0],
                fov_deg: 40.0,
            },
        },
    }
}

/// A 3D scene made ready for cameras: its patches and the BVH over them, built once for all
/// the images of a job (a mesh surface's picture sees the whole scene, and a scene of 10⁵
/// triangles with 81 meshes had built 82 BVHs of 10⁵ triangles).
pub(super) struct Stage<'j> {
    job: &'j Job,
    geo: Vec<Parallelogram>,
    bvh: Bvh,
    lights: Vec<Light>,
    /// The document surface of each patch (a mesh's triangles are one surface).
    owners: Vec<usize>,
}

impl<'j> Stage<'j> {
    /// The stage of a 3D scene (`None` for flatland).
    pub(super) fn of(job: &'j Job) -> Option<Stage<'j>> {
        let SceneKind::ThreeD(quads) = &job.scene.kind else {
            return None;
        };
        let geo: Vec<Parallelogram> = quads.iter().map(Parallelogram::of).collect();
        let bvh = Bvh::new(&geo);
        let lights = quads
            .iter()
            .map(|q| Light {
                on: q.material.emission != [0.0; 3],
                region: q.emission_region,
            })
            .collect();
        Some(Stage {
            job,
            geo,
            bvh,
            lights,
            owners: quads.owners(),
        })
    }

    /// The scene seen by a camera that frames the patches `patches` (a mesh surface's
    /// picture).
    pub(super) fn view_of(
        &self,
        fields: &[Field],
        patches: std::ops::Range<usize>,
        width: u32,
        height: u32,
    ) -> RgbImage {
        let camera = frame(&self.geo, &self.bvh, patches);
        self.shoot(fields, width, height, Options::default(), Some(camera))
            .image
    }

    /// [`shoot`] on this stage, from `camera` when given, else the document's or one framed
    /// automatically.
    pub(super) fn shoot(
        &self,
        fields: &[Field],
        width: u32,
        height: u32,
        opts: Options,
        camera: Option<Camera>,
    ) -> Shot {
        // the leaves' outlines and flat patches have edges inside a surface that the
        // centres do not show: there every pixel is supersampled
        let every_pixel = opts.raw || opts.mesh;
        self.shoot_sampled(fields, [width, height], opts, camera, every_pixel)
            .0
    }

    /// [`Stage::shoot`], supersampling `every_pixel` or only those at an edge ([`Seen::edge`]),
    /// with the number of pixels supersampled.
    fn shoot_sampled(
        &self,
        fields: &[Field],
        [width, height]: [u32; 2],
        opts: Options,
        camera: Option<Camera>,
        every_pixel: bool,
    ) -> (Shot, usize) {
        let (geo, bvh, lights) = (&self.geo, &self.bvh, &self.lights);
        let camera = camera
            .or(self.job.output.camera)
            .unwrap_or_else(|| frame(geo, bvh, 0..geo.len()));
        let view = View::new(&camera, width, height);
        let smooth: Vec<Option<Smooth>> = fields
            .iter()
            .map(|f| (!opts.raw && !f.tri).then(|| Smooth::new(f)))
            .collect();
        let (w, h) = (width as usize, height as usize);
        // the white point of what the camera sees
        let white_of =
            |seen: &mut dyn Iterator<Item = ([f64; 3], bool)>| match self.job.output.image.exposure
            {
                Exposure::White(v) => v,
                Exposure::Auto => auto_exposure(seen),
            };
        let trace = |x: f64, y: f64| {
            shade(
                bvh,
                geo,
                fields,
                &smooth,
                lights,
                view.eye,
                view.ray(x, y),
                opts,
                view.pixel_angle,
            )
        };
        let sampled = |x: usize, y: usize| {
            let mut sum = [0.0; 3];
            let mut lit = false;
            for o in SAMPLES {
                let seen = trace(x as f64 + o[0], y as f64 + o[1]);
                lit |= seen.lit;
                (0..3).for_each(|c| sum[c] += seen.radiance[c] / SAMPLES.len() as f64);
            }
            (sum, lit)
        };
        let (radiance, supersampled): (Vec<([f64; 3], bool)>, usize) = if !every_pixel {
            // one ray through each pixel's centre, rows in parallel
            let centres: Vec<Seen> = (0..w * h)
                .into_par_iter()
                .map(|i| trace((i % w) as f64 + 0.5, (i / w) as f64 + 0.5))
                .collect();
            // the centres' own, for the steps the edge test sees; the image's is taken again
            // from the pixels as they come out
            let white = white_of(&mut centres.iter().map(|c| (c.radiance, c.lit)));
            let shown: Vec<Rgb<u8>> = centres.iter().map(|c| encode(c.radiance, white)).collect();
            // a pixel whose centre differs from a neighbour's by an edge
            let edges: Vec<bool> = (0..w * h)
                .into_par_iter()
                .map(|i| {
                    let (x, y) = (i % w, i / w);
                    [
                        (x > 0).then(|| i - 1),
                        (x + 1 < w).then(|| i + 1),
                        (y > 0).then(|| i - w),
                        (y + 1 < h).then(|| i + w),
                    ]
                    .into_iter()
                    .flatten()
                    .any(|j| centres[i].edge(&centres[j], [shown[i], shown[j]], self))
                })
                .collect();
            let radiance = (0..w * h)
                .into_par_iter()
                .map(|i| match edges[i] {
                    true => sampled(i % w, i / w),
                    false => (centres[i].radiance, centres[i].lit),
                })
                .collect();
            (radiance, edges.iter().filter(|&&e| e).count())
        } else {
            let radiance = (0..h)
                .into_par_iter()
                .flat_map_iter(|y| (0..w).map(move |x| sampled(x, y)))
                .collect();
            (radiance, w * h)
        };
        let white = white_of(&mut radiance.iter().copied());
        let mut img = RgbImage::new(width, height);
        for (i, (v, _)) in radiance.iter().enumerate() {
            img.put_pixel((i % w) as u32, (i / w) as u32, encode(*v, white));
        }
        let shot = Shot {
            image: img,
            white,
            camera,
        };
        (shot, supersampled)
    }
}

/// B over one surface as an image (s to the right, t up), radiance B/π scaled so that
/// `exposure` maps to white.
pub fn surface_image(field: &Field, width: u32, height: u32, exposure: f64) -> RgbImage {
    let mut img = RgbImage::new(width, height);
    for y in 0..height {
        for x in 0..width {
            let s = (x as f64 + 0.5) / width as f64;
            let t = 1.0 - (y as f64 + 0.5) / height as f64;
            let b = field.eval(s, t);
            img.put_pixel(x, y, encode(b.map(|v| v / std::f64::consts::PI), exposure));
        }
    }
    img
}

/// A camera for a document that gives none (`part` all the patches), or for a mesh's picture
/// (`part` its patches): one that sees the fronts of the patches of `part`, the whole scene
/// in the way.
///
/// From outside, it frames the bounding sphere of `part` at 40° along one of the six axes or
/// the eight diagonals, −z first (an open box faces it, as in the Cornell box): the first
/// direction with the most pixels of a coarse probe image on the front of a patch of `part`.
/// Where that is less than a fifth of the probe (a closed room, two plates facing each other,
/// a ball in a room whose walls stand between it and every such camera), the same directions
/// at 90° from half as far, the centre of the sphere looking out at 90° along a horizontal
/// axis, eyes inside the box of `part` near each of its side faces, upper edges and upper
/// corners looking at its centre at 90°, and for a part of the scene eyes near the side
/// faces, edges and corners of the whole scene's box looking at the part's centre are tried
/// too: of those that see at least [`NEARLY`] as much front as the best, the one that sees
/// the fronts of most patches is taken.
fn frame(geo: &[Parallelogram], bvh: &Bvh, part: std::ops::Range<usize>) -> Camera {
    let (lo, hi) = bounding_box(&geo[part.clone()]);
    let center = scale(add(lo, hi), 0.5);
    let radius = 0.5 * norm(sub(hi, lo));
    let camera = |d: V3, dist: f64, fov_deg: f64| Camera {
        eye: sub(center, scale(d, dist)),
        look_at: center,
        up: if d[1].abs() > 0.9 {
            [0.0, 0.0, 1.0]
        } else {
            [0.0, 1.0, 0.0]
        },
        fov_deg,
    };
    let axes: [V3; 6] = [
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
    ];
    let diagonals = (0..8).map(|i| {
        let sign = |b: usize| if i & b == 0 { 1.0 } else { -1.0 };
        normalize([sign(1), sign(2), sign(4)])
    });
    let probe = |cams: Vec<Camera>| {
        cams.into_iter()
            .map(|c| (front_facing(bvh, geo, &c, part.clone()), c))
            .collect::<Vec<_>>()
    };
    let fov: f64 = 40.0;
    let dist = radius / (0.5 * fov.to_radians()).sin();
    let directions: Vec<V3> = axes.iter().copied().chain(diagonals).collect();
    let mut seen = probe(directions.iter().map(|&d| camera(d, dist, fov)).collect());
    let outside = *seen
        .iter()
        .reduce(|best, c| if c.0.front > best.0.front { c } else { best })
        .expect("fourteen cameras");
    if outside.0.front >= 0.2 {
        return outside.1;
    }
    let near = radius / (0.5 * 90f64.to_radians()).sin();
    seen = vec![outside];
    seen.extend(probe(
        directions.iter().map(|&d| camera(d, near, 90.0)).collect(),
    ));
    seen.extend(probe(
        axes.iter()
            .filter(|d| d[1].abs() < 0.9)
            .map(|&d| Camera {
                eye: center,
                look_at: add(center, d),
                ..camera(d, 0.0, 90.0)
            })
            .collect(),
    ));
    // inside the box, near each of its side faces, its upper edges and corners, looking at
    // its centre: a closed room seen from within, most of it in view, from eye height or
    // above (y is up). These and the centre's cameras do not look straight up or down: from
    // the room's centre, a room of boxes seen from above showed their tops and no more
    let within = |(lo, hi): (V3, V3), d: V3| {
        let (middle, half) = (scale(add(lo, hi), 0.5), scale(sub(hi, lo), 0.5));
        let m = d.iter().fold(0.0, |m: f64, x| m.max(x.abs()));
        Camera {
            eye: sub(middle, [0, 1, 2].map(|a| WITHIN * d[a] / m * half[a])),
            ..camera(d, 0.0, 90.0)
        }
    };
    seen.extend(probe(
        directions
            .iter()
            .filter(|d| d[1] <= 0.0 && d[1] > -0.9)
            .map(|&d| within((lo, hi), d))
            .collect(),
    ));
    // a part of the scene, from the same places in the whole scene's box, lower ones too,
    // looking at the part: a room's wall, floor or ceiling made of triangles is flat, and
    // every eye in its own box stood in its plane
    if part.len() < geo.len() {
        let scene = bounding_box(geo);
        seen.extend(probe(
            directions
                .iter()
                .filter(|d| d[1].abs() < 0.9)
                .map(|&d| within(scene, d))
                .collect(),
        ));
    }
    // of the cameras that see nearly as much of the fronts as the best, the one that sees
    // most surfaces: inside a room every camera sees fronts alone, and the one from the
    // ceiling's centre saw its light and little else
    let most = seen.iter().map(|c| c.0.front).fold(0.0, f64::max);
    seen.iter()
        .filter(|c| c.0.front >= NEARLY * most)
        .reduce(|best, c| {
            if c.0.patches > best.0.patches {
                c
            } else {
                best
            }
        })
        .expect("the camera that sees most")
        .1
}

/// How far toward the faces, edges and corners of a part's box the cameras inside it stand
/// ([`frame`]), as a share of the way from its centre: near enough to a room's walls to see
/// most of it, far enough not to stand in them.
const WITHIN: f64 = 0.85;

/// The share of the most front a camera must see to be chosen for the surfaces it sees
/// ([`frame`]).
const NEARLY: f64 = 0.9;

/// What a 32 × 32 probe image of a camera sees of a part of the scene ([`front_facing`]).
#[derive(Debug, Clone, Copy)]
struct Probe {
    /// The fraction of the image on the front of a patch of the part.
    front: f64,
    /// How many patches of the part it sees the front of.
    patches: usize,
}

/// What a 32 × 32 probe image of `camera` sees of the fronts of the patches of `part`.
fn front_facing(
    bvh: &Bvh,
    geo: &[Parallelogram],
    camera: &Camera,
    part: std::ops::Range<usize>,
) -> Probe {
    const N: u32 = 32;
    let view = View::new(camera, N, N);
    let mut front = Vec::new();
    for y in 0..N {
        for x in 0..N {
            let d = view.ray(x as f64 + 0.5, y as f64 + 0.5);
            let hit = bvh.first_hit(view.eye, d, 0.0, f64::INFINITY, [usize::MAX; 2]);
            if let Some(h) = hit {
                if part.contains(&h.surface) && dot(d, geo[h.surface].n) < 0.0 {
                    front.push(h.surface);
                }
            }
        }
    }
    let share = front.len() as f64 / (N * N) as f64;
    front.sort_unstable();
    front.dedup();
    Probe {
        front: share,
        patches: front.len(),
    }
}

struct View {
    eye: V3,
    forward: V3,
    right: V3,
    up: V3,
    /// Half-height of the image plane at distance 1, per pixel.
    pixel: f64,
    width: f64,
    height: f64,
    pixel_angle: f64,
}

impl View {
    fn new(c: &Camera, width: u32, height: u32) -> View {
        let forward = normalize(sub(c.look_at, c.eye));
        let right = normalize(cross(forward, c.up));
        let up = cross(right, forward);
        let half = (0.5 * c.fov_deg.to_radians()).tan();
        let pixel = 2.0 * half / height as f64;
        View {
            eye: c.eye,
            forward,
            right,
            up,
            pixel,
            width: width as f64,
            height: height as f64,
            pixel_angle: pixel,
        }
    }

    /// Direction through image point (x, y) (pixels, y down).
    fn ray(&self, x: f64, y: f64) -> V3 {
        let u = (x - 0.5 * self.width) * self.pixel;
        let v = (0.5 * self.height - y) * self.pixel;
        normalize(add(
            self.forward,
            add(scale(self.right, u), scale(self.up, v)),
        ))
    }
}

/// B interpolated between the centres of the finest cells of a field.
struct Smooth {
    res: usize,
    values: Vec<[f64; 3]>,
}

impl Smooth {
    fn new(f: &Field) -> Smooth {
        let res = f.res;
        let mut values = Vec::with_capacity(res * res);
        for t in 0..res {
            for s in 0..res {
                values.push(f.eval((s as f64 + 0.5) / res as f64, (t as f64 + 0.5) / res as f64));
            }
        }
        Smooth { res, values }
    }

    fn eval(&self, s: f64, t: f64) -> [f64; 3] {
        let n = self.res;
        let coord = |x: f64| {
            let u = (x * n as f64 - 0.5).clamp(0.0, (n - 1) as f64);
            let i = (u.floor() as usize).min(n.saturating_sub(2));
            (i, u - i as f64)
        };
        if n == 1 {
            return self.values[0];
        }
        let (i, fs) = coord(s);
        let (j, ft) = coord(t);
        let at = |a: usize, b: usize| self.values[b * n + a];
        std::array::from_fn(|c| {
            (1.0 - ft) * ((1.0 - fs) * at(i, j)[c] + fs * at(i + 1, j)[c])
                + ft * ((1.0 - fs) * at(i, j + 1)[c] + fs * at(i + 1, j + 1)[c])
        })
    }
}

/// Where a surface emits.
struct Light {
    on: bool,
    region: ([f64; 2], [f64; 2]),
}

/// What one ray from the camera saw.
struct Seen {
    /// The radiance along it.
    radiance: [f64; 3],
    /// Whether it sees a light (left out of the automatic exposure).
    lit: bool,
    /// The patch it hit ([`NOTHING`] where it hit none), and the distance.
    patch: u32,
    dist: f32,
}

/// [`Seen::patch`] of a ray that hit nothing.
const NOTHING: u32 = u32::MAX;

/// Where two neighbouring pixels' centres differ by more than this, in sRGB levels of 255 in
/// any channel, both are supersampled: the step that an eye sees on a smooth ramp is a few
/// levels.
const EDGE_CONTRAST: u8 = 4;
/// Neighbouring centres on patches whose normals are further apart than this cosine (18°)
/// lie across a crease: the edge of a box, even where both sides are as bright.
const EDGE_CREASE_COS: f64 = 0.95;
/// Neighbouring centres whose distances differ by more than this share of the nearer lie
/// across a silhouette of one surface on itself. A plane seen at 87° from its normal,
/// through pixels 1/1000 of a radian apart, changes its distance by 2 % a pixel.
const EDGE_DEPTH_JUMP: f64 = 0.05;

impl Seen {
    /// Whether the pixels whose centres saw `self` and `other`, shown as `shown`, may hold an
    /// edge that the centres alone would alias: a silhouette, a crease, a light's outline, or
    /// a step in what is shown (a shadow).
    fn edge(&self, other: &Seen, shown: [Rgb<u8>; 2], stage: &Stage) -> bool {
        if self.lit != other.lit {
            return true;
        }
        let geometric = match (self.patch, other.patch) {
            (NOTHING, NOTHING) => false,
            (NOTHING, _) | (_, NOTHING) => true,
            (a, b) => {
                let (a, b) = (a as usize, b as usize);
                let (da, db) = (f64::from(self.dist), f64::from(other.dist));
                stage.owners[a] != stage.owners[b]
                    || dot(stage.geo[a].n, stage.geo[b].n) < EDGE_CREASE_COS
                    || (da - db).abs() > EDGE_DEPTH_JUMP * da.min(db)
            }
        };
        let [p, q] = shown;
        geometric || (0..3).any(|c| p.0[c].abs_diff(q.0[c]) > EDGE_CONTRAST)
    }
}

/// What the ray from `eye` along `d` sees.
#[allow(clippy::too_many_arguments)]
fn shade(
    bvh: &Bvh,
    geo: &[Parallelogram],
    fields: &[Field],
    smooth: &[Option<Smooth>],
    lights: &[Light],
    eye: V3,
    d: V3,
    opts: Options,
    pixel_angle: f64,
) -> Seen {
    let Some(hit) = bvh.first_hit(eye, d, 0.0, f64::INFINITY, [usize::MAX; 2]) else {
        return Seen {
            radiance: [0.0; 3],
            lit: false,
            patch: NOTHING,
            dist: 0.0,
        };
    };
    let q = &geo[hit.surface];
    let (patch, dist) = (hit.surface as u32, hit.dist as f32);
    if dot(d, q.n) >= 0.0 {
        return Seen {
            radiance: [0.0; 3],
            lit: false,
            patch,
            dist,
        };
    }
    let light = &lights[hit.surface];
    let (rs, rt) = light.region;
    let lit = light.on && (rs[0]..=rs[1]).contains(&hit.s) && (rt[0]..=rt[1]).contains(&hit.t);
    let (s, t) = (hit.s.clamp(0.0, 1.0), hit.t.clamp(0.0, 1.0));
    let field = &fields[hit.surface];
    let b = match &smooth[hit.surface] {
        Some(sm) => sm.eval(s, t),
        None => field.eval(s, t),
    };
    let mut l = b.map(|v| (v / std::f64::consts::PI).max(0.0));
    if opts.mesh {
        let leaf = field.leaf_at(s, t);
        let foot = hit.dist * pixel_angle * 0.75;
        let (ls, lt) = (norm(q.e1), norm(q.e3));
        let edge =
            ((s - leaf.s[0]).min(leaf.s[1] - s) * ls).min((t - leaf.t[0]).min(leaf.t[1] - t) * lt);
        if edge < foot {
            l = l.map(|v| v * 0.35);
        }
    }
    Seen {
        radiance: l,
        lit,
        patch,
        dist,
    }
}

/// The white point: the 97th percentile of the luminance of what the camera sees, lights
/// left out (they would darken everything else).
fn auto_exposure(radiance: &mut dyn Iterator<Item = ([f64; 3], bool)>) -> f64 {
    let mut lum: Vec<f64> = radiance
        .filter(|(_, lit)| !lit)
        .map(|(v, _)| 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2])
        .filter(|&v| v > 0.0)
        .collect();
    if lum.is_empty() {
        return 1.0;
    }
    lum.sort_by(f64::total_cmp);
    lum[((lum.len() - 1) as f64 * 0.97) as usize].max(1e-300)
}

/// Linear radiance, scaled so that `white` maps to 1, clamped and sRGB-encoded.
pub fn encode(v: [f64; 3], white: f64) -> Rgb<u8> {
    let f = |x: f64| {
        let x = (x / white).clamp(0.0, 1.0);
        let s = if x <= 0.0031308 {
            12.92 * x
        } else {
            1.055 * x.powf(1.0 / 2.4) - 0.055
        };
        (s * 255.0 + 0.5) as u8
    };
    Rgb([f(v[0]), f(v[1]), f(v[2])])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_end_points() {
        assert_eq!(encode([0.0, 1.0, 2.0], 1.0), Rgb([0, 255, 255]));
        assert_eq!(encode([0.5, 0.5, 0.5], 1.0).0[0], 188);
    }

    /// A closed room of side 10 (its surfaces facing in) with a light in the ceiling, and an
    /// octahedron of radius 1 about `c`, facing out, as the last surface.
    fn room_document(c: V3) -> serde_json::Value {
        let quad = |name: &str, corners: [[f64; 3]; 4]| serde_json::json!({"name": name, "corners": corners, "reflectance": 0.5});
        let s = 10.0;
        let mut surfaces = vec![
            quad(
                "floor",
                [[0.0, 0.0, 0.0], [0.0, 0.0, s], [s, 0.0, s], [s, 0.0, 0.0]],
            ),
            quad(
                "ceiling",
                [[0.0, s, 0.0], [s, s, 0.0], [s, s, s], [0.0, s, s]],
            ),
            quad("back", [[0.0, 0.0, s], [0.0, s, s], [s, s, s], [s, 0.0, s]]),
            quad(
                "front",
                [[0.0, 0.0, 0.0], [s, 0.0, 0.0], [s, s, 0.0], [0.0, s, 0.0]],
            ),
            quad(
                "left",
                [[0.0, 0.0, 0.0], [0.0, s, 0.0], [0.0, s, s], [0.0, 0.0, s]],
            ),
            quad(
                "right",
                [[s, 0.0, 0.0], [s, 0.0, s], [s, s, s], [s, s, 0.0]],
            ),
            serde_json::json!({"name": "light", "reflectance": 0.0, "emission": 10.0,
                "corners": [[4.0, 9.99, 4.0], [6.0, 9.99, 4.0], [6.0, 9.99, 6.0], [4.0, 9.99, 6.0]]}),
        ];
        let axes: [V3; 6] = [
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
        ];
        surfaces.push(
            serde_json::json!({"name": "octahedron", "reflectance": 0.7, "mesh": {
            "positions": axes.map(|a| add(c, a)),
            "triangles": [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4],
                          [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]}}),
        );
        serde_json::json!({"scene": {"kind": "3d", "surfaces": surfaces},
            "solver": {"method": "hierarchical", "order": 0}})
    }

    fn room_with_octahedron(c: V3) -> Job {
        let doc = room_document(c);
        crate::scene::parse_value(&doc, &crate::scene::Limits::default()).expect("a valid room")
    }

    /// A mesh's picture is framed by what the whole scene lets its camera see: it shows at
    /// least half as much of the mesh as a picture of the mesh alone. Framed as if the mesh
    /// were alone, an octahedron near a room's corner was looked at from 2.9 of its radii
    /// away, through a wall's back: every mesh picture of the 81 icospheres was black.
    #[test]
    fn a_meshs_picture_sees_the_mesh_through_the_room_around_it() {
        for c in [[2.0, 4.0, 2.0], [5.0, 1.2, 8.5], [8.0, 8.0, 5.0]] {
            let job = room_with_octahedron(c);
            let stage = Stage::of(&job).expect("a 3D scene");
            let SceneKind::ThreeD(d) = &job.scene.kind else {
                unreachable!()
            };
            let part = d.surfaces[7].patches.clone();
            let camera = frame(&stage.geo, &stage.bvh, part.clone());
            let seen = front_facing(&stage.bvh, &stage.geo, &camera, part.clone()).front;
            let geo = &stage.geo[part];
            let bvh = Bvh::new(geo);
            let alone =
                front_facing(&bvh, geo, &frame(geo, &bvh, 0..geo.len()), 0..geo.len()).front;
            assert!(
                seen >= 0.5 * alone,
                "{seen} of the picture of an octahedron about {c:?} shows it, {alone} alone"
            );
            assert!(
                camera.eye.iter().all(|&x| (0.0..10.0).contains(&x)),
                "the eye {:?} is in the room",
                camera.eye
            );
        }
    }

    /// A closed room with no camera in its document is pictured from within, from where
    /// most of it is in view: every outside camera sees the walls' backs, and the camera at
    /// the room's centre looking along an axis sees one wall and the edges of four. The
    /// camera chosen sees the fronts of more patches than any of those, and of at least half
    /// of the room's 15 (six walls, the light, the octahedron's eight faces).
    #[test]
    fn a_closed_rooms_picture_sees_most_of_it_from_within() {
        let job = room_with_octahedron([3.0, 3.0, 6.0]);
        let stage = Stage::of(&job).expect("a 3D scene");
        let all = 0..stage.geo.len();
        assert_eq!(all.len(), 15);
        let camera = frame(&stage.geo, &stage.bvh, all.clone());
        assert!(camera.eye.iter().all(|&x| (0.0..10.0).contains(&x)));
        let Probe {
            front: share,
            patches,
        } = front_facing(&stage.bvh, &stage.geo, &camera, all.clone());
        assert!(share > 0.95, "{share} of the picture on fronts");
        assert!(patches >= 8, "{patches} patches seen");
        for d in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]] {
            for sign in [1.0, -1.0] {
                let centre = Camera {
                    eye: [5.0; 3],
                    look_at: add([5.0; 3], scale(d, sign)),
                    up: if d[1] != 0.0 {
                        [0.0, 0.0, 1.0]
                    } else {
                        [0.0, 1.0, 0.0]
                    },
                    fov_deg: 90.0,
                };
                let from_centre =
                    front_facing(&stage.bvh, &stage.geo, &centre, all.clone()).patches;
                assert!(
                    from_centre < patches,
                    "{from_centre} from the centre, {patches}"
                );
            }
        }
    }

    /// A flat mesh that is part of a closed room's shell (its floor as two triangles) is
    /// pictured from inside the room: every eye in the floor's own box stands in its plane,
    /// and every one outside the room sees the walls' backs.
    #[test]
    fn a_rooms_floor_made_of_triangles_is_pictured_from_inside_the_room() {
        let mut doc = room_document([3.0, 3.0, 6.0]);
        let surfaces = doc["scene"]["surfaces"].as_array_mut().expect("surfaces");
        assert_eq!(surfaces[0]["name"], "floor");
        surfaces[0] = serde_json::json!({"name": "floor", "reflectance": 0.5, "mesh": {
            "positions": [[0.0, 0.0, 0.0], [0.0, 0.0, 10.0], [10.0, 0.0, 10.0], [10.0, 0.0, 0.0]],
            "triangles": [[0, 1, 2], [0, 2, 3]]}});
        let job = crate::scene::parse_value(&doc, &crate::scene::Limits::default()).expect("valid");
        let stage = Stage::of(&job).expect("a 3D scene");
        let SceneKind::ThreeD(d) = &job.scene.kind else {
            unreachable!()
        };
        let part = d.surfaces[0].patches.clone();
        assert_eq!(part.len(), 2);
        let camera = frame(&stage.geo, &stage.bvh, part.clone());
        let Probe {
            front: share,
            patches,
        } = front_facing(&stage.bvh, &stage.geo, &camera, part);
        assert!(
            camera.eye.iter().all(|&x| (0.0..10.0).contains(&x)),
            "{camera:?}"
        );
        assert!(
            share >= 0.2 && patches == 2,
            "{share} of the picture on the floor"
        );
    }

    /// Adaptive supersampling gives the supersampled image, where the edge test says the
    /// centres alone are enough, to within the step it lets pass ([`EDGE_CONTRAST`]) and one
    /// level for an exposure drawn from nearly the same radiance, for at most half the rays
    /// (a quarter of the pixels supersampled: 1 + 4/4 rays a pixel against 4).
    #[test]
    fn adaptive_supersampling_is_the_supersampled_image() {
        let job = room_with_octahedron([3.0, 3.0, 4.0]);
        let out = crate::job::run(&job, &crate::progress::Silent).expect("solves");
        let stage = Stage::of(&job).expect("a 3D scene");
        let SceneKind::ThreeD(d) = &job.scene.kind else {
            unreachable!()
        };
        let camera = frame(&stage.geo, &stage.bvh, d.surfaces[7].patches.clone());
        let (w, h) = (220, 180);
        let shot = |every| {
            let o = Options::default();
            stage.shoot_sampled(&out.fields, [w, h], o, Some(camera), every)
        };
        let (adaptive, every) = (shot(false), shot(true));
        assert_eq!(every.1, (w * h) as usize);
        let share = adaptive.1 as f64 / (w * h) as f64;
        assert!(share < 0.25, "{share} of the pixels supersampled");
        assert!(share > 0.0, "the octahedron's outline is supersampled");
        let far = adaptive
            .0
            .image
            .pixels()
            .zip(every.0.image.pixels())
            .filter(|(a, b)| (0..3).any(|c| a.0[c].abs_diff(b.0[c]) > EDGE_CONTRAST + 1))
            .count();
        assert!(
            far as f64 <= 1e-3 * (w * h) as f64,
            "{far} pixels differ by more than {} levels",
            EDGE_CONTRAST + 1
        );
    }

    #[test]
    fn smooth_interpolation_is_linear_between_centres() {
        // B(s) = s on 4 order-0 cells: centres 0.125 … 0.875
        let local: Vec<[f64; 3]> = (0..16).map(|i| [((i % 4) as f64 + 0.5) / 4.0; 3]).collect();
        let f = Field::uniform_square(0, 4, &local);
        let sm = Smooth::new(&f);
        assert!((sm.eval(0.3, 0.6)[0] - 0.3).abs() < 1e-12);
        assert!((sm.eval(0.05, 0.6)[0] - 0.125).abs() < 1e-12);
    }
}
