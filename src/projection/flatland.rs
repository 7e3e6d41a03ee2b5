//! The Galerkin matrix of flatland (slides' eq. (4) kernel, eq. (11) matrix).
//!
//! Cell pairs are integrated by tensor Gauss rules whose order grows as the cells come closer
//! ([`super::points_for_separation`]); pairs closer than their size are bisected recursively,
//! which integrates the 1/r singularity of touching segments (room corners) to full precision.
//! Pairs that a third segment may occlude are integrated with exact visibility: the outer
//! interval is split where the shadow topology changes, and the inner integral is taken over
//! the visible pieces only ([`crate::visibility`]).

use super::{points_for_separation, Dense, Discretization, Layout, System};
use crate::basis::legendre;
use crate::geometry::{segment_distance, Line, V2};
use crate::kernel;
use crate::progress::{Cancelled, Phase, Progress};
use crate::quadrature::Rule;
use crate::scene::Segment;
use crate::visibility::{may_block, visible_from, Pieces};
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Deepest bisection of a near-singular pair: 2⁻⁴⁰ of a cell.
const MAX_DEPTH: u32 = 40;
/// Largest order k = m + 1 and Gauss rule handled on the stack.
const MAX_K: usize = 16;
const MAX_Q: usize = 24;

/// What is known of a pair of surfaces before any cell is integrated.
#[derive(Debug, Clone, Default)]
pub struct PairInfo {
    /// Parameters of surface i in front of surface j, and of j in front of i.
    pub front_i: Option<[f64; 2]>,
    pub front_j: Option<[f64; 2]>,
    /// Surfaces that may block some ray between the two.
    pub occluders: Vec<usize>,
}

/// The geometry of a flatland scene, with the pairwise facts the integrators need.
pub struct Geometry {
    pub lines: Vec<Line>,
    pub pairs: Vec<PairInfo>,
}

impl Geometry {
    pub fn new(segments: &[Segment]) -> Geometry {
        let lines: Vec<Line> = segments
            .iter()
            .map(|s| Line::new(s.a.into(), s.b.into()))
            .collect();
        let n = lines.len();
        let mut pairs = vec![PairInfo::default(); n * n];
        for i in 0..n {
            for j in 0..n {
                if i == j {
                    continue;
                }
                let (li, lj) = (&lines[i], &lines[j]);
                let front_i = front_range(li, lj);
                let front_j = front_range(lj, li);
                let mut occluders = Vec::new();
                if let (Some(fi), Some(fj)) = (front_i, front_j) {
                    let p = [li.at(fi[0]), li.at(fi[1])];
                    let q = [lj.at(fj[0]), lj.at(fj[1])];
                    for (k, lk) in lines.iter().enumerate() {
                        if k != i && k != j && may_block(p, q, [lk.a, lk.b]) {
                            occluders.push(k);
                        }
                    }
                }
                pairs[i * n + j] = PairInfo {
                    front_i,
                    front_j,
                    occluders,
                };
            }
        }
        Geometry { lines, pairs }
    }

    pub fn pair(&self, i: usize, j: usize) -> &PairInfo {
        &self.pairs[i * self.lines.len() + j]
    }

    /// Surface pairs (i < j) whose closed segments meet.
    pub fn touching(&self) -> Vec<(usize, usize)> {
        let n = self.lines.len();
        let mut out = Vec::new();
        for i in 0..n {
            for j in i + 1..n {
                let (a, b) = (&self.lines[i], &self.lines[j]);
                let scale = a.len.max(b.len);
                if segment_distance(a.a, a.b, b.a, b.b) <= 1e-9 * scale {
                    out.push((i, j));
                }
            }
        }
        out
    }
}

/// Parameters s of `a` whose points are strictly in front of `b`, as one interval.
fn front_range(a: &Line, b: &Line) -> Option<[f64; 2]> {
    let f0 = b.side(a.a);
    let f1 = b.side(a.b);
    let tol = 1e-12 * (a.len + b.len);
    match (f0 > tol, f1 > tol) {
        (true, true) => Some([0.0, 1.0]),
        (false, false) => None,
        (true, false) => Some([0.0, f0 / (f0 - f1)]),
        (false, true) => Some([f0 / (f0 - f1), 1.0]),
    }
}

fn intersect(a: [f64; 2], b: [f64; 2]) -> Option<[f64; 2]> {
    let lo = a[0].max(b[0]);
    let hi = a[1].min(b[1]);
    (hi > lo).then_some([lo, hi])
}

