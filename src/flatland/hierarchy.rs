//! Hierarchical wavelet radiosity in flatland (Gortler, Schröder, Cohen and Hanrahan, "Wavelet
//! Radiosity", SIGGRAPH 1993, §4–5; Hanrahan, Salzman and Aupperle, "A Rapid Hierarchical
//! Radiosity Algorithm", SIGGRAPH 1991, §3–4), with Alpert's multiwavelets of order m.
//!
//! Every segment is the root of a binary tree of elements (parameter intervals, at most
//! `resolution` leaves deep). An element carries the k = m + 1 coefficients of B, E and the
//! gathered irradiance H in the orthonormal Legendre functions on it. A link r ← s carries the
//! k × k Galerkin transfer T_pq = ∫_r ∫_s K(x,y) N_s,q(y) N_r,p(x) dy dx (eq. (11) between two
//! elements of any sizes, with exact visibility). One sweep of the solve is
//!
//! 1. gather: H_r = Σ_{links r ← s} T B_s;
//! 2. push–pull: H is pushed down the tree through the two-scale relations (child coefficients
//!    Hᵀ h), B = E + ρ H at the leaves, and B is pulled back up (parent coefficients H b, the
//!    projection onto the coarser level; the wavelet details stay in the children);
//!
//! a Jacobi sweep of B = E + ρKB in the non-standard multiwavelet form (with the document's
//! `"gauss-seidel"`, both steps segment by segment, each segment's gather reading the B that
//! the segments before it got in the same sweep). The refinement oracle
//! estimates what a link gets wrong: the part of K on r × s outside the tensor polynomials of
//! order m (sampled on a Gauss grid, visibility included), times ‖B_s‖, times ρ_r: a bound of
//! the L² norm of the error of B on r, the measure of eq. (6). A link whose estimate is above
//! ε·E_max·√L (L the longest segment) is replaced by links between the children of the longer
//! element. The first pass refines against the emission only; each
//! following pass re-refines against the B just solved ("BF refinement") until no link changes.

use crate::flatland::geometry::Line;
use crate::flatland::kernel;
use crate::flatland::projection::{emission_on, intersect, CellPair, Geometry};
use crate::flatland::visibility::{visible_from, Pieces};
use crate::math::basis::{legendre, Filters};
use crate::math::field::{Field, Leaf};
use crate::math::quadrature::Rule;
use crate::methods::solution::{JobError, Solution};
use crate::methods::solve::{Settings, SolveError, Solved};
use crate::progress::{Cancelled, Phase, Progress};
use crate::result::HierarchyStats;
use crate::scene::Iteration;
use crate::scene::{Rgb, Segment};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::time::Instant;

/// Refinement passes after the first solve, at most.
const MAX_PASSES: usize = 8;

/// An interval of a segment's parameter, in the tree of that segment.
#[derive(Debug, Clone)]
struct Element {
    surface: usize,
    range: [f64; 2],
    level: u32,
    children: Option<[usize; 2]>,
    /// Coefficients in N_p = φ_p(ŝ) / √|e| (orthonormal in arc length), per channel.
    e: Vec<Rgb>,
    b: Vec<Rgb>,
    /// Gathered at this element by its own links.
    h: Vec<Rgb>,
    /// H from all levels, pushed down (leaves only; for the energy balance).
    h_total: Vec<Rgb>,
}

/// A link r ← s and its transfer block (row-major k × k, p of r by q of s).
#[derive(Debug, Clone)]
struct Link {
    r: usize,
    s: usize,
    t: Vec<f64>,
}

impl Link {
    /// What the link delivers to its receiver: T b, for the source's coefficients b.
    fn transfer(&self, b: &[Rgb]) -> Vec<Rgb> {
        self.t
            .chunks_exact(b.len())
            .map(|row| {
                row.iter().zip(b).fold([0.0; 3], |mut o, (t, bq)| {
                    (0..3).for_each(|c| o[c] += t * bq[c]);
                    o
                })
            })
            .collect()
    }
}

struct Hierarchy<'a> {
    geo: Geometry,
    segments: &'a [Segment],
    filters: &'static Filters,
    k: usize,
    order: usize,
    quadrature: usize,
    max_level: u32,
    threshold: f64,
    negative_tolerance: f64,
    rho_max: Vec<f64>,
    elements: Vec<Element>,
    links: Vec<Link>,
    refinements: usize,
    /// The most links the refinement may make (their k² transfers in [`LINK_BYTES`]); set
    /// `too_large` and stop there.
    max_links: usize,
    too_large: bool,
}

