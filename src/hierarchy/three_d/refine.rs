//! The refinement oracle and the links of hierarchical radiosity (Hanrahan, Salzman and
//! Aupperle 1991, "BF refinement"; Gortler et al. 1993 for higher orders).
//!
//! A candidate interaction from source S to receiver R is estimated, before any quadrature,
//! as the irradiance it carries times the part of it a polynomial of order m on the pair
//! cannot represent:
//!
//! ```text
//! err = ρ_R · B̄_S · F̂(R ← S) · (d / (d + dist))^(m+1)
//! ```
//!
//! with F̂ the largest point-to-piece form factor from a few points of R to S (in closed
//! form), d the larger diameter and dist the distance of the two pieces. A partly
//! visible pair loses the smoothness factor (a shadow edge is not a polynomial). When err is
//! above ε times the brightest emission, the larger element is split (down to the finest level
//! allowed) and its children are linked instead; otherwise the pair becomes a link whose k² × k²
//! block is integrated by [`crate::transfer`] and scaled by the visible fraction.

use super::tree::{push, Element, NONE};
use super::Hierarchy;
use crate::progress::{Cancelled, Progress};
use crate::projection::three_d::VISIBILITY_GRID;
use crate::space::{norm, quad_quad, sub};
use crate::transfer::{self, Integrand};
use crate::visibility3d::{pair_seed, Piece};
use rayon::prelude::*;

/// What the oracle makes of a pair.
#[derive(Debug, Clone, Copy)]
enum Verdict {
    /// Refine: split the larger element and judge its children against the other.
    Split,
    /// Accept as a link with this geometric factor and visible fraction.
    Link(f64, f64),
    /// Accept, but no ray got through: no link, unless the source brightens enough to
    /// refine the pair (the factor is kept for that).
    Hidden(f64),
}

/// An interaction from `src` to `recv`.
#[derive(Debug, Clone)]
pub struct Link {
    pub recv: u32,
    pub src: u32,
    /// The oracle's geometric factor: err = ρ_R B̄_S · geom.
    pub geom: f64,
    /// Visible fraction.
    pub visibility: f64,
    /// k² × k², row = receiver coefficient.
    pub block: Vec<f64>,
}