/// Builds the flatland system.
pub fn build(
    segments: &[Segment],
    disc: Discretization,
    progress: &dyn Progress,
) -> Result<System, Cancelled> {
    let geo = Geometry::new(segments);
    let matrix = matrix(&geo, disc, progress)?;
    let k = disc.order + 1;
    let layout = Layout::Line {
        cells: disc.cells,
        k,
    };
    let mut emission = Vec::with_capacity(segments.len() * layout.len());
    for (s, line) in segments.iter().zip(&geo.lines) {
        emission.extend(emission_coefficients(s, line.len, disc));
    }
    Ok(System {
        layout,
        surfaces: segments.len(),
        matrix,
        emission,
        reflectance: segments.iter().map(|s| s.material.reflectance).collect(),
        measure: geo.lines.iter().map(|l| l.len).collect(),
        touching: geo.touching(),
    })
}

/// E_{cell,p} = E √(L/h) ∫_{cell ∩ region} φ_p(ŝ) ds, exactly.
fn emission_coefficients(s: &Segment, len: f64, disc: Discretization) -> Vec<[f64; 3]> {
    let k = disc.order + 1;
    let h = 1.0 / disc.cells as f64;
    let rule = Rule::for_degree(disc.order);
    let mut out = vec![[0.0; 3]; disc.cells * k];
    let mut phi = vec![0.0; k];
    for c in 0..disc.cells {
        let cell = [c as f64 * h, (c + 1) as f64 * h];
        let Some(part) = intersect(cell, s.emission_region) else {
            continue;
        };
        for (x, w) in rule.mapped(part[0], part[1]) {
            legendre((x - cell[0]) / h, &mut phi);
            for p in 0..k {
                let v = w * phi[p] * (len / h).sqrt();
                for ch in 0..3 {
                    out[c * k + p][ch] += v * s.material.emission[ch];
                }
            }
        }
    }
    out
}

/// The ρ-free Galerkin matrix, rows in parallel.
pub fn matrix(
    geo: &Geometry,
    disc: Discretization,
    progress: &dyn Progress,
) -> Result<Dense, Cancelled> {
    let k = disc.order + 1;
    assert!(k <= MAX_K, "order {} above {}", disc.order, MAX_K - 1);
    let per = disc.cells * k;
    let n = geo.lines.len() * per;
    let mut m = Dense::zeros(n);
    let done = AtomicUsize::new(0);
    let blocks = geo.lines.len() * disc.cells;
    progress.report(Phase::Projection, 0.0);
    m.data
        .par_chunks_mut(k * n)
        .enumerate()
        .try_for_each(|(row_block, rows)| {
            progress.check()?;
            let (i, a) = (row_block / disc.cells, row_block % disc.cells);
            let mut block = [0.0; MAX_K * MAX_K];
            for j in 0..geo.lines.len() {
                if i == j {
                    continue;
                }
                let pair = geo.pair(i, j);
                let (Some(fi), Some(fj)) = (pair.front_i, pair.front_j) else {
                    continue;
                };
                for b in 0..disc.cells {
                    block[..k * k].fill(0.0);
                    let ctx = CellPair::new(geo, disc, i, a, j, b, pair);
                    ctx.integrate(fi, fj, &mut block[..k * k]);
                    for p in 0..k {
                        let dst = &mut rows[p * n + j * per + b * k..p * n + j * per + b * k + k];
                        dst.copy_from_slice(&block[p * k..p * k + k]);
                    }
                }
            }
            let d = done.fetch_add(1, Ordering::Relaxed) + 1;
            if d % 16 == 0 || d == blocks {
                progress.report(Phase::Projection, d as f64 / blocks as f64);
            }
            Ok::<(), Cancelled>(())
        })?;
    Ok(m)
}

/// One pair of cells: cell a of surface i (rows) and cell b of surface j (columns).
pub struct CellPair<'g> {
    li: &'g Line,
    lj: &'g Line,
    lines: &'g [Line],
    occluders: &'g [usize],
    cell_a: [f64; 2],
    cell_b: [f64; 2],
    h: f64,
    k: usize,
    q_min: usize,
    /// √(L_i L_j / (h_a h_b)): the normalisation of the two basis functions; L_i L_j for K².
    scale: f64,
    /// Integrate K² instead of K φ_p φ_r (for the denominator of eq. (5)); then k = 1.
    squared: bool,
}

