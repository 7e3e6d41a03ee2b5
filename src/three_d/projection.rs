//! The Galerkin matrix of a 3D scene (slides' eq. (3) kernel, eq. (11) matrix): n × n cells
//! on every parallelogram, k² = (m + 1)² tensor Legendre functions per cell, orthonormal in
//! area. Each cell pair is integrated by [`crate::three_d::transfer`] (tensor Gauss rules far apart,
//! adaptive subdivision toward shared edges) and scaled by the fraction of it that is visible
//! ([`crate::three_d::visibility`]: no rays when no surface can come between the two cells).

use crate::math::basis::legendre;
use crate::math::quadrature::Rule;
use crate::methods::projection::{Dense, Discretization, Layout, System};
use crate::progress::{Cancelled, Phase, Progress};
use crate::scene::Quad;
use crate::three_d::bvh::Bvh;
use crate::three_d::congruence::Congruence;
use crate::three_d::cover::Mask;
use crate::three_d::geometry::Piece;
use crate::three_d::geometry::{quad_quad, Parallelogram};
use crate::three_d::steps::Steps;
use crate::three_d::transfer::{self, Accuracy, Integrand};
use crate::three_d::visibility::{self, pair_seed, Seen};
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Rays per side of the stratified visibility grid of a partly occluded cell pair.
pub(super) const VISIBILITY_GRID: usize = 4;

/// The geometry of a 3D scene with the facts about pairs of surfaces that every method needs.
/// Nothing here is a table over pairs of surfaces: a scene of 10⁵ triangles has 10¹⁰ pairs,
/// of which the solver looks at a few per element.
pub struct Geometry {
    pub(super) quads: Vec<Parallelogram>,
    /// The surfaces that may occlude a ray between two others ([`Bvh::occluders`]).
    pub(super) bvh: Bvh,
    /// The thorough hull tests of [`visibility::occluders`] asked so far.
    hulls: visibility::HullMemo,
}

impl Geometry {
    pub(crate) fn new(quads: &[Quad]) -> Geometry {
        let quads: Vec<Parallelogram> = quads.iter().map(Parallelogram::of).collect();
        Geometry {
            bvh: Bvh::occluders(&quads),
            hulls: visibility::HullMemo::new(),
            quads,
        }
    }

    fn len(&self) -> usize {
        self.quads.len()
    }

    /// Whether some point of each of surfaces `i` and `j` is in front of the other.
    pub(super) fn facing(&self, i: usize, j: usize) -> bool {
        let (a, b) = (&self.quads[i], &self.quads[j]);
        i != j && in_front(a, b) && in_front(b, a)
    }

    /// Surface pairs (i < j) whose closed parallelograms meet.
    pub(crate) fn touching(&self) -> Vec<(usize, usize)> {
        let n = self.len();
        let mut out = Vec::new();
        for i in 0..n {
            for j in i + 1..n {
                let (a, b) = (&self.quads[i], &self.quads[j]);
                let ca = a.outline();
                let cb = b.outline();
                if quad_quad(&ca, a.n, &cb, b.n) <= 1e-9 * a.diameter().max(b.diameter()) {
                    out.push((i, j));
                }
            }
        }
        out
    }

    /// The visible fraction of the pair of pieces, 1 without rays when nothing can come
    /// between them; rays cast are added to `rays`.
    pub(super) fn visibility(
        &self,
        a: Piece,
        b: Piece,
        seed: u64,
        grid: usize,
        rays: &mut u64,
    ) -> Seen {
        self.visibility_over(a, None, b, seed, grid, rays)
    }

    /// What may come between pieces `a` and `b`, for their rays ([`visibility::occluders`]):
    /// nothing when no surface of the occluders' tree that may meet the hull of the two pieces
    /// (by its box) meets it by the quick test and that of their whole surfaces by the
    /// thorough one, else those surfaces when they are few, or the whole tree.
    pub(super) fn occluders(&self, a: Piece, b: Piece) -> visibility::Occluders<'_> {
        visibility::occluders(&self.bvh, &self.hulls, a, b)
    }

    /// Whether something that may come between pieces `a` and `b` lies within `reach` of `a`
    /// ([`visibility::occluder_near`]).
    pub(super) fn occluder_near(&self, a: Piece, b: Piece, reach: f64) -> bool {
        visibility::occluder_near(&self.bvh, a, b, reach)
    }

    /// [`Geometry::visibility`] over the exposed part of `a` only, where `covered` marks a
    /// covered part of its surface ([`crate::three_d::cover`]).
    fn visibility_over(
        &self,
        a: Piece,
        covered: Option<&Mask>,
        b: Piece,
        seed: u64,
        grid: usize,
        rays: &mut u64,
    ) -> Seen {
        let occluders = self.occluders(a, b);
        if occluders.clear() {
            return Seen::CLEAR;
        }
        visibility::visible_fraction_over(&occluders, a, covered, b, grid, seed, rays)
    }
}

