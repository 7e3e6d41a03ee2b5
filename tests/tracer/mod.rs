//! An independent Monte Carlo reference for the 3D solvers.
//!
//! It shares no code with the library: it reads the scene's JSON itself, finds the surfaces a
//! ray may meet with the `bvh` crate's tree over their boxes (not the library's own tree) and
//! meets them with its own ray–parallelogram test, and estimates the radiosity equation
//! B(x) = E(x) + ρ(x) ∫ B(y) cosθx cosθy / (π r²) V(x, y) dA_y by path tracing with Russian
//! roulette. The emitted light reaching a vertex is estimated twice and the two combined by
//! multiple importance sampling (Veach and Guibas 1995, the power heuristic): a light point on
//! every emitting document surface (on one of its patches drawn by area), and the
//! cosine-distributed direction that continues the path when it meets an emitter. Light
//! points alone have unbounded variance next to an emitter (1/r² where a frame stands on a
//! lit window pane); the direction has none there.
//! It returns cell means on the same `grid × grid` split as the result, each with its standard
//! error, so that a comparison can tell a real difference from sampling noise.
#![allow(dead_code)]

use bvh::aabb::{Aabb, Bounded};
use bvh::bounding_hierarchy::BHShape;
use bvh::bvh::Bvh;
use bvh::ray::Ray;
use nalgebra::{Point3, Vector3};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use serde_json::Value;
use wavrad::job;
use wavrad::progress::Silent;
use wavrad::scene::{parse_value, Limits};

pub type V3 = [f64; 3];

pub fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
pub fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
pub fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
pub fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
pub fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
pub fn mul(a: V3, b: V3) -> V3 {
    [a[0] * b[0], a[1] * b[1], a[2] * b[2]]
}

/// One parallelogram p(s, t) = p0 + s e1 + t e2 as the spec defines it, or with `tri` the
/// triangle s + t ≤ 1 of the same map (a `triangle`, or one triangle of a `mesh`).
pub struct Quad {
    pub p0: V3,
    pub e1: V3,
    pub e2: V3,
    pub n: V3,
    pub area: f64,
    pub tri: bool,
    /// The document surface it belongs to.
    pub owner: usize,
    pub rho: V3,
    pub emission: V3,
    pub region: ([f64; 2], [f64; 2]),
}

impl Quad {
    pub fn at(&self, s: f64, t: f64) -> V3 {
        add(self.p0, add(scale(self.e1, s), scale(self.e2, t)))
    }

    /// The distance along `dir` from `o` to this parallelogram, if the ray meets it.
    pub fn hit(&self, o: V3, dir: V3) -> Option<f64> {
        self.hit_at(o, dir).map(|(h, _, _)| h)
    }

    /// The distance and the (s, t) where the ray from `o` along `dir` meets this patch.
    pub fn hit_at(&self, o: V3, dir: V3) -> Option<(f64, f64, f64)> {
        // Möller–Trumbore for a parallelogram: solve o + h dir = p0 + s e1 + t e2
        let p = cross(dir, self.e2);
        let det = dot(self.e1, p);
        if det.abs() < 1e-300 {
            return None;
        }
        let inv = 1.0 / det;
        let q = sub(o, self.p0);
        let s = dot(q, p) * inv;
        if !(0.0..=1.0).contains(&s) {
            return None;
        }
        let r = cross(q, self.e1);
        let t = dot(dir, r) * inv;
        if !(0.0..=1.0).contains(&t) || (self.tri && s + t > 1.0) {
            return None;
        }
        Some((dot(self.e2, r) * inv, s, t))
    }

    /// The area of its emission region.
    pub fn emitting_area(&self) -> f64 {
        let (rs, rt) = self.region;
        self.area * (rs[1] - rs[0]) * (rt[1] - rt[0])
    }

    pub fn emits(&self, s: f64, t: f64) -> bool {
        let (rs, rt) = self.region;
        rs[0] <= s && s <= rs[1] && rt[0] <= t && t <= rt[1]
    }
}

pub fn rgb(v: Option<&Value>, default: f64) -> V3 {
    match v {
        None => [default; 3],
        Some(Value::Array(a)) => [0, 1, 2].map(|i| a[i].as_f64().expect("number")),
        Some(x) => [x.as_f64().expect("number"); 3],
    }
}