/// The memory the links' transfers may take.
const LINK_BYTES: usize = 1 << 28;

impl<'a> Hierarchy<'a> {
    fn new(
        segments: &'a [Segment],
        order: usize,
        resolution: usize,
        quadrature: usize,
        epsilon: f64,
    ) -> Self {
        let geo = Geometry::new(segments);
        let e_max = segments
            .iter()
            .flat_map(|s| s.material.emission)
            .fold(0.0f64, f64::max);
        let mut h = Hierarchy {
            segments,
            filters: Filters::of_order(order),
            k: order + 1,
            order,
            quadrature,
            max_level: resolution.trailing_zeros(),
            // B below this is below zero, not rounding ([`Hierarchy::below_zero`])
            negative_tolerance: 1e-9 * e_max,
            // the L² norm of the brightest light over the longest segment
            threshold: epsilon
                * e_max
                * segments
                    .iter()
                    .map(|s| (s.b[0] - s.a[0]).hypot(s.b[1] - s.a[1]))
                    .fold(0.0, f64::max)
                    .sqrt(),
            rho_max: segments
                .iter()
                .map(|s| s.material.reflectance.iter().fold(0.0f64, |a, b| a.max(*b)))
                .collect(),
            elements: Vec::new(),
            links: Vec::new(),
            refinements: 0,
            max_links: LINK_BYTES / (8 * (order + 1).pow(2) + 64),
            too_large: false,
            geo,
        };
        for i in 0..segments.len() {
            h.push_element(i, [0.0, 1.0], 0);
        }
        // an element across an edge of its emission region would spread the light over
        // itself (and below zero beside it): split down to the finest level along the edges
        let mut open: Vec<usize> = (0..segments.len()).collect();
        while let Some(e) = open.pop() {
            let el = &h.elements[e];
            let seg = &segments[el.surface];
            let [r0, r1] = seg.emission_region;
            let emits = seg.material.emission.iter().any(|&x| x != 0.0);
            let straddles =
                el.range[0] < r1 && r0 < el.range[1] && !(r0 <= el.range[0] && el.range[1] <= r1);
            if emits && straddles && el.level < h.max_level {
                open.extend(h.split(e));
            }
        }
        h
    }

    fn push_element(&mut self, surface: usize, range: [f64; 2], level: u32) -> usize {
        let seg = &self.segments[surface];
        let e = emission_on(seg, self.geo.lines[surface].len, range, self.order);
        self.elements.push(Element {
            surface,
            range,
            level,
            children: None,
            b: e.clone(),
            e,
            h: vec![[0.0; 3]; self.k],
            h_total: vec![[0.0; 3]; self.k],
        });
        self.elements.len() - 1
    }

    /// Splits a leaf in two; the children start from the parent's B pushed down.
    fn split(&mut self, e: usize) -> [usize; 2] {
        if let Some(c) = self.elements[e].children {
            return c;
        }
        let Element {
            surface,
            range,
            level,
            ..
        } = self.elements[e];
        let mid = 0.5 * (range[0] + range[1]);
        let a = self.push_element(surface, [range[0], mid], level + 1);
        let b = self.push_element(surface, [mid, range[1]], level + 1);
        let parent_b = self.elements[e].b.clone();
        for (child, c) in [(a, 0), (b, 1)] {
            self.elements[child].b = self.down(&parent_b, c);
        }
        self.elements[e].children = Some([a, b]);
        [a, b]
    }

    /// Coefficients on child `c` (0 left, 1 right) of the parent function with coefficients v.
    fn down(&self, v: &[Rgb], c: usize) -> Vec<Rgb> {
        let k = self.k;
        let h = &self.filters.h;
        (0..k)
            .map(|q| {
                let mut out = [0.0; 3];
                for p in 0..k {
                    let f = h[p * 2 * k + c * k + q];
                    for ch in 0..3 {
                        out[ch] += f * v[p][ch];
                    }
                }
                out
            })
            .collect()
    }