/// Whether some corner of `b` is strictly in front of `a`.
fn in_front(a: &Parallelogram, b: &Parallelogram) -> bool {
    let tol = 1e-12 * (a.diameter() + b.diameter());
    b.outline().iter().any(|&c| a.side(c) > tol)
}

/// The accuracy of the projection method's cell pairs at `q` Gauss points per direction.
fn accuracy(q: usize) -> Accuracy {
    Accuracy {
        q_min: q,
        digits: 6.0,
        outer_depth: 10,
        inner_depth: 2,
    }
}

fn cell(c: usize, n: usize) -> [f64; 2] {
    let h = 1.0 / n as f64;
    [c as f64 * h, (c + 1) as f64 * h]
}

/// Builds the 3D system.
pub fn build(
    quads: &[Quad],
    disc: Discretization,
    progress: &dyn Progress,
) -> Result<System, Cancelled> {
    let geo = Geometry::new(quads);
    let (matrix, _rays, evaluations) = matrix(&geo, disc, accuracy(disc.quadrature), progress)?;
    let k = disc.order + 1;
    let layout = Layout::Square {
        cells: disc.cells,
        k,
    };
    let mut emission = Vec::with_capacity(quads.len() * layout.len());
    for (q, p) in quads.iter().zip(&geo.quads) {
        emission.extend(emission_coefficients(q, p.area, disc));
    }
    Ok(System {
        layout,
        surfaces: quads.len(),
        matrix,
        emission,
        reflectance: quads.iter().map(|q| q.material.reflectance).collect(),
        measure: geo.quads.iter().map(|q| q.area).collect(),
        touching: geo.touching(),
        kernel_evaluations: Some(evaluations),
    })
}

/// E_{cell,(q,p)} = E √A / h ∫∫_{cell ∩ region} φ_p(ŝ) φ_q(t̂) ds dt, exactly.
fn emission_coefficients(q: &Quad, area: f64, disc: Discretization) -> Vec<[f64; 3]> {
    let k = disc.order + 1;
    let n = disc.cells;
    let mut out = vec![[0.0; 3]; n * n * k * k];
    for ct in 0..n {
        for cs in 0..n {
            let piece = Piece {
                upper: false,
                surface: 0,
                s: cell(cs, n),
                t: cell(ct, n),
            };
            let at = (ct * n + cs) * k * k;
            piece_emission(q, area, piece, k, &mut out[at..at + k * k]);
        }
    }
    out
}

/// E ∫_{piece ∩ region} N_(q,p) dA for N orthonormal in the piece's area, exactly.
pub(super) fn piece_emission(q: &Quad, area: f64, piece: Piece, k: usize, out: &mut [[f64; 3]]) {
    if q.triangle {
        // E is constant on a triangle (no emission region): ∫ E N_0 dA = E √A_piece, and the
        // other functions are orthogonal to the constant
        let a = area * (piece.s[1] - piece.s[0]) * (piece.t[1] - piece.t[0]);
        out[0] = q.material.emission.map(|e| e * a.sqrt());
        return;
    }
    let (rs, rt) = q.emission_region;
    let s = [piece.s[0].max(rs[0]), piece.s[1].min(rs[1])];
    let t = [piece.t[0].max(rt[0]), piece.t[1].min(rt[1])];
    if s[1] <= s[0] || t[1] <= t[0] || q.material.emission == [0.0; 3] {
        return;
    }
    let (hs, ht) = (piece.s[1] - piece.s[0], piece.t[1] - piece.t[0]);
    let norm = area / (area * hs * ht).sqrt();
    let rule = Rule::for_degree(k);
    let mut ps = vec![0.0; k];
    let mut pt = vec![0.0; k];
    for (y, wy) in rule.mapped(t[0], t[1]) {
        legendre((y - piece.t[0]) / ht, &mut pt);
        for (x, wx) in rule.mapped(s[0], s[1]) {
            legendre((x - piece.s[0]) / hs, &mut ps);
            for a in 0..k {
                for b in 0..k {
                    let v = wx * wy * pt[a] * ps[b] * norm;
                    for (o, e) in out[a * k + b].iter_mut().zip(q.material.emission) {
                        *o += v * e;
                    }
                }
            }
        }
    }
}

