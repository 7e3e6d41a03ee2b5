//! The Galerkin matrix of flatland (slides' eq. (4) kernel, eq. (11) matrix).
//!
//! Cell pairs are integrated by tensor Gauss rules whose order grows as the cells come closer
//! ([`super::points_for_separation`]); pairs closer than their size are bisected recursively,
//! which integrates the 1/r singularity of touching segments (room corners) to full precision.
//! Pairs that a third segment may occlude are integrated with exact visibility: the outer
//! interval is split where the shadow topology changes, and the inner integral is taken over
//! the visible pieces only (`crate::flatland::visibility`).

use crate::flatland::geometry::{segment_distance, Line, V2};
use crate::flatland::kernel;
use crate::flatland::visibility::{may_block, visible_from, Pieces};
use crate::math::basis::legendre;
use crate::math::quadrature::Rule;
use crate::methods::projection::{points_for_separation, Dense, Discretization, Layout, System};
use crate::progress::{Cancelled, Phase, Progress};
use crate::scene::Segment;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};

/// Deepest bisection of a near-singular pair: 2⁻⁴⁰ of a cell.
const MAX_DEPTH: u32 = 40;
/// Largest order k = m + 1 and Gauss rule handled on the stack.
const MAX_K: usize = 16;
const MAX_Q: usize = 24;

/// What is known of a pair of surfaces before any cell is integrated.
#[derive(Debug, Clone, Default)]
pub(super) struct PairInfo {
    /// Parameters of surface i in front of surface j, and of j in front of i.
    pub(super) front_i: Option<[f64; 2]>,
    pub(super) front_j: Option<[f64; 2]>,
    /// Surfaces that may block some ray between the two.
    pub(super) occluders: Vec<usize>,
}

/// The geometry of a flatland scene, with the pairwise facts the integrators need.
pub struct Geometry {
    pub(super) lines: Vec<Line>,
    pairs: Vec<PairInfo>,
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

    pub(super) fn pair(&self, i: usize, j: usize) -> &PairInfo {
        &self.pairs[i * self.lines.len() + j]
    }

    /// Surface pairs (i < j) whose closed segments meet.
    pub(crate) fn touching(&self) -> Vec<(usize, usize)> {
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

pub(super) fn intersect(a: [f64; 2], b: [f64; 2]) -> Option<[f64; 2]> {
    let lo = a[0].max(b[0]);
    let hi = a[1].min(b[1]);
    (hi > lo).then_some([lo, hi])
}

/// Builds the flatland system.
pub(crate) fn build(
    segments: &[Segment],
    disc: Discretization,
    progress: &dyn Progress,
) -> Result<System, Cancelled> {
    let geo = Geometry::new(segments);
    let (matrix, kernel_evaluations) = matrix(&geo, disc, progress)?;
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
        kernel_evaluations: Some(kernel_evaluations),
    })
}

/// E on every cell of a uniform grid, `[cell][p]`.
fn emission_coefficients(s: &Segment, len: f64, disc: Discretization) -> Vec<[f64; 3]> {
    let h = 1.0 / disc.cells as f64;
    (0..disc.cells)
        .flat_map(|c| emission_on(s, len, [c as f64 * h, (c + 1) as f64 * h], disc.order))
        .collect()
}

/// E_p = ∫_{cell} E N_p = E √(L/h) ∫_{cell ∩ region} φ_p(ŝ) ds on one parameter interval,
/// exactly (E is constant on its region).
pub(super) fn emission_on(s: &Segment, len: f64, cell: [f64; 2], order: usize) -> Vec<[f64; 3]> {
    let k = order + 1;
    let h = cell[1] - cell[0];
    let mut out = vec![[0.0; 3]; k];
    let Some(part) = intersect(cell, s.emission_region) else {
        return out;
    };
    let mut phi = vec![0.0; k];
    for (x, w) in Rule::for_degree(order).mapped(part[0], part[1]) {
        legendre((x - cell[0]) / h, &mut phi);
        for p in 0..k {
            let v = w * phi[p] * (len / h).sqrt();
            for ch in 0..3 {
                out[p][ch] += v * s.material.emission[ch];
            }
        }
    }
    out
}