    /// Parent coefficients of the function with child coefficients `left` and `right`.
    fn up(&self, left: &[Rgb], right: &[Rgb]) -> Vec<Rgb> {
        let k = self.k;
        let h = &self.filters.h;
        (0..k)
            .map(|p| {
                let mut out = [0.0; 3];
                for q in 0..k {
                    for ch in 0..3 {
                        out[ch] +=
                            h[p * 2 * k + q] * left[q][ch] + h[p * 2 * k + k + q] * right[q][ch];
                    }
                }
                out
            })
            .collect()
    }

    fn length(&self, e: usize) -> f64 {
        let el = &self.elements[e];
        self.geo.lines[el.surface].len * (el.range[1] - el.range[0])
    }

    /// ‖B_s‖ in L²(s) (largest channel), or of E alone in the first pass.
    fn source_norm(&self, s: usize, emission_only: bool) -> f64 {
        let v = if emission_only {
            &self.elements[s].e
        } else {
            &self.elements[s].b
        };
        (0..3)
            .map(|c| v.iter().map(|x| x[c] * x[c]).sum::<f64>().sqrt())
            .fold(0.0, f64::max)
    }

    /// Whether r and s can exchange light at all (both partly in front of the other).
    fn facing(&self, r: usize, s: usize) -> bool {
        let (er, es) = (&self.elements[r], &self.elements[s]);
        if er.surface == es.surface {
            return false;
        }
        let pair = self.geo.pair(er.surface, es.surface);
        match (pair.front_i, pair.front_j) {
            (Some(fi), Some(fj)) => {
                intersect(er.range, fi).is_some() && intersect(es.range, fj).is_some()
            }
            _ => false,
        }
    }

    /// The oracle: the L² norm over r of the error of B that the link r ← s would make (the
    /// measure of eq. (6)): ρ_r ‖K − PKP‖ ‖B_s‖.
    fn estimate(&self, r: usize, s: usize, emission_only: bool) -> f64 {
        let rho = self.rho_max[self.elements[r].surface];
        let bs = self.source_norm(s, emission_only);
        if rho == 0.0 || bs == 0.0 {
            return 0.0;
        }
        rho * self.kernel_residual(r, s) * bs
    }

    /// ‖K − P_r ⊗ P_s K‖ in L²(r × s), K sampled (with visibility) on a (k+2)² Gauss grid.
    fn kernel_residual(&self, r: usize, s: usize) -> f64 {
        let k = self.k;
        let (er, es) = (&self.elements[r], &self.elements[s]);
        let (li, lj) = (&self.geo.lines[er.surface], &self.geo.lines[es.surface]);
        let pair = self.geo.pair(er.surface, es.surface);
        let occ: Vec<Line> = pair.occluders.iter().map(|&o| self.geo.lines[o]).collect();
        // a shadow boundary can fall between samples, and so can the line where one element
        // crosses the other's line (the kernel has a kink there, and the source's B may
        // differ on the two sides, which a coarse link would average): sample such pairs
        // three times denser
        let straddles = |range: [f64; 2], front: Option<[f64; 2]>| {
            front.is_some_and(|f| f[0] > range[0] || f[1] < range[1])
        };
        let crossed = straddles(er.range, pair.front_i) || straddles(es.range, pair.front_j);
        let rule = Rule::gauss(if occ.is_empty() && !crossed {
            k + 2
        } else {
            3 * (k + 2)
        });
        let q = rule.len();
        let mut kv = vec![0.0; q * q];
        let mut pieces = Pieces::new();
        let range_j = pair.front_j.and_then(|f| intersect(es.range, f));
        for (a, &u) in rule.nodes.iter().enumerate() {
            let x = li.at(er.range[0] + u * (er.range[1] - er.range[0]));
            let sees = lj.side(x) > 0.0;
            if sees && !occ.is_empty() {
                if let Some(rj) = range_j {
                    visible_from(x, lj, rj, &occ, &mut pieces);
                } else {
                    pieces.clear();
                }
            }
            for (b, &v) in rule.nodes.iter().enumerate() {
                let t = es.range[0] + v * (es.range[1] - es.range[0]);
                let visible =
                    sees && (occ.is_empty() || pieces.iter().any(|p| p[0] <= t && t <= p[1]));
                kv[a * q + b] = if visible {
                    kernel::flatland(x, li.n, lj.at(t), lj.n)
                } else {
                    0.0
                };
            }
        }
        // project onto φ_p(u) φ_q(v), p, q ≤ m, and measure what is left
        let mut phi = vec![0.0; q * k];
        for (a, &u) in rule.nodes.iter().enumerate() {
            legendre(u, &mut phi[a * k..(a + 1) * k]);
        }
        let w = &rule.weights;
        let mut c = vec![0.0; k * k];
        for a in 0..q {
            for b in 0..q {
                let f = w[a] * w[b] * kv[a * q + b];
                for p in 0..k {
                    for r2 in 0..k {
                        c[p * k + r2] += f * phi[a * k + p] * phi[b * k + r2];
                    }
                }
            }
        }
        let mut resid = 0.0;
        for a in 0..q {
            for b in 0..q {
                let mut fit = 0.0;
                for p in 0..k {
                    for r2 in 0..k {
                        fit += c[p * k + r2] * phi[a * k + p] * phi[b * k + r2];
                    }
                }
                resid += w[a] * w[b] * (kv[a * q + b] - fit).powi(2);
            }
        }
        (resid * self.length(r) * self.length(s)).sqrt()
    }