pub fn point(v: &Value) -> V3 {
    [0, 1, 2].map(|i| v[i].as_f64().expect("coordinate"))
}

pub fn quads(doc: &Value) -> Vec<Quad> {
    let mut out = Vec::new();
    for (owner, s) in doc["scene"]["surfaces"]
        .as_array()
        .expect("surfaces")
        .iter()
        .enumerate()
    {
        let rho = rgb(s.get("reflectance"), 0.0);
        let emission = rgb(s.get("emission"), 0.0);
        let make = |p0: V3, p1: V3, p2: V3, tri: bool, region| {
            let (e1, e2) = (sub(p1, p0), sub(p2, p0));
            let n = cross(e1, e2);
            let area = dot(n, n).sqrt();
            Quad {
                p0,
                e1,
                e2,
                n: scale(n, 1.0 / area),
                area: if tri { 0.5 * area } else { area },
                tri,
                owner,
                rho,
                emission,
                region,
            }
        };
        let whole = ([0.0, 1.0], [0.0, 1.0]);
        if let Some(c) = s.get("corners").and_then(Value::as_array) {
            let region = match s.get("emission_region") {
                Some(r) => (
                    [r["s"][0].as_f64().unwrap(), r["s"][1].as_f64().unwrap()],
                    [r["t"][0].as_f64().unwrap(), r["t"][1].as_f64().unwrap()],
                ),
                None => whole,
            };
            out.push(make(
                point(&c[0]),
                point(&c[1]),
                point(&c[3]),
                false,
                region,
            ));
        } else if let Some(t) = s.get("triangle").and_then(Value::as_array) {
            out.push(make(point(&t[0]), point(&t[1]), point(&t[2]), true, whole));
        } else {
            let m = &s["mesh"];
            let p: Vec<V3> = m["positions"]
                .as_array()
                .unwrap()
                .iter()
                .map(point)
                .collect();
            for t in m["triangles"].as_array().unwrap() {
                let i = [0, 1, 2].map(|k| t[k].as_u64().unwrap() as usize);
                out.push(make(p[i[0]], p[i[1]], p[i[2]], true, whole));
            }
        }
    }
    out
}

pub struct Tracer {
    pub quads: Vec<Quad>,
    /// Per emitting document surface: its patches and their cumulative shares of its area.
    pub emitters: Vec<(Vec<usize>, Vec<f64>)>,
    /// Per patch, the emitting area of its document surface (0 for one that does not emit):
    /// a light point's density over that area is its inverse.
    emitting_area: Vec<f64>,
    /// A length far below any feature of the scene, to step off surfaces.
    pub eps: f64,
    boxes: Vec<Patch>,
    tree: Bvh<f64, 3>,
}

/// A patch's box in the `bvh` crate's tree.
struct Patch {
    index: usize,
    bounds: Aabb<f64, 3>,
    node: usize,
}

impl Bounded<f64, 3> for Patch {
    fn aabb(&self) -> Aabb<f64, 3> {
        self.bounds
    }
}

impl BHShape<f64, 3> for Patch {
    fn set_bh_node_index(&mut self, index: usize) {
        self.node = index;
    }
    fn bh_node_index(&self) -> usize {
        self.node
    }
}