/// The ρ-free Galerkin matrix and the number of kernel evaluations it took.
pub fn matrix(
    geo: &Geometry,
    disc: Discretization,
    progress: &dyn Progress,
) -> Result<(Dense, u64), Cancelled> {
    let k = disc.order + 1;
    assert!(k <= MAX_K, "order {} above {}", disc.order, MAX_K - 1);
    let per = disc.cells * k;
    let n = geo.lines.len() * per;
    let mut m = Dense::zeros(n);
    let done = AtomicUsize::new(0);
    let evaluations = AtomicU64::new(0);
    let blocks = geo.lines.len() * disc.cells;
    let tables = FastTables::new(geo, disc);
    progress.report(Phase::Projection, 0.0);
    m.data
        .par_chunks_mut(k * n)
        .enumerate()
        .try_for_each(|(row_block, rows)| {
            progress.check()?;
            let (i, a) = (row_block / disc.cells, row_block % disc.cells);
            let mut block = [0.0; MAX_K * MAX_K];
            let mut evals = 0;
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
                    evals += match tables.fast_points(geo, pair, i, a, j, b) {
                        Some(q) => tables.tensor(geo, (i, a), (j, b), q, &mut block[..k * k]),
                        None => CellPair::new(geo, disc, i, a, j, b, pair).integrate(
                            fi,
                            fj,
                            &mut block[..k * k],
                        ),
                    };
                    for p in 0..k {
                        let dst = &mut rows[p * n + j * per + b * k..p * n + j * per + b * k + k];
                        dst.copy_from_slice(&block[p * k..p * k + k]);
                    }
                }
            }
            evaluations.fetch_add(evals, Ordering::Relaxed);
            let d = done.fetch_add(1, Ordering::Relaxed) + 1;
            if d.is_multiple_of(16) || d == blocks {
                progress.report(Phase::Projection, d as f64 / blocks as f64);
            }
            Ok::<(), Cancelled>(())
        })?;
    Ok((m, evaluations.into_inner()))
}

/// The fast path of the fill: for well-separated, unoccluded cell pairs entirely in front of
/// each other (most pairs of most scenes), Gauss nodes and weighted basis values are tabulated
/// once per surface and rule, so a pair costs its q² kernel evaluations and little else.
/// Everything else goes through [`CellPair`].
struct FastTables {
    k: usize,
    cells: usize,
    h: f64,
    q_min: usize,
    /// For each rule size q (index q − q_min): per surface, `cells × q` points and
    /// `cells × q × k` basis values times weights.
    points: Vec<Vec<Vec<V2>>>,
    phi: Vec<Vec<Vec<f64>>>,
    /// Cell midpoints per surface.
    mids: Vec<Vec<V2>>,
    /// `ratios[t]`: the smallest distance / size at which rule q_min + t is accurate enough.
    ratios: Vec<f64>,
}

/// Largest rule on the fast path; closer pairs (needing more points) take the careful path.
const FAST_MAX_Q: usize = 12;
/// Largest k = m + 1 on the fast path; higher orders take the careful path.
const FAST_MAX_K: usize = 8;