    /// An error if the refinement stopped at `max_links`.
    fn within_budget(&self) -> Result<(), JobError> {
        if self.too_large {
            return Err(JobError::TooLarge {
                links: self.max_links,
                order: self.order,
            });
        }
        Ok(())
    }

    /// Links r ← s, refining where the oracle asks; new links have an empty transfer.
    fn refine(&mut self, r: usize, s: usize, emission_only: bool) {
        if self.links.len() >= self.max_links {
            self.too_large = true;
        }
        if self.too_large || !self.facing(r, s) {
            return;
        }
        let (lr, ls) = (self.elements[r].level, self.elements[s].level);
        let at_bottom = lr >= self.max_level && ls >= self.max_level;
        if at_bottom || self.estimate(r, s, emission_only) <= self.threshold {
            self.links.push(Link {
                r,
                s,
                t: Vec::new(),
            });
            return;
        }
        let split_receiver =
            ls >= self.max_level || (lr < self.max_level && self.length(r) >= self.length(s));
        if split_receiver {
            for c in self.split(r) {
                self.refine(c, s, emission_only);
            }
        } else {
            for c in self.split(s) {
                self.refine(r, c, emission_only);
            }
        }
    }

    /// Computes the transfers of the links that have none, in parallel; stops early (leaving
    /// links without transfers) once `progress` is cancelled.
    fn transfers(&mut self, progress: &dyn Progress) -> Result<u64, Cancelled> {
        let k = self.k;
        let (geo, elements, order, quadrature) =
            (&self.geo, &self.elements, self.order, self.quadrature);
        let evals = self
            .links
            .par_iter_mut()
            .filter(|l| l.t.is_empty())
            .map(|l| {
                if progress.cancelled() {
                    return 0;
                }
                let (er, es) = (&elements[l.r], &elements[l.s]);
                let pair = geo.pair(er.surface, es.surface);
                let mut t = vec![0.0; k * k];
                let evals = match (pair.front_i, pair.front_j) {
                    (Some(fi), Some(fj)) => CellPair::between(
                        geo,
                        (er.surface, er.range),
                        (es.surface, es.range),
                        order,
                        quadrature,
                        pair,
                    )
                    .integrate(fi, fj, &mut t),
                    _ => 0,
                };
                l.t = t;
                evals
            })
            .sum::<u64>();
        progress.check()?;
        Ok(evals)
    }

    /// Elements over a leaf whose B goes below zero (the leaf and its ancestors). B ≥ 0 holds
    /// for the exact solution; a polynomial fitted to the irradiance over a coarse receiver
    /// that a shadow crosses overshoots below zero on the dark side (−0.01 on the floor of
    /// `flatland-room.json` at order 1, where the lamp is 10), within the oracle's tolerance.
    fn below_zero(&self) -> Vec<bool> {
        let mut marked = vec![false; self.elements.len()];
        let mut phi = vec![0.0; self.k];
        let n = 2 * self.k + 1;
        for (i, e) in self.elements.iter().enumerate() {
            if e.children.is_some() {
                continue;
            }
            let scale = 1.0 / self.length(i).sqrt();
            let negative = (0..=n).any(|j| {
                crate::math::basis::legendre::legendre(j as f64 / n as f64, &mut phi);
                (0..3).any(|c| {
                    let v: f64 = e.b.iter().zip(&phi).map(|(b, p)| b[c] * p).sum();
                    v * scale < -self.negative_tolerance
                })
            });
            if negative {
                marked[i] = true;
            }
        }
        // up the trees: a link into an ancestor delivers its polynomial to the leaf too
        for i in (0..self.elements.len()).rev() {
            if let Some([a, b]) = self.elements[i].children {
                marked[i] |= marked[a] || marked[b];
            }
        }
        marked
    }