impl Tracer {
    pub fn new(doc: &Value) -> Tracer {
        let quads = quads(doc);
        let mut emitters: Vec<(Vec<usize>, Vec<f64>)> = Vec::new();
        let mut last_owner = usize::MAX;
        for (i, q) in quads.iter().enumerate() {
            if !q.emission.iter().any(|&e| e > 0.0) {
                continue;
            }
            if q.owner != last_owner {
                emitters.push((Vec::new(), Vec::new()));
                last_owner = q.owner;
            }
            emitters.last_mut().unwrap().0.push(i);
        }
        let mut emitting_area = vec![0.0; quads.len()];
        for (patches, cumulative) in &mut emitters {
            let total: f64 = patches.iter().map(|&i| quads[i].emitting_area()).sum();
            let mut acc = 0.0;
            for &i in patches.iter() {
                emitting_area[i] = total;
                acc += quads[i].emitting_area() / total;
                cumulative.push(acc);
            }
        }
        let size = quads
            .iter()
            .map(|q| dot(q.e1, q.e1).max(dot(q.e2, q.e2)).sqrt())
            .fold(0.0, f64::max);
        let eps = 1e-9 * size;
        let mut boxes: Vec<Patch> = quads
            .iter()
            .enumerate()
            .map(|(index, q)| {
                let far = if q.tri {
                    q.p0
                } else {
                    add(q.p0, add(q.e1, q.e2))
                };
                let corners = [q.p0, add(q.p0, q.e1), add(q.p0, q.e2), far];
                let lo = [0, 1, 2].map(|k| corners.iter().map(|c| c[k]).fold(f64::MAX, f64::min));
                let hi = [0, 1, 2].map(|k| corners.iter().map(|c| c[k]).fold(f64::MIN, f64::max));
                // a flat patch's box has no depth along its normal: widen it a little so that
                // no ray slips past a box of zero thickness
                let pad = 1e3 * eps;
                Patch {
                    index,
                    bounds: Aabb::with_bounds(
                        Point3::new(lo[0] - pad, lo[1] - pad, lo[2] - pad),
                        Point3::new(hi[0] + pad, hi[1] + pad, hi[2] + pad),
                    ),
                    node: 0,
                }
            })
            .collect();
        let tree = Bvh::build(&mut boxes);
        Tracer {
            quads,
            emitters,
            emitting_area,
            eps,
            boxes,
            tree,
        }
    }

    /// The nearest surface the ray from `o` along the unit `dir` meets, other than `skip`.
    pub fn nearest(&self, o: V3, dir: V3, skip: usize) -> Option<(usize, f64)> {
        let ray = Ray::new(Point3::from(o), Vector3::from(dir));
        let mut best: Option<(usize, f64)> = None;
        // the boxes come nearest entry first: once one is entered beyond the best hit, no
        // later one can hold a nearer hit
        for p in self.tree.nearest_traverse_iterator(&ray, &self.boxes) {
            if let (Some((_, b)), Some((enter, _))) =
                (best, ray.intersection_slice_for_aabb(&p.bounds))
            {
                if enter > b {
                    break;
                }
            }
            let i = p.index;
            if i == skip {
                continue;
            }
            if let Some(h) = self.quads[i].hit(o, dir) {
                if h > self.eps && best.is_none_or(|(_, b)| h < b) {
                    best = Some((i, h));
                }
            }
        }
        best
    }

    /// [`Tracer::nearest`] by testing every patch: the tree's check.
    pub fn nearest_by_brute_force(&self, o: V3, dir: V3, skip: usize) -> Option<(usize, f64)> {
        let mut best: Option<(usize, f64)> = None;
        for (i, q) in self.quads.iter().enumerate() {
            if i == skip {
                continue;
            }
            if let Some(h) = q.hit(o, dir) {
                if h > self.eps && best.is_none_or(|(_, b)| h < b) {
                    best = Some((i, h));
                }
            }
        }
        best
    }

    /// Whether anything but surfaces `a` and `b` lies strictly between x and y.
    pub fn blocked(&self, x: V3, y: V3, a: usize, b: usize) -> bool {
        let d = sub(y, x);
        let len = dot(d, d).sqrt();
        let dir = scale(d, 1.0 / len);
        let ray = Ray::new(Point3::from(x), Vector3::from(dir));
        self.tree.traverse_iterator(&ray, &self.boxes).any(|p| {
            let i = p.index;
            i != a
                && i != b
                && self.quads[i]
                    .hit(x, dir)
                    .is_some_and(|h| h > self.eps && h < len - self.eps)
        })
    }