impl FastTables {
    fn new(geo: &Geometry, disc: Discretization) -> FastTables {
        let k = disc.order + 1;
        let h = 1.0 / disc.cells as f64;
        let q_min = disc.quadrature.clamp(1, FAST_MAX_Q);
        let mut points = Vec::new();
        let mut phi = Vec::new();
        for q in q_min..=FAST_MAX_Q {
            let rule = Rule::gauss(q);
            let mut pts_q = Vec::new();
            let mut phi_q = Vec::new();
            for line in &geo.lines {
                let mut pts = Vec::with_capacity(disc.cells * q);
                let mut ph = vec![0.0; disc.cells * q * k];
                for c in 0..disc.cells {
                    for (a, (x, w)) in rule.mapped(0.0, 1.0).enumerate() {
                        pts.push(line.at((c as f64 + x) * h));
                        let at = (c * q + a) * k;
                        legendre(x, &mut ph[at..at + k]);
                        ph[at..at + k].iter_mut().for_each(|v| *v *= w * h);
                    }
                }
                pts_q.push(pts);
                phi_q.push(ph);
            }
            points.push(pts_q);
            phi.push(phi_q);
        }
        let mids = geo
            .lines
            .iter()
            .map(|l| {
                (0..disc.cells)
                    .map(|c| l.at((c as f64 + 0.5) * h))
                    .collect()
            })
            .collect();
        // points_for_separation(r) ≤ q ⇔ ρ ≥ e^(15/q), ρ = a + √(a² − 1), a = 1 + 2r
        let ratios = (q_min..=FAST_MAX_Q)
            .map(|q| {
                let rho = (15.0 / q as f64).exp();
                let a = 0.5 * (rho + 1.0 / rho);
                (0.5 * (a - 1.0)).max(1.0) * (1.0 + 1e-12)
            })
            .collect();
        FastTables {
            ratios,
            k,
            cells: disc.cells,
            h,
            q_min,
            points,
            phi,
            mids,
        }
    }

    /// The rule for cells a (of i) and b (of j) if the pair may take the fast path.
    fn fast_points(
        &self,
        geo: &Geometry,
        pair: &PairInfo,
        i: usize,
        a: usize,
        j: usize,
        b: usize,
    ) -> Option<usize> {
        if !pair.occluders.is_empty() || self.k > FAST_MAX_K {
            return None;
        }
        let (fi, fj) = (pair.front_i?, pair.front_j?);
        let (sa, sb) = (a as f64 * self.h, b as f64 * self.h);
        if sa < fi[0] || sa + self.h > fi[1] || sb < fj[0] || sb + self.h > fj[1] {
            return None;
        }
        let (la, lb) = (geo.lines[i].len * self.h, geo.lines[j].len * self.h);
        let size = la.max(lb);
        // a lower bound of the distance between the two cells
        let dist = (self.mids[i][a] - self.mids[j][b]).norm() - 0.5 * (la + lb);
        if dist < size {
            return None;
        }
        let t = self.ratios.iter().position(|&r| dist >= r * size)?;
        Some(self.q_min + t)
    }

    /// The q × q rule on cell a of surface i and cell b of surface j, from the tables.
    fn tensor(
        &self,
        geo: &Geometry,
        (i, a): (usize, usize),
        (j, b): (usize, usize),
        q: usize,
        out: &mut [f64],
    ) -> u64 {
        let k = self.k;
        let t = q - self.q_min;
        let xs = &self.points[t][i][a * q..(a + 1) * q];
        let ys = &self.points[t][j][b * q..(b + 1) * q];
        let pa = &self.phi[t][i][a * q * k..(a + 1) * q * k];
        let pb = &self.phi[t][j][b * q * k..(b + 1) * q * k];
        let (ni, nj) = (geo.lines[i].n, geo.lines[j].n);
        let scale = (geo.lines[i].len * geo.lines[j].len).sqrt() / self.h;
        // k known at compile time for the common orders, so the inner loops unroll
        match k {
            1 => contract::<1>(xs, ys, pa, pb, ni, nj, scale, out),
            2 => contract::<2>(xs, ys, pa, pb, ni, nj, scale, out),
            3 => contract::<3>(xs, ys, pa, pb, ni, nj, scale, out),
            4 => contract::<4>(xs, ys, pa, pb, ni, nj, scale, out),
            5 => contract::<5>(xs, ys, pa, pb, ni, nj, scale, out),
            6 => contract::<6>(xs, ys, pa, pb, ni, nj, scale, out),
            7 => contract::<7>(xs, ys, pa, pb, ni, nj, scale, out),
            8 => contract::<8>(xs, ys, pa, pb, ni, nj, scale, out),
            _ => unreachable!("the fast path takes k ≤ {FAST_MAX_K}"),
        }
        debug_assert_eq!(self.cells * q, self.points[t][i].len());
        (q * q) as u64
    }
}