    /// One refinement pass over the existing links against the current B; whether any changed.
    /// Besides the oracle's verdict, a link into an element over a leaf where B went below zero
    /// is split on its receiver's side, down to the finest level.
    fn rerefine(&mut self) -> bool {
        let below = self.below_zero();
        let old = std::mem::take(&mut self.links);
        let mut changed = false;
        for link in old {
            let (lr, ls) = (self.elements[link.r].level, self.elements[link.s].level);
            let at_bottom = lr >= self.max_level && ls >= self.max_level;
            if below[link.r] && lr < self.max_level {
                changed = true;
                for c in self.split(link.r) {
                    self.refine(c, link.s, false);
                }
            } else if at_bottom || self.estimate(link.r, link.s, false) <= self.threshold {
                self.links.push(link);
            } else {
                changed = true;
                let (r, s) = (link.r, link.s);
                let split_receiver = ls >= self.max_level
                    || (lr < self.max_level && self.length(r) >= self.length(s));
                if split_receiver {
                    for c in self.split(r) {
                        self.refine(c, s, false);
                    }
                } else {
                    for c in self.split(s) {
                        self.refine(r, c, false);
                    }
                }
            }
        }
        changed
    }

    /// One Jacobi sweep: gather over the links, then push–pull every tree. Returns the change
    /// of B at the leaves and the norm of the new B (squared sums).
    fn sweep(&mut self) -> (f64, f64) {
        let k = self.k;
        for e in &mut self.elements {
            e.h.iter_mut().for_each(|v| *v = [0.0; 3]);
        }
        // links are grouped by receiver only loosely: accumulate sequentially (deterministic)
        let gathered: Vec<(usize, Vec<Rgb>)> = self
            .links
            .par_iter()
            .map(|l| (l.r, l.transfer(&self.elements[l.s].b)))
            .collect();
        for (r, h) in gathered {
            for p in 0..k {
                for c in 0..3 {
                    self.elements[r].h[p][c] += h[p][c];
                }
            }
        }
        let (mut change, mut norm) = (0.0, 0.0);
        for root in 0..self.segments.len() {
            let zero = vec![[0.0; 3]; k];
            self.push_pull(root, &zero, &mut change, &mut norm);
        }
        (change, norm)
    }

    /// One Gauss–Seidel sweep, a segment at a time in their order: the links into the
    /// segment's tree gather from the sources' B as it is now (the segments before it
    /// already swept), then the tree is pushed and pulled. Returns what [`Self::sweep`] does.
    fn sweep_gauss_seidel(&mut self) -> (f64, f64) {
        let k = self.k;
        for e in &mut self.elements {
            e.h.iter_mut().for_each(|v| *v = [0.0; 3]);
        }
        let mut into = vec![Vec::new(); self.segments.len()];
        for (i, l) in self.links.iter().enumerate() {
            into[self.elements[l.r].surface].push(i);
        }
        let (mut change, mut norm) = (0.0, 0.0);
        for (root, links) in into.iter().enumerate() {
            for &i in links {
                let l = &self.links[i];
                let out = l.transfer(&self.elements[l.s].b);
                let h = &mut self.elements[l.r].h;
                for (hp, o) in h.iter_mut().zip(&out) {
                    (0..3).for_each(|c| hp[c] += o[c]);
                }
            }
            let zero = vec![[0.0; 3]; k];
            self.push_pull(root, &zero, &mut change, &mut norm);
        }
        (change, norm)
    }

    fn push_pull(&mut self, e: usize, above: &[Rgb], change: &mut f64, norm: &mut f64) {
        let k = self.k;
        let total: Vec<Rgb> = (0..k)
            .map(|p| [0, 1, 2].map(|c| self.elements[e].h[p][c] + above[p][c]))
            .collect();
        match self.elements[e].children {
            None => {
                let rho = self.segments[self.elements[e].surface].material.reflectance;
                let el = &mut self.elements[e];
                for p in 0..k {
                    for c in 0..3 {
                        let new = el.e[p][c] + rho[c] * total[p][c];
                        *change += (new - el.b[p][c]).powi(2);
                        *norm += new * new;
                        el.b[p][c] = new;
                    }
                }
                el.h_total = total;
            }
            Some([a, b]) => {
                let (da, db) = (self.down(&total, 0), self.down(&total, 1));
                self.push_pull(a, &da, change, norm);
                self.push_pull(b, &db, change, norm);
                let up = self.up(&self.elements[a].b, &self.elements[b].b);
                self.elements[e].b = up;
            }
        }
    }