    /// Irradiance / π from every emitting surface at x on patch `on`: one light point each,
    /// on one of its patches drawn by area (a parallelogram's only patch draws no number).
    pub fn direct(&self, x: V3, on: usize, rng: &mut SmallRng) -> V3 {
        let n = self.quads[on].n;
        let mut sum = [0.0; 3];
        for (patches, cumulative) in &self.emitters {
            let l = if patches.len() == 1 {
                patches[0]
            } else {
                let u = rng.random::<f64>();
                patches[cumulative
                    .partition_point(|&c| c < u)
                    .min(patches.len() - 1)]
            };
            if l == on {
                continue;
            }
            let q = &self.quads[l];
            let (rs, rt) = q.region;
            let s = rs[0] + (rs[1] - rs[0]) * rng.random::<f64>();
            let t = rt[0] + (rt[1] - rt[0]) * rng.random::<f64>();
            // a triangle: the square folded onto it along its diagonal
            let (s, t) = if q.tri && s + t > 1.0 {
                (1.0 - s, 1.0 - t)
            } else {
                (s, t)
            };
            let y = q.at(s, t);
            let d = sub(y, x);
            let r2 = dot(d, d);
            let cx = dot(d, n);
            let cy = -dot(d, q.n);
            if cx <= 0.0 || cy <= 0.0 || self.blocked(x, y, on, l) {
                continue;
            }
            // a patch drawn by its share of the surface's emitting area, then a point on it
            // uniformly: the point's density over that area is one over all of it
            let area = self.emitting_area[l];
            let g = cx * cy / (std::f64::consts::PI * r2 * r2) * area;
            // the densities, per solid angle at x, of this light point and of the cosine
            // direction toward it
            let r = r2.sqrt();
            let light = r2 * r / (cy * area);
            let cosine = cx / (r * std::f64::consts::PI);
            sum = add(sum, scale(q.emission, g * power_heuristic(light, cosine)));
        }
        sum
    }

    /// One sample of ∫ B(y) cos θ / π dω at x on patch `on` for a given radiosity `b(patch, s,
    /// t)` instead of a path: the emitters' E by a light point each ([`Tracer::direct`]) and by
    /// one cosine-distributed direction, weighted against each other, and the rest of B where
    /// that direction meets a front face. Returns the light points' part and, when the
    /// direction meets a front face, that patch and what it adds; `None` when it meets the back
    /// of a surface (x is inside a solid: a covered point, which receives nothing).
    pub fn one_bounce(
        &self,
        x: V3,
        on: usize,
        rng: &mut SmallRng,
        b: &dyn Fn(usize, f64, f64) -> V3,
    ) -> Option<(V3, Option<(usize, V3)>)> {
        let direct = self.direct(x, on, rng);
        let n = self.quads[on].n;
        let dir = cosine_direction(n, rng.random(), rng.random());
        let Some((hit, h)) = self.nearest(x, dir, on) else {
            return Some((direct, None));
        };
        let q = &self.quads[hit];
        if dot(dir, q.n) >= 0.0 {
            return None;
        }
        let (_, s, t) = q.hit_at(x, dir).expect("the nearest patch is met");
        let mut v = b(hit, s, t);
        if self.emitting_area[hit] > 0.0 && q.emits(s, t) {
            // B holds E, which the light points count too: the direction keeps its share
            let cy = -dot(dir, q.n);
            let light = h * h / (cy * self.emitting_area[hit]);
            let cosine = dot(dir, n) / std::f64::consts::PI;
            let w = power_heuristic(cosine, light) - 1.0;
            v = add(v, scale(q.emission, w));
        }
        Some((direct, Some((hit, v))))
    }

    /// ∫ B(y) cos/(π r²) V dA_y at x on `on`, without the emitters' own E (counted by `direct`).
    pub fn gathered(&self, x: V3, on: usize, rng: &mut SmallRng) -> V3 {
        let mut total = self.direct(x, on, rng);
        // one cosine-distributed direction: its estimator of ∫ B cosθx/π dω is B(y) itself
        let n = self.quads[on].n;
        let dir = cosine_direction(n, rng.random(), rng.random());
        if let Some((hit, h)) = self.nearest(x, dir, on) {
            let q = &self.quads[hit];
            if dot(dir, q.n) < 0.0 && self.emitting_area[hit] > 0.0 {
                // the light this direction meets, weighted against the light points
                let (_, s, t) = q.hit_at(x, dir).expect("the nearest patch is met");
                if q.emits(s, t) {
                    let cy = -dot(dir, q.n);
                    let light = h * h / (cy * self.emitting_area[hit]);
                    let cosine = dot(dir, n) / std::f64::consts::PI;
                    // the direction's estimate of ∫ E cosθx/π dω is E itself
                    total = add(total, scale(q.emission, power_heuristic(cosine, light)));
                }
            }
            if dot(dir, q.n) < 0.0 {
                let keep = q.rho.iter().copied().fold(0.0, f64::max);
                if keep > 0.0 && rng.random::<f64>() < keep {
                    let y = add(x, scale(dir, h));
                    let more = self.gathered(y, hit, rng);
                    total = add(total, scale(mul(q.rho, more), 1.0 / keep));
                }
            }
        }
        total
    }