impl<'g> CellPair<'g> {
    pub fn new(
        geo: &'g Geometry,
        disc: Discretization,
        i: usize,
        a: usize,
        j: usize,
        b: usize,
        pair: &'g PairInfo,
    ) -> CellPair<'g> {
        let h = 1.0 / disc.cells as f64;
        let (li, lj) = (&geo.lines[i], &geo.lines[j]);
        CellPair {
            li,
            lj,
            lines: &geo.lines,
            occluders: &pair.occluders,
            cell_a: [a as f64 * h, (a + 1) as f64 * h],
            cell_b: [b as f64 * h, (b + 1) as f64 * h],
            h,
            k: disc.order + 1,
            q_min: disc.quadrature.min(MAX_Q),
            scale: (li.len * lj.len).sqrt() / h,
            squared: false,
        }
    }

    /// The same pair, integrating K² (k = 1, scale L_i L_j).
    pub fn squared(mut self) -> CellPair<'g> {
        self.squared = true;
        self.k = 1;
        self.scale = self.li.len * self.lj.len;
        self
    }

    /// Adds ∫∫ K φ_p φ_r over the cells (restricted to the front ranges) to `out` (k × k).
    pub fn integrate(&self, front_i: [f64; 2], front_j: [f64; 2], out: &mut [f64]) {
        let (Some(sa), Some(sb)) = (intersect(self.cell_a, front_i), intersect(self.cell_b, front_j))
        else {
            return;
        };
        self.sub(sa, sb, 0, out);
    }

    fn sub(&self, sa: [f64; 2], sb: [f64; 2], depth: u32, out: &mut [f64]) {
        let (pa, pb) = ([self.li.at(sa[0]), self.li.at(sa[1])], [self.lj.at(sb[0]), self.lj.at(sb[1])]);
        let la = self.li.len * (sa[1] - sa[0]);
        let lb = self.lj.len * (sb[1] - sb[0]);
        let size = la.max(lb);
        let dist = segment_distance(pa[0], pa[1], pb[0], pb[1]);
        if dist < size && depth < MAX_DEPTH {
            let mid_a = 0.5 * (sa[0] + sa[1]);
            let mid_b = 0.5 * (sb[0] + sb[1]);
            let halves_a: &[[f64; 2]] = &[[sa[0], mid_a], [mid_a, sa[1]]];
            let halves_b: &[[f64; 2]] = &[[sb[0], mid_b], [mid_b, sb[1]]];
            let whole_a: &[[f64; 2]] = &[sa];
            let whole_b: &[[f64; 2]] = &[sb];
            let (ra, rb) = if la > 2.0 * lb {
                (halves_a, whole_b)
            } else if lb > 2.0 * la {
                (whole_a, halves_b)
            } else {
                (halves_a, halves_b)
            };
            for &x in ra {
                for &y in rb {
                    self.sub(x, y, depth + 1, out);
                }
            }
            return;
        }
        let q = points_for_separation(dist, size).max(self.q_min).min(MAX_Q);
        if self.occluders.is_empty() {
            self.tensor(sa, sb, q, out);
            return;
        }
        let mut occ: smallvec::SmallVec<[Line; 8]> = smallvec::SmallVec::new();
        for &o in self.occluders {
            let l = &self.lines[o];
            if may_block(pa, pb, [l.a, l.b]) {
                occ.push(*l);
            }
        }
        if occ.is_empty() {
            self.tensor(sa, sb, q, out);
        } else {
            self.occluded(sa, sb, q, &occ, out);
        }
    }

    /// Unoccluded: the q × q tensor Gauss rule.
    fn tensor(&self, sa: [f64; 2], sb: [f64; 2], q: usize, out: &mut [f64]) {
        let k = self.k;
        let rule = Rule::gauss(q);
        let mut phi_a = [0.0; MAX_Q * MAX_K];
        let mut phi_b = [0.0; MAX_Q * MAX_K];
        let mut xs = [V2::default(); MAX_Q];
        let mut ys = [V2::default(); MAX_Q];
        for (n, (s, w)) in rule.mapped(sa[0], sa[1]).enumerate() {
            legendre((s - self.cell_a[0]) / self.h, &mut phi_a[n * k..n * k + k]);
            phi_a[n * k..n * k + k].iter_mut().for_each(|v| *v *= w);
            xs[n] = self.li.at(s);
        }
        for (n, (t, w)) in rule.mapped(sb[0], sb[1]).enumerate() {
            legendre((t - self.cell_b[0]) / self.h, &mut phi_b[n * k..n * k + k]);
            phi_b[n * k..n * k + k].iter_mut().for_each(|v| *v *= w);
            ys[n] = self.lj.at(t);
        }
        let (ni, nj) = (self.li.n, self.lj.n);
        let mut tmp = [0.0; MAX_K];
        for a in 0..q {
            tmp[..k].fill(0.0);
            for b in 0..q {
                let mut kv = kernel::flatland(xs[a], ni, ys[b], nj);
                if self.squared {
                    kv *= kv;
                }
                for r in 0..k {
                    tmp[r] += kv * phi_b[b * k + r];
                }
            }
            for p in 0..k {
                let f = phi_a[a * k + p] * self.scale;
                for r in 0..k {
                    out[p * k + r] += f * tmp[r];
                }
            }
        }
    }

    /// Occluded: outer pieces between the breakpoints of the shadow topology, inner integral
    /// over the visible pieces of the target.
    fn occluded(&self, sa: [f64; 2], sb: [f64; 2], q: usize, occ: &[Line], out: &mut [f64]) {
        let k = self.k;
        let breaks = self.breakpoints(sa, sb, occ);
        let outer = Rule::gauss((q + 2).min(MAX_Q));
        let inner = Rule::gauss(q);
        let mut phi = [0.0; MAX_K];
        let mut tmp = [0.0; MAX_K];
        let mut pieces = Pieces::new();
        for w in breaks.windows(2) {
            for (s, ws) in outer.mapped(w[0], w[1]) {
                let x = self.li.at(s);
                if self.lj.side(x) <= 0.0 {
                    continue;
                }
                visible_from(x, self.lj, sb, occ, &mut pieces);
                tmp[..k].fill(0.0);
                for piece in &pieces {
                    for (t, wt) in inner.mapped(piece[0], piece[1]) {
                        let mut kv = kernel::flatland(x, self.li.n, self.lj.at(t), self.lj.n);
                        if self.squared {
                            kv *= kv;
                        }
                        kv *= wt;
                        legendre((t - self.cell_b[0]) / self.h, &mut phi[..k]);
                        for r in 0..k {
                            tmp[r] += kv * phi[r];
                        }
                    }
                }
                legendre((s - self.cell_a[0]) / self.h, &mut phi[..k]);
                for p in 0..k {
                    let f = phi[p] * ws * self.scale;
                    for r in 0..k {
                        out[p * k + r] += f * tmp[r];
                    }
                }
            }
        }
    }

    /// Parameters of surface i inside `sa` where the visible pieces of `sb` change their form:
    /// where x lines up with two of the fixed points (occluder ends, occluder crossings of the
    /// target line, ends of the target range), and where x's distance to the target line equals
    /// an occluder end's.
    fn breakpoints(&self, sa: [f64; 2], sb: [f64; 2], occ: &[Line]) -> smallvec::SmallVec<[f64; 32]> {
        let mut fixed: smallvec::SmallVec<[V2; 16]> = smallvec::SmallVec::new();
        for o in occ {
            fixed.push(o.a);
            fixed.push(o.b);
            let (s0, s1) = (self.lj.side(o.a), self.lj.side(o.b));
            if (s0 > 0.0) != (s1 > 0.0) {
                fixed.push(o.at(s0 / (s0 - s1)));
            }
        }
        let n_fixed = fixed.len();
        fixed.push(self.lj.at(sb[0]));
        fixed.push(self.lj.at(sb[1]));
        let mut out: smallvec::SmallVec<[f64; 32]> = smallvec::SmallVec::new();
        out.push(sa[0]);
        out.push(sa[1]);
        let inside = |s: f64| s > sa[0] && s < sa[1];
        for f in 0..n_fixed {
            for g in f + 1..fixed.len() {
                if let Some(s) = self.li.meet(fixed[f], fixed[g]) {
                    if inside(s) {
                        out.push(s);
                    }
                }
            }
            // side_j(x(s)) = side_j(fixed[f]), linear in s
            let (d0, d1) = (self.lj.side(self.li.a), self.lj.side(self.li.b));
            if (d1 - d0).abs() > 1e-300 {
                let s = (self.lj.side(fixed[f]) - d0) / (d1 - d0);
                if inside(s) {
                    out.push(s);
                }
            }
        }
        out.sort_by(f64::total_cmp);
        out.dedup_by(|a, b| (*a - *b).abs() <= 1e-14);
        out
    }
}

/// ∫_i ∫_j K² dy dx for every ordered pair of surfaces (i ≠ j), row-major `S × S`: the
/// denominator of eq. (5), with the cells and Gauss points of `disc` (take them finer than the
/// solve's). Pairs that touch diverge: skip them.
pub fn kernel_squares(
    geo: &Geometry,
    disc: Discretization,
    skip: impl Fn(usize, usize) -> bool + Sync,
) -> Vec<f64> {
    let s = geo.lines.len();
    (0..s * s)
        .into_par_iter()
        .map(|ij| {
            let (i, j) = (ij / s, ij % s);
            if i == j || skip(i, j) {
                return 0.0;
            }
            let pair = geo.pair(i, j);
            let (Some(fi), Some(fj)) = (pair.front_i, pair.front_j) else {
                return 0.0;
            };
            let mut sum = 0.0;
            for a in 0..disc.cells {
                for b in 0..disc.cells {
                    let mut out = [0.0];
                    CellPair::new(geo, disc, i, a, j, b, pair)
                        .squared()
                        .integrate(fi, fj, &mut out);
                    sum += out[0];
                }
            }
            sum
        })
        .collect()
}