/// The ρ-free Galerkin matrix, rows of cells in parallel; also the visibility rays cast and
/// the kernel evaluations.
fn matrix(
    geo: &Geometry,
    disc: Discretization,
    acc: Accuracy,
    progress: &dyn Progress,
) -> Result<(Dense, u64, u64), Cancelled> {
    let k = disc.order + 1;
    let kk = k * k;
    let n = disc.cells;
    let per = n * n * kk;
    let size = geo.len() * per;
    let mut m = Dense::zeros(size);
    let done = AtomicUsize::new(0);
    let blocks = geo.len() * n * n;
    let steps = Steps::new(k);
    progress.report(Phase::Projection, 0.0);
    let counts: Vec<(u64, u64)> = m
        .data
        .par_chunks_mut(kk * size)
        .enumerate()
        .map(|(row_block, rows)| {
            progress.check()?;
            let (i, a) = (row_block / (n * n), row_block % (n * n));
            let pa = Piece {
                upper: false,
                surface: i,
                s: cell(a % n, n),
                t: cell(a / n, n),
            };
            let mut block = vec![0.0; kk * kk];
            let (mut rays, mut evaluations) = (0u64, 0u64);
            for j in 0..geo.len() {
                if i == j || !geo.facing(i, j) {
                    continue;
                }
                for b in 0..n * n {
                    let pb = Piece {
                        upper: false,
                        surface: j,
                        s: cell(b % n, n),
                        t: cell(b / n, n),
                    };
                    let seed = pair_seed((i * n * n + a) as u64, (j * n * n + b) as u64);
                    let v = geo.visibility(pa, pb, seed, VISIBILITY_GRID, &mut rays);
                    if v.whole == 0.0 {
                        continue;
                    }
                    block.fill(0.0);
                    evaluations += transfer::block(
                        &geo.quads,
                        pa,
                        pb,
                        Integrand::Galerkin { k },
                        acc,
                        &mut block,
                    );
                    v.weigh(&steps, &mut block);
                    for r in 0..kk {
                        let dst = &mut rows
                            [r * size + j * per + b * kk..r * size + j * per + (b + 1) * kk];
                        for (d, s) in dst.iter_mut().zip(&block[r * kk..(r + 1) * kk]) {
                            *d = *s;
                        }
                    }
                }
            }
            let d = done.fetch_add(1, Ordering::Relaxed) + 1;
            if d.is_multiple_of(16) || d == blocks {
                progress.report(Phase::Projection, d as f64 / blocks as f64);
            }
            Ok::<(u64, u64), Cancelled>((rays, evaluations))
        })
        .collect::<Result<_, _>>()?;
    Ok((
        m,
        counts.iter().map(|c| c.0).sum(),
        counts.iter().map(|c| c.1).sum(),
    ))
}

/// ∫_i ∫_j K² V dy dx for every ordered pair of surfaces (row-major `S × S`) on `cells × cells`
/// order-0 pieces: the denominator of eq. (5). Pairs that touch diverge: `skip` them.
///
/// K is symmetric and so is V, so each unordered pair is integrated once and entered twice;
/// congruent pairs of pieces ([`crate::three_d::congruence`]: most of them on parallel or perpendicular
/// walls) share one integral of K², and only the visible fraction is per pair.
pub(crate) fn kernel_squares(
    geo: &Geometry,
    cells: usize,
    q: usize,
    skip: impl Fn(usize, usize) -> bool + Sync,
    progress: &dyn Progress,
) -> Result<Vec<f64>, Cancelled> {
    let s = geo.len();
    let acc = accuracy(q);
    let unit = geo.quads.iter().map(|q| q.diameter()).fold(0.0, f64::max) * (-32f64).exp2();
    let upper: Vec<f64> = (0..s * s)
        .into_par_iter()
        .map(|ij| {
            let (i, j) = (ij / s, ij % s);
            if i >= j || skip(i, j) || !geo.facing(i, j) {
                return Ok(0.0);
            }
            let mut squares = rustc_hash::FxHashMap::default();
            let mut sum = 0.0;
            let mut rays = 0;
            for a in 0..cells * cells {
                progress.check()?;
                let pa = Piece {
                    upper: false,
                    surface: i,
                    s: cell(a % cells, cells),
                    t: cell(a / cells, cells),
                };
                for b in 0..cells * cells {
                    let pb = Piece {
                        upper: false,
                        surface: j,
                        s: cell(b % cells, cells),
                        t: cell(b / cells, cells),
                    };
                    let seed = pair_seed(
                        (i * cells * cells + a) as u64,
                        (j * cells * cells + b) as u64,
                    );
                    let v = geo.visibility(pa, pb, seed, VISIBILITY_GRID, &mut rays);
                    if v.whole > 0.0 {
                        let k2 = squares
                            .entry(Congruence::of(&geo.quads, pa, pb, unit, false).key)
                            .or_insert_with(|| {
                                let mut out = [0.0];
                                transfer::block(
                                    &geo.quads,
                                    pa,
                                    pb,
                                    Integrand::Squared,
                                    acc,
                                    &mut out,
                                );
                                out[0]
                            });
                        sum += v.whole * *k2;
                    }
                }
            }
            Ok(sum)
        })
        .collect::<Result<_, _>>()?;
    Ok((0..s * s)
        .map(|ij| {
            let (i, j) = (ij / s, ij % s);
            upper[i.min(j) * s + i.max(j)]
        })
        .collect())
}