/// out[p][r] += scale Σ_α Σ_β pa[α][p] K(x_α, y_β) pb[β][r], for cells wholly in front of
/// each other (so the one-sided test of eq. (4) is not needed).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn contract<const K: usize>(
    xs: &[V2],
    ys: &[V2],
    pa: &[f64],
    pb: &[f64],
    ni: V2,
    nj: V2,
    scale: f64,
    out: &mut [f64],
) {
    for (alpha, &x) in xs.iter().enumerate() {
        let mut tmp = [0.0; K];
        for (beta, &y) in ys.iter().enumerate() {
            let kv = kernel::flatland_facing(x, ni, y, nj);
            for r in 0..K {
                tmp[r] += kv * pb[beta * K + r];
            }
        }
        for p in 0..K {
            let f = pa[alpha * K + p] * scale;
            for r in 0..K {
                out[p * K + r] += f * tmp[r];
            }
        }
    }
}

/// One pair of cells: cell a of surface i (rows) and cell b of surface j (columns).
pub(super) struct CellPair<'g> {
    li: &'g Line,
    lj: &'g Line,
    lines: &'g [Line],
    occluders: &'g [usize],
    cell_a: [f64; 2],
    cell_b: [f64; 2],
    h_a: f64,
    h_b: f64,
    k: usize,
    q_min: usize,
    /// √(L_i L_j / (h_a h_b)): the normalisation of the two basis functions; L_i L_j for K².
    scale: f64,
    /// Integrate K² instead of K φ_p φ_r (for the denominator of eq. (5)); then k = 1.
    squared: bool,
}