    /// The mean of B over each document surface from `samples` stratified points (by area
    /// over its patches), with its standard error.
    pub fn surface_means(&self, samples: usize, seed: u64) -> Vec<(V3, V3)> {
        let surfaces = self.quads.iter().map(|q| q.owner + 1).max().unwrap_or(0);
        (0..surfaces)
            .map(|owner| {
                let patches: Vec<usize> = (0..self.quads.len())
                    .filter(|&i| self.quads[i].owner == owner)
                    .collect();
                let total: f64 = patches.iter().map(|&i| self.quads[i].area).sum();
                let mut cumulative = Vec::new();
                let mut acc = 0.0;
                for &i in &patches {
                    acc += self.quads[i].area / total;
                    cumulative.push(acc);
                }
                let values: Vec<V3> = (0..samples)
                    .into_par_iter()
                    .map(|k| {
                        let mut rng =
                            SmallRng::seed_from_u64(seed ^ ((owner as u64) << 40) ^ k as u64);
                        let u = (k as f64 + rng.random::<f64>()) / samples as f64;
                        let at = cumulative
                            .partition_point(|&c| c < u)
                            .min(patches.len() - 1);
                        let on = patches[at];
                        let q = &self.quads[on];
                        let (mut s, mut t) = (rng.random::<f64>(), rng.random::<f64>());
                        if q.tri && s + t > 1.0 {
                            (s, t) = (1.0 - s, 1.0 - t);
                        }
                        let x = q.at(s, t);
                        let e = if q.emits(s, t) { q.emission } else { [0.0; 3] };
                        add(e, mul(q.rho, self.gathered(x, on, &mut rng)))
                    })
                    .collect();
                let m = samples as f64;
                let mean = scale(values.iter().fold([0.0; 3], |a, v| add(a, *v)), 1.0 / m);
                let err = [0, 1, 2].map(|c| {
                    let var =
                        values.iter().map(|v| (v[c] - mean[c]).powi(2)).sum::<f64>() / (m - 1.0);
                    (var / m).sqrt()
                });
                (mean, err)
            })
            .collect()
    }

    /// Cell means of B on every document surface, as a result lists them: a parallelogram's
    /// `grid × grid` (rows by t then s), a triangle's or a mesh's one per triangle; each from
    /// `per_side²` stratified samples, with its standard error.
    pub fn cells(&self, grid: usize, per_side: usize, seed: u64) -> Vec<Vec<(V3, V3)>> {
        self.surfaces()
            .into_iter()
            .map(|patches| {
                let tri = self.quads[patches[0]].tri;
                let cells: Vec<(usize, usize)> = if tri {
                    patches.iter().map(|&on| (on, 0)).collect()
                } else {
                    (0..grid * grid).map(|cell| (patches[0], cell)).collect()
                };
                let grid = if tri { 1 } else { grid };
                cells
                    .into_par_iter()
                    .map(|(on, cell)| {
                        let (ci, cj) = (cell % grid, cell / grid);
                        let mut rng = SmallRng::seed_from_u64(
                            seed ^ ((on as u64) << 40) ^ ((cell as u64) << 8),
                        );
                        let q = &self.quads[on];
                        let (mut sum, mut sq) = ([0.0; 3], [0.0; 3]);
                        for k in 0..per_side * per_side {
                            let mut s = (ci as f64
                                + ((k % per_side) as f64 + rng.random::<f64>()) / per_side as f64)
                                / grid as f64;
                            let mut t = (cj as f64
                                + ((k / per_side) as f64 + rng.random::<f64>()) / per_side as f64)
                                / grid as f64;
                            // a triangle's points: the square's, folded onto s + t ≤ 1
                            if q.tri && s + t > 1.0 {
                                (s, t) = (1.0 - s, 1.0 - t);
                            }
                            let x = q.at(s, t);
                            let e = if q.emits(s, t) { q.emission } else { [0.0; 3] };
                            let b = add(e, mul(q.rho, self.gathered(x, on, &mut rng)));
                            sum = add(sum, b);
                            sq = add(sq, mul(b, b));
                        }
                        let m = (per_side * per_side) as f64;
                        let mean = scale(sum, 1.0 / m);
                        let err = [0, 1, 2]
                            .map(|c| ((sq[c] / m - mean[c] * mean[c]).max(0.0) / (m - 1.0)).sqrt());
                        (mean, err)
                    })
                    .collect()
            })
            .collect()
    }