    fn solve(
        &mut self,
        settings: Settings,
        history: &mut Vec<f64>,
        progress: &dyn Progress,
    ) -> Result<bool, JobError> {
        for _ in 0..settings.max_iterations {
            progress.check()?;
            let (change, norm) = match settings.iteration {
                Iteration::Jacobi => self.sweep(),
                Iteration::GaussSeidel => self.sweep_gauss_seidel(),
            };
            let rel = if norm > 0.0 {
                (change / norm).sqrt()
            } else {
                change.sqrt()
            };
            history.push(rel);
            if !rel.is_finite() {
                return Err(SolveError::Diverged {
                    iteration: history.len(),
                    reason: "B is no longer finite".into(),
                }
                .into());
            }
            if history.len() > 50
                && history[history.len() - 50..]
                    .windows(2)
                    .all(|w| w[1] > w[0])
            {
                return Err(SolveError::Diverged {
                    iteration: history.len(),
                    reason: "the change between sweeps has grown for 50 sweeps".into(),
                }
                .into());
            }
            if rel < settings.tolerance {
                return Ok(true);
            }
        }
        Ok(false)
    }

    fn leaves_of(&self, surface: usize) -> Vec<usize> {
        let mut out = Vec::new();
        let mut stack = vec![surface];
        while let Some(e) = stack.pop() {
            match self.elements[e].children {
                None => out.push(e),
                Some([a, b]) => {
                    stack.push(b);
                    stack.push(a);
                }
            }
        }
        out
    }

    /// The links as a picture of the operator: on the grid of finest cells of all surfaces
    /// (receivers down, sources across), each link fills its block with the mean kernel value
    /// it carries, |T_00| / √(|r||s|), so the picture shows the interaction blocks of the
    /// hierarchy (coarse far away, fine near corners and shadows).
    fn picture(
        &self,
        resolution: usize,
        max_side: usize,
    ) -> crate::methods::compress::MagnitudePicture {
        let cells = |e: &Element| {
            let at = |x: f64| e.surface * resolution + (x * resolution as f64).round() as usize;
            at(e.range[0])..at(e.range[1])
        };
        let blocks = self.links.iter().map(|l| {
            let v = l.t[0].abs() / (self.length(l.r) * self.length(l.s)).sqrt();
            (cells(&self.elements[l.r]), cells(&self.elements[l.s]), v)
        });
        crate::methods::compress::block_picture(self.segments.len() * resolution, max_side, blocks)
    }

    /// A field per surface from the leaves' coefficients chosen by `pick`.
    fn fields(&self, resolution: usize, pick: impl Fn(&Element) -> &Vec<Rgb>) -> Vec<Field> {
        (0..self.segments.len())
            .map(|i| {
                let leaves = self
                    .leaves_of(i)
                    .into_iter()
                    .map(|e| {
                        let el = &self.elements[e];
                        let f = 1.0 / self.length(e).sqrt();
                        Leaf {
                            s: el.range,
                            t: [0.0, 1.0],
                            coeffs: pick(el).iter().map(|v| v.map(|x| x * f)).collect(),
                            upper: false,
                        }
                    })
                    .collect();
                Field::from_leaves(1, self.order, resolution, leaves)
            })
            .collect()
    }
}

/// Solves a flatland scene by hierarchical wavelet radiosity.
/// The document's settings that a flatland hierarchy needs besides order and resolution.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Tuning {
    /// Gauss points per element for the transfers.
    pub(crate) quadrature: usize,
    /// The oracle's tolerance, relative to the brightest emission.
    pub(crate) epsilon: f64,
    /// How many sorted coefficient magnitudes the result lists.
    pub(crate) coefficients: usize,
}