impl Hierarchy<'_> {
    /// A stable identity of an element (surface, level, cell) for seeding its rays.
    fn identity(&self, e: u32) -> u64 {
        let el = &self.elements[e as usize];
        ((el.piece.surface as u64) << 48)
            | ((el.level as u64) << 40)
            | ((el.cell[1] as u64) << 20)
            | el.cell[0] as u64
    }

    /// (F̂, smoothness factor) of the oracle. F̂ is the largest unoccluded form factor from a
    /// point of the receiver to the whole source piece, in closed form
    /// ([`transfer::point_polygon`], clipped to the point's horizon) at a 3 × 3 grid of points
    /// that reaches the receiver's edges: the part of a source that a receiver sees may be a
    /// thin strip next to their common line (the floor in front of a box), which interior
    /// samples miss.
    fn estimate(&self, r: u32, s: u32) -> (f64, f64) {
        let (er, es) = (&self.elements[r as usize], &self.elements[s as usize]);
        let qr = &self.geo.quads[er.piece.surface];
        let qs = &self.geo.quads[es.piece.surface];
        let ca = qr.piece(er.piece.s, er.piece.t);
        let cb = qs.piece(es.piece.s, es.piece.t);
        const AT: [f64; 3] = [0.01, 0.5, 0.99];
        let p = &er.piece;
        let mut f: f64 = 0.0;
        for v in AT {
            for u in AT {
                let x = qr.at(
                    p.s[0] + u * (p.s[1] - p.s[0]),
                    p.t[0] + v * (p.t[1] - p.t[0]),
                );
                // a point behind the source's plane receives nothing from it
                if qs.side(x) > 0.0 {
                    f = f.max(transfer::point_polygon(x, qr.n, &cb));
                }
            }
        }
        let size = norm(sub(ca[2], ca[0])).max(norm(sub(cb[2], cb[0])));
        let dist = quad_quad(&ca, qr.n, &cb, qs.n);
        (f, (size / (size + dist)).powi(self.k as i32))
    }

    /// Splits element `e` into four if it has no children yet; B of the children is the
    /// parent's B restricted to them.
    pub(super) fn split(&mut self, e: u32) -> u32 {
        if self.elements[e as usize].children != NONE {
            return self.elements[e as usize].children;
        }
        self.refinements += 1;
        let first = self.elements.len() as u32;
        let parent = self.elements[e as usize].clone();
        let kk = self.k * self.k;
        for dt in 0..2 {
            for ds in 0..2 {
                let p = parent.piece;
                let ms = 0.5 * (p.s[0] + p.s[1]);
                let mt = 0.5 * (p.t[0] + p.t[1]);
                let piece = Piece {
                    surface: p.surface,
                    s: if ds == 0 { [p.s[0], ms] } else { [ms, p.s[1]] },
                    t: if dt == 0 { [p.t[0], mt] } else { [mt, p.t[1]] },
                };
                let mut b = vec![[0.0; 3]; kk];
                push(self.filters, &parent.b, dt, ds, &mut b);
                let mut e_coeffs = vec![[0.0; 3]; kk];
                let quad = &self.quads[p.surface];
                crate::projection::three_d::piece_emission(
                    quad,
                    self.geo.quads[p.surface].area,
                    piece,
                    self.k,
                    &mut e_coeffs,
                );
                let peak = peak_emission(quad, piece);
                self.elements.push(Element {
                    peak,
                    piece,
                    level: parent.level + 1,
                    cell: [
                        2 * parent.cell[0] + ds as u32,
                        2 * parent.cell[1] + dt as u32,
                    ],
                    parent: e,
                    children: NONE,
                    area: parent.area / 4.0,
                    e: e_coeffs,
                    b,
                    h: vec![[0.0; 3]; kk],
                });
            }
        }
        self.elements[e as usize].children = first;
        first
    }

    fn splittable(&self, e: u32) -> bool {
        self.elements[e as usize].level < self.max_level
    }

    /// The oracle's verdict on one pair, with the element tree as it is: read-only, so that
    /// a whole frontier of pairs is judged in parallel (the rays are most of the work).
    fn judge(&self, r: u32, s: u32) -> (Verdict, u64) {
        let rho = self.rho[self.elements[r as usize].piece.surface];
        let b = self.elements[s as usize].brightness();
        let (f, smooth) = self.estimate(r, s);
        let thr = self.threshold;
        let can = self.splittable(r) || self.splittable(s);
        if can && rho * b * f * smooth > thr {
            return (Verdict::Split, 0);
        }
        let (pr, ps) = (
            self.elements[r as usize].piece,
            self.elements[s as usize].piece,
        );
        let seed = pair_seed(self.identity(r), self.identity(s));
        let mut rays = 0;
        // a link between big pieces carries much of the light, and its visible fraction
        // is an average over a large, varied set of rays: more rays for the top levels
        // (there are few such pairs, so they cost little)
        let top = self.elements[r as usize]
            .level
            .min(self.elements[s as usize].level);
        let grid = VISIBILITY_GRID << 2u32.saturating_sub(top);
        let v = self.geo.visibility(pr, ps, seed, grid, &mut rays);
        // partly visible, or hidden as far as the few sampled rays can tell (a big pair's
        // light may pass through a gap none of them found): no smoothness credit
        let geom = if v < 1.0 { f } else { f * smooth };
        if can && rho * b * geom > thr {
            return (Verdict::Split, rays);
        }
        if v > 0.0 {
            (Verdict::Link(geom, v), rays)
        } else {
            (Verdict::Hidden(geom), rays)
        }
    }

    /// Refines the interactions `pairs` (receiver, source) top-down, appending the accepted
    /// (recv, src, geom, V) to `out` in a fixed order. Each level's pairs are judged in
    /// parallel; the splits they ask for are then made in order, so the elements are numbered
    /// the same on every run.
    pub(super) fn refine_all(
        &mut self,
        mut pairs: Vec<(u32, u32)>,
        out: &mut Vec<(u32, u32, f64, f64)>,
        progress: &dyn Progress,
    ) -> Result<(), Cancelled> {
        while !pairs.is_empty() {
            progress.check()?;
            let verdicts: Vec<(Verdict, u64)> =
                pairs.par_iter().map(|&(r, s)| self.judge(r, s)).collect();
            let mut next = Vec::new();
            for (&(r, s), (verdict, rays)) in pairs.iter().zip(verdicts) {
                self.rays += rays;
                match verdict {
                    Verdict::Split => {
                        let split_r = self.splittable(r)
                            && (!self.splittable(s)
                                || self.elements[r as usize].area
                                    >= self.elements[s as usize].area);
                        if split_r {
                            let c = self.split(r);
                            next.extend((0..4).map(|i| (c + i, s)));
                        } else {
                            let c = self.split(s);
                            next.extend((0..4).map(|i| (r, c + i)));
                        }
                    }
                    Verdict::Link(geom, v) => out.push((r, s, geom, v)),
                    Verdict::Hidden(geom) => self.hidden.push((r, s, geom)),
                }
            }
            pairs = next;
        }
        Ok(())
    }

    /// Integrates the blocks of accepted pairs, in parallel.
    pub(super) fn make_links(
        &self,
        pending: &[(u32, u32, f64, f64)],
        progress: &dyn Progress,
    ) -> Result<Vec<Link>, Cancelled> {
        let kk = self.k * self.k;
        pending
            .par_iter()
            .map(|&(recv, src, geom, visibility)| {
                progress.check()?;
                let mut block = vec![0.0; kk * kk];
                let (a, b) = (
                    self.elements[recv as usize].piece,
                    self.elements[src as usize].piece,
                );
                let evaluations = transfer::block(
                    &self.geo.quads,
                    a,
                    b,
                    Integrand::Galerkin { k: self.k },
                    self.accuracy,
                    &mut block,
                );
                self.evaluations
                    .fetch_add(evaluations, std::sync::atomic::Ordering::Relaxed);
                block.iter_mut().for_each(|v| *v *= visibility);
                Ok(Link {
                    recv,
                    src,
                    geom,
                    visibility,
                    block,
                })
            })
            .collect()
    }
}

/// The largest emission channel of `quad` if `piece` overlaps its emission region, else 0.
pub fn peak_emission(quad: &crate::scene::Quad, piece: Piece) -> f64 {
    let (rs, rt) = quad.emission_region;
    let overlaps =
        piece.s[0] < rs[1] && rs[0] < piece.s[1] && piece.t[0] < rt[1] && rt[0] < piece.t[1];
    if overlaps {
        quad.material.emission.iter().copied().fold(0.0, f64::max)
    } else {
        0.0
    }
}