    /// The patches of each document surface, in the document's order.
    pub fn surfaces(&self) -> Vec<Vec<usize>> {
        let count = self.quads.iter().map(|q| q.owner + 1).max().unwrap_or(0);
        let mut out = vec![Vec::new(); count];
        for (i, q) in self.quads.iter().enumerate() {
            out[q.owner].push(i);
        }
        out
    }

    /// Per document surface: whether it emits, and the weights of its [`Tracer::cells`] in
    /// its mean (equal on a parallelogram's grid, the triangles' areas on a mesh).
    fn cell_weights(&self, reference: &[Vec<(V3, V3)>]) -> Vec<(bool, Vec<f64>)> {
        self.surfaces()
            .into_iter()
            .zip(reference)
            .map(|(patches, cells)| {
                let emits = patches
                    .iter()
                    .any(|&i| self.quads[i].emission.iter().any(|&e| e > 0.0));
                let q = &self.quads[patches[0]];
                let weights = if q.tri {
                    let total: f64 = patches.iter().map(|&i| self.quads[i].area).sum();
                    patches
                        .iter()
                        .map(|&i| self.quads[i].area / total)
                        .collect()
                } else {
                    vec![1.0 / cells.len() as f64; cells.len()]
                };
                (emits, weights)
            })
            .collect()
    }
}