impl<'g> CellPair<'g> {
    fn new(
        geo: &'g Geometry,
        disc: Discretization,
        i: usize,
        a: usize,
        j: usize,
        b: usize,
        pair: &'g PairInfo,
    ) -> CellPair<'g> {
        let h = 1.0 / disc.cells as f64;
        let cell_a = [a as f64 * h, (a + 1) as f64 * h];
        let cell_b = [b as f64 * h, (b + 1) as f64 * h];
        CellPair::between(
            geo,
            (i, cell_a),
            (j, cell_b),
            disc.order,
            disc.quadrature,
            pair,
        )
    }

    /// Two parameter intervals of any sizes: `cell_a` of surface i and `cell_b` of surface j,
    /// with the orthonormal Legendre functions of order `order` on each.
    pub(super) fn between(
        geo: &'g Geometry,
        (i, cell_a): (usize, [f64; 2]),
        (j, cell_b): (usize, [f64; 2]),
        order: usize,
        quadrature: usize,
        pair: &'g PairInfo,
    ) -> CellPair<'g> {
        let (li, lj) = (&geo.lines[i], &geo.lines[j]);
        let (h_a, h_b) = (cell_a[1] - cell_a[0], cell_b[1] - cell_b[0]);
        CellPair {
            li,
            lj,
            lines: &geo.lines,
            occluders: &pair.occluders,
            cell_a,
            cell_b,
            h_a,
            h_b,
            k: order + 1,
            q_min: quadrature.min(MAX_Q),
            scale: (li.len * lj.len / (h_a * h_b)).sqrt(),
            squared: false,
        }
    }

    /// The same pair, integrating K² (k = 1, scale L_i L_j).
    fn squared(mut self) -> CellPair<'g> {
        self.squared = true;
        self.k = 1;
        self.scale = self.li.len * self.lj.len;
        self
    }

    /// Adds ∫∫ K φ_p φ_r over the cells (restricted to the front ranges) to `out` (k × k);
    /// returns the number of kernel evaluations.
    pub(super) fn integrate(&self, front_i: [f64; 2], front_j: [f64; 2], out: &mut [f64]) -> u64 {
        let (Some(sa), Some(sb)) = (
            intersect(self.cell_a, front_i),
            intersect(self.cell_b, front_j),
        ) else {
            return 0;
        };
        self.sub(sa, sb, 0, out)
    }

    fn sub(&self, sa: [f64; 2], sb: [f64; 2], depth: u32, out: &mut [f64]) -> u64 {
        let (pa, pb) = (
            [self.li.at(sa[0]), self.li.at(sa[1])],
            [self.lj.at(sb[0]), self.lj.at(sb[1])],
        );
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
            let mut evals = 0;
            for &x in ra {
                for &y in rb {
                    evals += self.sub(x, y, depth + 1, out);
                }
            }
            return evals;
        }
        let q = points_for_separation(dist, size).max(self.q_min).min(MAX_Q);
        if self.occluders.is_empty() {
            return self.tensor(sa, sb, q, out);
        }
        let mut occ: smallvec::SmallVec<[Line; 8]> = smallvec::SmallVec::new();
        for &o in self.occluders {
            let l = &self.lines[o];
            if may_block(pa, pb, [l.a, l.b]) {
                occ.push(*l);
            }
        }
        if occ.is_empty() {
            self.tensor(sa, sb, q, out)
        } else {
            self.occluded(sa, sb, q, &occ, out)
        }
    }

    /// Unoccluded: the q × q tensor Gauss rule.
    fn tensor(&self, sa: [f64; 2], sb: [f64; 2], q: usize, out: &mut [f64]) -> u64 {
        let k = self.k;
        let rule = Rule::gauss(q);
        let mut phi_a = [0.0; MAX_Q * MAX_K];
        let mut phi_b = [0.0; MAX_Q * MAX_K];
        let mut xs = [V2::default(); MAX_Q];
        let mut ys = [V2::default(); MAX_Q];
        for (n, (s, w)) in rule.mapped(sa[0], sa[1]).enumerate() {
            legendre(
                (s - self.cell_a[0]) / self.h_a,
                &mut phi_a[n * k..n * k + k],
            );
            phi_a[n * k..n * k + k].iter_mut().for_each(|v| *v *= w);
            xs[n] = self.li.at(s);
        }
        for (n, (t, w)) in rule.mapped(sb[0], sb[1]).enumerate() {
            legendre(
                (t - self.cell_b[0]) / self.h_b,
                &mut phi_b[n * k..n * k + k],
            );
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
        (q * q) as u64
    }

    /// Occluded: outer pieces between the breakpoints of the shadow topology, inner integral
    /// over the visible pieces of the target.
    fn occluded(&self, sa: [f64; 2], sb: [f64; 2], q: usize, occ: &[Line], out: &mut [f64]) -> u64 {
        let mut evals = 0;
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
                    evals += inner.len() as u64;
                    for (t, wt) in inner.mapped(piece[0], piece[1]) {
                        let mut kv = kernel::flatland(x, self.li.n, self.lj.at(t), self.lj.n);
                        if self.squared {
                            kv *= kv;
                        }
                        kv *= wt;
                        legendre((t - self.cell_b[0]) / self.h_b, &mut phi[..k]);
                        for r in 0..k {
                            tmp[r] += kv * phi[r];
                        }
                    }
                }
                legendre((s - self.cell_a[0]) / self.h_a, &mut phi[..k]);
                for p in 0..k {
                    let f = phi[p] * ws * self.scale;
                    for r in 0..k {
                        out[p * k + r] += f * tmp[r];
                    }
                }
            }
        }
        evals
    }

    /// Parameters of surface i inside `sa` where the visible pieces of `sb` change their form:
    /// where x lines up with two of the fixed points (occluder ends, occluder crossings of the
    /// target line, ends of the target range), and where x's distance to the target line equals
    /// an occluder end's.
    fn breakpoints(
        &self,
        sa: [f64; 2],
        sb: [f64; 2],
        occ: &[Line],
    ) -> smallvec::SmallVec<[f64; 32]> {
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
pub(crate) fn kernel_squares(
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
                    let _evals = CellPair::new(geo, disc, i, a, j, b, pair)
                        .squared()
                        .integrate(fi, fj, &mut out);
                    sum += out[0];
                }
            }
            sum
        })
        .collect()
}