pub(crate) fn solve(
    segments: &[Segment],
    order: usize,
    resolution: usize,
    tuning: Tuning,
    settings: Settings,
    progress: &dyn Progress,
) -> Result<Solution, JobError> {
    let Tuning {
        quadrature,
        epsilon,
        coefficients,
    } = tuning;
    let start = Instant::now();
    let mut timings = BTreeMap::new();
    let mut h = Hierarchy::new(segments, order, resolution, quadrature, epsilon);
    progress.report(Phase::Refinement, 0.0);
    let roots = segments.len();
    for r in 0..roots {
        for s in 0..roots {
            progress.check()?;
            h.refine(r, s, true);
        }
    }
    h.within_budget()?;
    let mut evaluations = h.transfers(progress)?;
    let mut history = Vec::new();
    let mut converged = h.solve(settings, &mut history, progress)?;
    for pass in 0..MAX_PASSES {
        progress.check()?;
        progress.report(
            Phase::Refinement,
            (pass + 1) as f64 / (MAX_PASSES + 1) as f64,
        );
        if !h.rerefine() {
            break;
        }
        h.within_budget()?;
        h.refinements += 1;
        evaluations += h.transfers(progress)?;
        converged = h.solve(settings, &mut history, progress)?;
    }
    timings.insert("solve".to_string(), start.elapsed().as_secs_f64() * 1e3);
    progress.report(Phase::Solve, 1.0);
    let k = h.k;
    let leaves: usize = (0..roots).map(|i| h.leaves_of(i).len()).sum();
    let levels = h.elements.iter().map(|e| e.level).max().unwrap_or(0) as usize + 1;
    // the links' coefficients that are not zero (a pair of pieces at a right angle or in one
    // line has some): what the hierarchy keeps of the operator
    let mut mags: Vec<f64> = h
        .links
        .iter()
        .flat_map(|l| l.t.iter().map(|v| v.abs()))
        .filter(|v| *v > 0.0)
        .collect();
    mags.sort_by(|a, b| b.total_cmp(a));
    let ranks = crate::methods::compress::sample_ranks(mags.len(), coefficients);
    let magnitudes = ranks.iter().map(|&r| (r, mags[r])).collect();
    let stats = HierarchyStats {
        elements: h.elements.len(),
        leaves,
        links: h.links.len(),
        levels,
        refinements: h.refinements,
        rays: 0,
        min_element_size: None,
    };
    let picture = h.picture(resolution, 512);
    // Σ‖T‖² per pair of surfaces: each link is the orthogonal projection of K on its block
    // r × s, so eq. (5) follows by Parseval as for the projection method
    let mut kept_squares = vec![0.0; roots * roots];
    for l in &h.links {
        let (sr, ss) = (h.elements[l.r].surface, h.elements[l.s].surface);
        kept_squares[sr * roots + ss] += l.t.iter().map(|v| v * v).sum::<f64>();
    }
    let fields = h.fields(resolution, |e| &e.b);
    let emission = h.fields(resolution, |e| &e.e);
    let irradiance = h.fields(resolution, |e| &e.h_total);
    let residual = history.last().copied().unwrap_or(0.0);
    Ok(Solution {
        fields,
        shown: None,
        emission,
        irradiance,
        basis_size: leaves * k,
        matrix_entries: (leaves * k) * (leaves * k),
        kept_entries: mags.len(),
        cut: 0.0,
        magnitudes,
        picture: Some(picture),
        solved: Solved {
            b: Vec::new(),
            iterations: history.len(),
            residual,
            history,
            converged,
        },
        kernel_error: None,
        kernel_error_sampling: None,
        left_out: Vec::new(),
        hierarchy: Some(stats),
        timings,
        kept_squares,
        kernel_evaluations: Some(evaluations),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{parse_value, Limits, SceneKind};

    fn square() -> Vec<Segment> {
        let doc = serde_json::json!({"scene": {"kind": "flatland", "surfaces": [
            {"name": "a", "segment": [[0, 0], [1, 0]], "reflectance": 0.5, "emission": 1},
            {"name": "b", "segment": [[1, 0], [1, 1]], "reflectance": 0.5, "emission": 1},
            {"name": "c", "segment": [[1, 1], [0, 1]], "reflectance": 0.5, "emission": 1},
            {"name": "d", "segment": [[0, 1], [0, 0]], "reflectance": 0.5, "emission": 1}]}});
        match parse_value(&doc, &Limits::default()).unwrap().scene.kind {
            SceneKind::Flatland(s) => s,
            _ => unreachable!(),
        }
    }

    /// Every link set covers each pair of surfaces exactly once; when every link is between
    /// leaves, B = 1 in a closed room gathers H = 1 (∫K = 1) at every leaf.
    #[test]
    fn links_partition_the_interactions_and_conserve_energy() {
        let segs = square();
        let mut h = Hierarchy::new(&segs, 0, 4, 2, 1e-12);
        for r in 0..4 {
            for s in 0..4 {
                h.refine(r, s, true);
            }
        }
        h.transfers(&crate::progress::Silent).unwrap();
        for e in &mut h.elements {
            e.b = vec![[1.0; 3]];
        }
        for pass in 0..3 {
            // B = 1 everywhere, in every element's coefficients
            for i in 0..h.elements.len() {
                let len = h.length(i);
                h.elements[i].b = vec![[len.sqrt(); 3]];
            }
            let mut covered = [0.0; 16];
            for l in &h.links {
                let (er, es) = (&h.elements[l.r], &h.elements[l.s]);
                covered[er.surface * 4 + es.surface] +=
                    (er.range[1] - er.range[0]) * (es.range[1] - es.range[0]);
            }
            for i in 0..4 {
                for j in 0..4 {
                    let want = if i == j { 0.0 } else { 1.0 };
                    assert!(
                        (covered[i * 4 + j] - want).abs() < 1e-12,
                        "pass {pass} ({i},{j}): {}",
                        covered[i * 4 + j]
                    );
                }
            }
            assert!(h
                .links
                .iter()
                .all(|l| h.elements[l.r].children.is_none() && h.elements[l.s].children.is_none()));
            h.sweep();
            for i in 0..4 {
                for leaf in h.leaves_of(i) {
                    let hv = h.elements[leaf].h_total[0][0] / h.length(leaf).sqrt();
                    assert!(
                        (hv - 1.0).abs() < 1e-9,
                        "pass {pass} leaf {leaf} {:?}: H = {hv}",
                        h.elements[leaf].range
                    );
                }
            }
            for e in &mut h.elements {
                e.b = vec![[1.0; 3]];
            }
            h.rerefine();
            h.transfers(&crate::progress::Silent).unwrap();
        }
    }
}

#[cfg(test)]
mod transfer_check {
    use super::*;

    #[test]
    fn unequal_cells_agree_with_uniform_cells() {
        let segs = tests_square();
        let geo = Geometry::new(&segs);
        // floor [0, 1/16] against left wall [0.5, 1] (the corner is at the wall's t = 1)
        let pair = geo.pair(0, 3);
        let (fi, fj) = (pair.front_i.unwrap(), pair.front_j.unwrap());
        let mut big = [0.0];
        CellPair::between(&geo, (0, [0.0, 1.0 / 16.0]), (3, [0.5, 1.0]), 0, 2, pair)
            .integrate(fi, fj, &mut big);
        let mut sum = 0.0;
        for b in 8..16 {
            let mut t = [0.0];
            CellPair::between(
                &geo,
                (0, [0.0, 1.0 / 16.0]),
                (3, [b as f64 / 16.0, (b + 1) as f64 / 16.0]),
                0,
                2,
                pair,
            )
            .integrate(fi, fj, &mut t);
            // ∫∫K = T √(|r||s|)
            sum += t[0] * (1.0 / 16.0f64 * 1.0 / 16.0).sqrt();
        }
        let whole = big[0] * (1.0 / 16.0f64 * 0.5).sqrt();
        assert!((whole - sum).abs() < 1e-10 * sum, "{whole} vs {sum}");
    }

    fn tests_square() -> Vec<Segment> {
        let doc = serde_json::json!({"scene": {"kind": "flatland", "surfaces": [
            {"name": "a", "segment": [[0, 0], [1, 0]], "reflectance": 0.5, "emission": 1},
            {"name": "b", "segment": [[1, 0], [1, 1]], "reflectance": 0.5, "emission": 1},
            {"name": "c", "segment": [[1, 1], [0, 1]], "reflectance": 0.5, "emission": 1},
            {"name": "d", "segment": [[0, 1], [0, 0]], "reflectance": 0.5, "emission": 1}]}});
        match crate::scene::parse_value(&doc, &crate::scene::Limits::default())
            .unwrap()
            .scene
            .kind
        {
            crate::scene::SceneKind::Flatland(s) => s,
            _ => unreachable!(),
        }
    }
}