/// A direction about the unit normal `n` with density cos θ / π, from two uniform numbers.
pub fn cosine_direction(n: V3, u1: f64, u2: f64) -> V3 {
    let (r, phi) = (u1.sqrt(), 2.0 * std::f64::consts::PI * u2);
    let a = if n[0].abs() > 0.5 {
        [0.0, 1.0, 0.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    let b1 = cross(n, a);
    let b1 = scale(b1, 1.0 / dot(b1, b1).sqrt());
    let b2 = cross(n, b1);
    add(
        add(scale(b1, r * phi.cos()), scale(b2, r * phi.sin())),
        scale(n, (1.0 - u1).sqrt()),
    )
}

/// The power heuristic's weight (β = 2) of a sample drawn with density `a` against another
/// strategy's density `b` at the same point.
fn power_heuristic(a: f64, b: f64) -> f64 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 == 0.0 {
        0.0
    } else {
        a2 / (a2 + b2)
    }
}

/// The mean of cells with `weights`, and its standard error, in channel `c`.
fn weighted(cells: &[(V3, V3)], weights: &[f64], c: usize) -> (f64, f64) {
    let mean = cells.iter().zip(weights).map(|((v, _), w)| w * v[c]).sum();
    let var: f64 = cells
        .iter()
        .zip(weights)
        .map(|((_, e), w)| (w * e[c]).powi(2))
        .sum();
    (mean, var.sqrt())
}

/// A solution against the reference.
/// The largest gaps of a solution against the reference, beyond `z` of its standard errors:
/// per surface mean and per cell, relative to the reference, over the non-emitting surfaces
/// and the channels; with the name of the surface where each is found.
pub struct Gaps {
    pub surface: (f64, String),
    pub cell: (f64, String),
}

impl Tracer {
    /// [`Gaps`] of `surfaces` (a result's) against `reference` (cell means of
    /// [`reference`]), printing each surface's first channel.
    pub fn gaps(
        &self,
        surfaces: &[wavrad::result::SurfaceResult],
        reference: &[Vec<(V3, V3)>],
        z: f64,
    ) -> Gaps {
        let mut g = Gaps {
            surface: (0.0, String::new()),
            cell: (0.0, String::new()),
        };
        let worst = |slot: &mut (f64, String), gap: f64, name: &str| {
            if gap > slot.0 {
                *slot = (gap, name.to_string());
            }
        };
        let weights = self.cell_weights(reference);
        for ((s, cells), (emits, w)) in surfaces.iter().zip(reference).zip(&weights) {
            if *emits {
                continue;
            }
            for c in 0..3 {
                let (mean, err) = weighted(cells, w, c);
                let beyond = ((s.mean[c] - mean).abs() - z * err).max(0.0) / mean;
                if c == 0 {
                    eprintln!(
                        "  {:14} {:+.2} % ± {:.2} %",
                        s.name,
                        100.0 * (s.mean[c] / mean - 1.0),
                        100.0 * err / mean
                    );
                }
                worst(&mut g.surface, beyond, &s.name);
                for (got, (v, e)) in s.cells.iter().zip(cells) {
                    let beyond = ((got[c] - v[c]).abs() - z * e[c]).max(0.0) / v[c];
                    worst(&mut g.cell, beyond, &s.name);
                }
            }
        }
        g
    }
}

pub struct Comparison {
    /// Per surface (not emitting): name, the largest |solver / reference − 1| over the
    /// channels, and that channel's relative standard error of the reference.
    pub surfaces: Vec<(String, f64, f64)>,
    /// Relative L2 gap of all cell means of the surfaces that do not emit.
    pub cells: f64,
    /// The same for the reference's own sampling error.
    pub cells_noise: f64,
}

impl Comparison {
    /// The relative L2 gap of the cell means without the reference's own noise.
    pub fn net(&self) -> f64 {
        (self.cells.powi(2) - self.cells_noise.powi(2))
            .max(0.0)
            .sqrt()
    }
}

/// Cell means of the reference on the document's grid, `per_side²` paths per cell.
pub fn reference(doc: &Value, per_side: usize) -> Vec<Vec<(V3, V3)>> {
    let grid = doc["output"]["grid"].as_u64().unwrap_or(8) as usize;
    Tracer::new(doc).cells(grid, per_side, 0x5eed)
}

pub fn compare(doc: &Value, reference: &[Vec<(V3, V3)>], label: &str) -> Comparison {
    compare_with(doc, reference, label, &job::Rules::DEFAULT)
}

/// [`compare`] of a solve with the 3D refinement's `rules`.
pub fn compare_with(
    doc: &Value,
    reference: &[Vec<(V3, V3)>],
    label: &str,
    rules: &job::Rules,
) -> Comparison {
    let tracer = Tracer::new(doc);
    let j = parse_value(doc, &Limits::default()).expect("valid document");
    let out = job::run_with(&j, rules, &Silent).expect("solves");
    let mut surfaces = Vec::new();
    let (mut gap2, mut noise2, mut norm2) = (0.0, 0.0, 0.0);
    eprintln!("{label}: surface means, solver / path traced − 1 (± 1 standard error)");
    let weights = tracer.cell_weights(reference);
    for ((s, cells), (emits, w)) in out.result.surfaces.iter().zip(reference).zip(&weights) {
        if *emits {
            continue;
        }
        let mut line = format!("  {:12}", s.name);
        let (mut worst, mut noise) = (0.0_f64, 0.0);
        for c in 0..3 {
            let (mean, err) = weighted(cells, w, c);
            let rel = s.mean[c] / mean - 1.0;
            line += &format!(" {:+7.2}% ±{:.2}%", 100.0 * rel, 100.0 * err / mean);
            if rel.abs() > worst {
                (worst, noise) = (rel.abs(), err / mean);
            }
        }
        eprintln!("{line}");
        surfaces.push((s.name.clone(), worst, noise));
        for (got, (want, err)) in s.cells.iter().zip(cells) {
            for c in 0..3 {
                gap2 += (got[c] - want[c]).powi(2);
                noise2 += err[c] * err[c];
                norm2 += want[c] * want[c];
            }
        }
    }
    let cmp = Comparison {
        surfaces,
        cells: (gap2 / norm2).sqrt(),
        cells_noise: (noise2 / norm2).sqrt(),
    };
    eprintln!(
        "  cell means: relative L2 gap {:.2}% (reference noise {:.2}%)",
        100.0 * cmp.cells,
        100.0 * cmp.cells_noise
    );
    cmp
}
