//! The refinement oracle and the links of hierarchical radiosity (Hanrahan, Salzman and
//! Aupperle 1991, "BF refinement"; Gortler et al. 1993 for higher orders).
//!
//! A candidate interaction from source S to receiver R is estimated, before any quadrature,
//! as the irradiance it carries times the part of it a polynomial of order m on the pair
//! cannot represent, plus what reading the source's B as one polynomial loses:
//!
//! ```text
//! err = w_RS · ρ_R · F̂(R ← S) · (B̄_S · (d / (d + dist))^(m+1) + D_S)
//! ```
//!
//! with F̂ the largest point-to-piece form factor from a few points of R to S (in closed
//! form), d the larger diameter and dist the distance of the two pieces, and D_S the root mean
//! square of B on S minus its polynomial there (the wavelet detail below S). A partly visible
//! pair loses the smoothness factor (a shadow edge is not a polynomial), and so does a pair all
//! of whose rays got through when something that may come between the two lies near the
//! receiver, within its diameter ([`Rules::near_occluders`]); and so does a receiver
//! along a line where another surface stands on its surface, when anything may come between it
//! and S; such a pair is judged against a share of the tolerance
//! ([`Rules::contact_share`]), before any ray,
//! and split on the receiver's side whatever the two pieces' sizes (the error lies on the
//! receiver; a source split into pieces sends it through their links, each under the share and
//! all of one sign). A pair none of whose n rays got through takes 3/n for the factor, the
//! rays' bound on what they missed ([`crate::three_d::visibility::unseen_bound`]). w_RS = 1
//! when S emits; for inter-reflected light it is the inverse of S's share of R's tolerance
//! ([`super::tolerance`]): R gathers from all its sources and their errors add up with one
//! sign (a coarse link averages a source's bright spot over a kernel that peaks at it, so it
//! carries too little: with w = 1 every surface of the Cornell box came out 1–3 % low). When err is
//! above ε times the brightest emission (less on a dim receiver, [`super::tolerance`]), an
//! element is split (down to the
//! finest level allowed: the source when D_S is most of the error, else the larger, except that
//! a receiver coarser than [`Rules::receiver_first_level`] goes first, and only where the
//! split lowers the estimate: `Hierarchy::splits`) and its children are linked instead;
//! otherwise the pair becomes a link whose k² × k² block is integrated by [`crate::three_d::transfer`]
//! and scaled by the visible fraction. That fraction comes from rays that did not judge the
//! pair: the verdict depends on its rays (a pair all of whose rays passed is accepted where
//! a partly visible one is split), so the judging rays' fraction is biased over the accepted
//! links, and always the same way. Bars 4 cm wide across a window that the rays of a pair
//! happened to miss made the far wall 2.6 % bright (`tests/path_traced.rs`); fresh rays are
//! independent of the verdict, and their fraction is not. Once B is known, each fresh ray
//! is weighted by the source's B where it ends ([`Hierarchy::light_at`]): the fraction is the
//! share of the light that is not stopped, as a cluster link's is, because the part of a
//! source that an occluder hides from a receiver is most often in the occluder's shadow too.
//! The same rays weigh what D_S leaves out: a link carries its source's polynomial, and
//! its block is scaled by the ratio of the light that the source's leaves send along the
//! rays to what that polynomial sends along them ([`crate::three_d::visibility::Seen`]'s
//! `detail`), since the kernel peaks where the light is and each link's shortfall, within
//! its estimate, shares its sign with those of the other links into the receiver.
//! The partly visible links made before the first solve carry the judging rays' fraction
//! through it, and take the share of the light from fresh rays after it.
//!
//! Each estimate bounds one link; the errors of partly visible links add up where their
//! shadows fall together, and [`super::shadows`] holds their sum on each leaf to the leaf's
//! tolerance after every solve.

use super::clustered::{ClusterLink, ClusterVerdict};
use super::links::Links;
use super::shadows::Cells;
use super::tree::{push, Element, NONE};
use super::{Hierarchy, Overrun};
use crate::math::basis::legendre;
use crate::progress::{Cancelled, Progress};
use crate::scene::Rgb;
use crate::three_d::cluster::is_cluster;
use crate::three_d::congruence::{Congruence, Labels};
use crate::three_d::cover::Exposure;
use crate::three_d::geometry::Piece;
use crate::three_d::geometry::{add, dot, norm, normalize, quad_quad, scale, sub};
use crate::three_d::projection::VISIBILITY_GRID;
#[cfg(doc)]
use crate::three_d::rules::Rules;
use crate::three_d::steps::{Steps, STEP};
use crate::three_d::transfer::{self, Integrand};
use crate::three_d::visibility::{
    pair_seed, unseen_bound, visible_fraction_over, visible_share_of_light, Occluders, Seen,
};
use rayon::prelude::*;

/// What one pair of the frontier holds beyond its chunk: itself, and up to four pairs of the
/// next level made by its split.
pub(super) const PAIR_BYTES: usize = 5 * std::mem::size_of::<(u32, u32)>();

/// Whether the triangle with vertices `v` (in a surface's (s, t)) holds the point (s, t),
/// its edges included.
fn holds(v: [[f64; 2]; 3], s: f64, t: f64) -> bool {
    let side = |p: [f64; 2], q: [f64; 2]| (q[0] - p[0]) * (t - p[1]) - (q[1] - p[1]) * (s - p[0]);
    let d = [side(v[0], v[1]), side(v[1], v[2]), side(v[2], v[0])];
    !(d.iter().any(|&x| x < -1e-12) && d.iter().any(|&x| x > 1e-12))
}

/// The geometric part of the oracle's estimate for one pair (in single precision: every link
/// keeps it, and an estimate needs no more).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Factors {
    /// F̂: the largest point-to-piece form factor from the receiver to the source.
    f: f32,
    /// (d / (d + dist))^(m+1); 1 when the pair is partly visible, at a contact line or with an
    /// occluder near its receiver; 3/n when none of its n rays got through.
    smooth: f32,
    /// Whether the receiver touches a contact line and something may come between it and
    /// the source ([`Rules::contact_share`]).
    pub(super) contact: bool,
    /// Linked before B was known with a visible fraction below 1, the share of the rays
    /// rather than of the light: the side of the grid of fresh rays that take its fraction
    /// again, weighted by the light, after the first solve ([`Hierarchy::share_of_light`]).
    pub(super) unlit: Option<u8>,
    /// The visible fraction on each step cell, where it varies over the receiver: the
    /// shadow budget's ([`super::shadows`]).
    pub(super) shadow: Option<Cells>,
}

/// What the oracle makes of a pair.
#[derive(Debug, Clone, Copy)]
enum Verdict {
    /// Refine: split an element and judge its children against the other; the source
    /// first when its own variation is most of the error.
    Split { source: bool },
    /// Refine on the receiver's side whatever the two pieces' sizes: the contact lines'
    /// split ([`Rules::contact_share`]). The error it bounds lies on the receiver (its points
    /// next to the line see less of the source than rays from inside it can tell), so
    /// splitting the source would leave it where it was: the pieces' form factors add up to
    /// the whole's, and so do their errors, with one sign.
    SplitReceiver,
    /// Accept as a link with these factors and visible fractions.
    Link(Factors, Seen),
    /// Drop, without rays: the receiver is covered (it receives nothing), or the source is
    /// covered and does not emit (it sends nothing).
    Inert,
    /// Accept, but no ray got through: no link, unless the source brightens enough to
    /// refine the pair (the factors are kept for that).
    Hidden(Factors),
}

/// An interaction from `src` to `recv`; its k² × k² block (row = receiver coefficient, the
/// visible fraction in it) is kept beside it in [`Links`].
#[derive(Debug, Clone, Copy)]
pub(super) struct Link {
    pub(super) recv: u32,
    pub(super) src: u32,
    /// The oracle's geometric factors, to judge the link again as B changes.
    pub(super) factors: Factors,
}

impl Hierarchy<'_> {
    /// A stable identity of an element (surface, level, cell) for seeding its rays.
    pub(super) fn identity(&self, e: u32) -> u64 {
        let el = &self.elements[e as usize];
        ((el.piece.surface as u64) << 48)
            | ((el.level as u64) << 40)
            | (u64::from(el.piece.upper) << 39)
            | ((el.cell[1] as u64) << 20)
            | el.cell[0] as u64
    }

    /// (F̂, smoothness factor) of the oracle. F̂ is the largest unoccluded form factor from a
    /// point of the receiver to the whole source piece, in closed form
    /// ([`transfer::point_polygon`], clipped to the point's horizon) at a 3 × 3 grid of points
    /// that reaches the receiver's edges: the part of a source that a receiver sees may be a
    /// thin strip next to their common line (the floor in front of a box), which interior
    /// samples miss; and at the source's corners and centre projected onto the receiver
    /// (under a small source close in front of a large receiver the form factor peaks at up
    /// to 1 between the grid's points; in front of a box's face standing on or just above a
    /// floor element, at up to ½).
    fn estimate(&self, r: u32, s: u32) -> (f64, f64) {
        let (er, es) = (&self.elements[r as usize], &self.elements[s as usize]);
        let qr = &self.geo.quads[er.piece.surface];
        let qs = &self.geo.quads[es.piece.surface];
        let ca = er.piece.corners(&self.geo.quads);
        let cb = es.piece.corners(&self.geo.quads);
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
        // and under the source: its corners and centre projected onto the receiver's plane,
        // clamped into the receiver. A small source close in front of a large receiver (the
        // bottom of a box 2 cm above a floor) peaks at up to 1 under itself, between the grid's
        // points. Where the source meets or nears the receiver's plane at an angle (a wall
        // standing inside a floor element, its foot perhaps the grid's middle line, in the
        // wall's plane; the side of a box 2 cm above a floor), the point under its lower edge
        // lies in the source's own plane, where the form factor is 0, while the strip just in
        // front of it sees the source with up to ½: so for every source at an angle to the
        // receiver the points are moved a hundredth of the receiver's size along the source's
        // normal, onto its front side
        // (a triangle's corners repeat its third)
        let n = if cb[2] == cb[3] { 3 } else { 4 };
        let along = sub(qs.n, scale(qr.n, dot(qs.n, qr.n)));
        let diameter = transfer::diameter(&ca);
        let nudge = if norm(along) > 1e-9 {
            scale(normalize(along), 0.01 * diameter)
        } else {
            [0.0; 3]
        };
        let centre = scale(
            cb[..n].iter().fold([0.0; 3], |a, &c| add(a, c)),
            1.0 / n as f64,
        );
        for c in cb[..n].iter().copied().chain([centre]) {
            let (cs, ct) = qr.params(add(sub(c, scale(qr.n, qr.side(c))), nudge));
            let x = qr.at_clamped(p, cs, ct);
            if qs.side(x) > 0.0 {
                f = f.max(transfer::point_polygon(x, qr.n, &cb));
            }
        }
        let size = diameter.max(transfer::diameter(&cb));
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
        if self.geo.quads[parent.piece.surface].tri {
            self.split_triangle(&parent);
            self.elements[e as usize].children = first;
            return first;
        }
        for dt in 0..2 {
            for ds in 0..2 {
                let p = parent.piece;
                let piece = p.child(false, 2 * dt + ds);
                let mut b = vec![[0.0; 3]; kk];
                push(self.filters, &parent.b, dt, ds, &mut b);
                let mut e_coeffs = vec![[0.0; 3]; kk];
                let quad = &self.quads[p.surface];
                crate::three_d::projection::piece_emission(
                    quad,
                    self.geo.quads[p.surface].area,
                    piece,
                    self.k,
                    &mut e_coeffs,
                );
                let peak = peak_emission(quad, piece);
                let exposure = match (&parent.exposure, &self.masks[p.surface]) {
                    (Exposure::Partial(_), Some(m)) => m.exposure_of(&piece, false, self.k),
                    (e, _) => e.clone(),
                };
                self.elements.push(Element {
                    exposure,
                    peak,
                    piece,
                    level: parent.level + 1,
                    cell: [
                        2 * parent.cell[0] + ds as u32,
                        2 * parent.cell[1] + dt as u32,
                    ],
                    children: NONE,
                    area: parent.area / 4.0,
                    e: e_coeffs,
                    b,
                    h: vec![[0.0; 3]; kk],
                    detail: 0.0,
                });
            }
        }
        self.elements[e as usize].children = first;
        first
    }

    /// The four children of the midpoint split of a triangle element, in the order of
    /// [`crate::math::triangle::CHILDREN`], with B pushed exactly by the triangle basis' two-
    /// scale relation.
    fn split_triangle(&mut self, parent: &Element) {
        let kk = self.k * self.k;
        let basis = self.tri_basis;
        let quad = &self.quads[parent.piece.surface];
        for c in 0..4 {
            let piece = parent.piece.tri_child(c);
            let mut b = vec![[0.0; 3]; kk];
            basis.push(&parent.b, c, &mut b);
            let mut e = vec![[0.0; 3]; kk];
            crate::three_d::projection::piece_emission(
                quad,
                self.geo.quads[piece.surface].area,
                piece,
                self.k,
                &mut e,
            );
            let at = |x: f64| (x * f64::from(1u32 << (parent.level + 1))).round() as u32;
            let exposure = match (&parent.exposure, &self.masks[piece.surface]) {
                (Exposure::Partial(_), Some(m)) => m.exposure_of(&piece, true, self.k),
                (e, _) => e.clone(),
            };
            self.elements.push(Element {
                exposure,
                peak: peak_emission(quad, piece),
                piece,
                level: parent.level + 1,
                cell: [at(piece.s[0]), at(piece.t[0])],
                children: NONE,
                area: parent.area / 4.0,
                e,
                b,
                h: vec![[0.0; 3]; kk],
                detail: 0.0,
            });
        }
    }

    /// Whether the kernel from source `s` reaches the covered part of receiver `r`: only
    /// then is the block's irradiance, a polynomial over all of `r`, read off its exposed
    /// part by the masked Gram matrix.
    fn sends_to_covered(&self, r: u32, s: u32) -> bool {
        let p = self.elements[r as usize].piece;
        let source = &self.geo.quads[self.elements[s as usize].piece.surface];
        self.masks[p.surface]
            .as_ref()
            .is_some_and(|m| !m.covered_behind(&self.geo.quads[p.surface], p.s, p.t, source))
    }

    /// Whether element `e` touches a line where another surface stands on its surface.
    fn at_contact(&self, e: u32) -> bool {
        let p = self.elements[e as usize].piece;
        self.contacts[p.surface]
            .iter()
            .any(|line| crate::three_d::cover::meets(line, p.s, p.t))
    }

    /// The visible fraction of the pair (`r`, `s`) from a fresh `n` × `n` grid of rays,
    /// independent of the rays that judged it, each weighted by the source's B where it ends
    /// ([`visible_share_of_light`], [`Hierarchy::light_at`]), and the ratio of that light to
    /// the polynomial that `s` sends, which a link carries (the `detail` of [`Seen`]);
    /// `occluders` are the pair's ([`Geometry::occluders`], `None` to find them).
    pub(super) fn share_of_light(
        &self,
        r: u32,
        s: u32,
        n: usize,
        occluders: Option<&Occluders>,
        rays: &mut u64,
    ) -> Seen {
        let (pr, ps) = (
            self.elements[r as usize].piece,
            self.elements[s as usize].piece,
        );
        let sent = self.sending(s);
        let found;
        let occluders = match occluders {
            Some(o) => o,
            None => {
                found = self.geo.occluders(pr, ps);
                &found
            }
        };
        visible_share_of_light(
            occluders,
            pr,
            self.masks[pr.surface].as_ref(),
            ps,
            n,
            pair_seed(self.identity(r), self.identity(s)) ^ 2,
            rays,
            &|s_, t_| self.light_at(s, s_, t_),
            // a leaf's light is the polynomial it sends: no ratio to take
            (!self.elements[s as usize].is_leaf())
                .then_some(&|s_: f64, t_: f64| self.value_at(s, &sent, s_, t_)),
        )
    }

    /// The radiosity (mean of the channels) at (s, t) of the surface of element `e`, as far as
    /// the tree below `e` knows it: the polynomial that the leaf that holds the point sends,
    /// or where the point is covered, the polynomial that `e` sends (a partly covered element
    /// sends its polynomial over the whole of it, and the rays take the covered part out). The
    /// weight of a ray's end in a link's visible fraction ([`visible_share_of_light`]); at
    /// least a tiny positive number, so that a dark source still has a fraction. A leaf's
    /// polynomial, not its mean: on a source that is a leaf, the light is then the polynomial
    /// the link carries, and their ratio is 1.
    pub(super) fn light_at(&self, e: u32, s: f64, t: f64) -> f64 {
        let surface = self.elements[e as usize].piece.surface;
        let covered = self.masks[surface]
            .as_ref()
            .is_some_and(|m| m.covered(s, t));
        let at = if covered { e } else { self.leaf_at(e, s, t) };
        self.value_at(at, &self.sending(at), s, t)
            .max(f64::MIN_POSITIVE)
    }

    /// The coefficients of the polynomial that element `e` sends ([`Element::sent`]): its B,
    /// unless a solid partly covers it.
    fn sending(&self, e: u32) -> std::borrow::Cow<'_, [Rgb]> {
        let el = &self.elements[e as usize];
        if let Exposure::Partial(_) = el.exposure {
            let mut sent = vec![[0.0; 3]; el.b.len()];
            el.sent(&mut sent);
            sent.into()
        } else {
            el.b.as_slice().into()
        }
    }

    /// The value at (s, t) (mean of the channels) of the polynomial with coefficients `c`
    /// on element `e`. Once or twice per ray of a link's fraction: summed as it goes, with
    /// no array of the basis' values (filling one of the highest order's 81 per call made the
    /// room with 3 × 3 boxes' job 7 % slower).
    fn value_at(&self, e: u32, c: &[Rgb], s: f64, t: f64) -> f64 {
        let el = &self.elements[e as usize];
        let mean = |c: &Rgb| (c[0] + c[1] + c[2]) / 3.0;
        let sum: f64 = if self.geo.quads[el.piece.surface].tri {
            let (u, v) = el.piece.local(s, t);
            let n = crate::math::triangle::dimension(self.k - 1);
            let mut phi = [0.0; 16];
            self.tri_basis.eval(u, v, &mut phi[..n]);
            phi[..n].iter().zip(c).map(|(p, c)| p * mean(c)).sum()
        } else {
            let (k, p) = (self.k, el.piece);
            let (mut ps, mut pt) = ([0.0; transfer::MAX_K], [0.0; transfer::MAX_K]);
            legendre((s - p.s[0]) / (p.s[1] - p.s[0]), &mut ps[..k]);
            legendre((t - p.t[0]) / (p.t[1] - p.t[0]), &mut pt[..k]);
            (0..k)
                .map(|q| pt[q] * (0..k).map(|i| ps[i] * mean(&c[q * k + i])).sum::<f64>())
                .sum()
        };
        sum / el.area.sqrt()
    }

    /// The radiosity (mean of the channels) at (s, t) of the surface of element `e`, as far
    /// as the tree below `e` knows it: the mean of the leaf that holds the point, or where the
    /// point is covered, the mean of what `e` sends there.
    pub(super) fn radiosity_at(&self, e: u32, s: f64, t: f64) -> f64 {
        let source = &self.elements[e as usize];
        let surface = source.piece.surface;
        if self.masks[surface]
            .as_ref()
            .is_some_and(|m| m.covered(s, t))
        {
            return source.mean_of(&[source.sent0()]);
        }
        let leaf = &self.elements[self.leaf_at(e, s, t) as usize];
        leaf.mean_of(&leaf.b)
    }

    /// The leaf under element `e` that holds (s, t) of its surface.
    fn leaf_at(&self, e: u32, s: f64, t: f64) -> u32 {
        let tri = self.geo.quads[self.elements[e as usize].piece.surface].tri;
        let mut e = e;
        loop {
            let el = &self.elements[e as usize];
            if el.children == NONE {
                return e;
            }
            e = if tri {
                (el.children..el.children + 4)
                    .find(|&c| holds(self.elements[c as usize].piece.triangle(), s, t))
                    .unwrap_or(el.children)
            } else {
                let ds = u32::from(s >= 0.5 * (el.piece.s[0] + el.piece.s[1]));
                let dt = u32::from(t >= 0.5 * (el.piece.t[0] + el.piece.t[1]));
                el.children + 2 * dt + ds
            };
        }
    }

    /// Whether receiver `r` is above the level of [`Rules::receiver_first_level`] at this
    /// order: split before its source when a pair is over the tolerance through the kernel's
    /// variation.
    fn coarse(&self, r: u32) -> bool {
        self.elements[r as usize].level < self.rules.receiver_first(self.k - 1)
    }

    pub(super) fn splittable(&self, e: u32) -> bool {
        self.elements[e as usize].level < self.finest(e)
    }

    /// Whether a pair whose estimate is (`kernel`, `detail`) against the tolerance `limit`
    /// is split, and on which side (true: the source). A split is made only where it lowers
    /// the estimate. Splitting the receiver always may (its polynomial gets finer). Splitting
    /// the source lowers the detail part (its children read B finer), but the kernel part
    /// only while the source is the larger piece: the estimate's size factor is the larger
    /// diameter, and its children's F̂ add up to the parent's. So once the receiver is at its
    /// finest level and the source is no larger, a pair whose error is the kernel's is
    /// linked at the error that `min_element_size` allows: splitting the source would turn
    /// one link into four with the same error at the receiver, and at a contact line, where
    /// F̂ does not fall as pieces shrink, into as many links as there are elements near it.
    pub(super) fn splits(
        &self,
        r: u32,
        s: u32,
        kernel: f64,
        detail: f64,
        limit: f64,
    ) -> Option<bool> {
        if kernel + detail <= limit {
            return None;
        }
        if self.splittable(r) {
            return Some(detail > kernel);
        }
        let larger = self.elements[s as usize].area > self.elements[r as usize].area;
        (self.splittable(s) && (larger || detail > kernel)).then_some(true)
    }

    /// The oracle's estimate of the error of a link from `s` to `r`, in two parts: what the
    /// kernel's variation over the pair costs (B̄_S carried by a transfer that a polynomial
    /// of order m on the pair misses), and what the source's own variation below its level
    /// costs (a link reads the source's B as one polynomial: a bright spot in a dim surface
    /// is spread over it, and the kernel's peak, which sits where light is, loses it).
    pub(super) fn error(&self, r: u32, s: u32, x: Factors) -> (f64, f64) {
        let rho = self.rho[self.elements[r as usize].piece.surface];
        let es = &self.elements[s as usize];
        let w = if es.peak > 0.0 {
            1.0
        } else {
            self.indirect
                .between(self.elements[r as usize].piece.surface, es.piece.surface)
        };
        (
            w * rho * es.brightness() * f64::from(x.f) * f64::from(x.smooth),
            w * rho * es.detail * f64::from(x.f),
        )
    }

    /// The oracle's verdict on one pair, with the element tree as it is: read-only, so that
    /// a whole frontier of pairs is judged in parallel (the rays are most of the work).
    fn judge(&self, r: u32, s: u32, (f, smooth): (f64, f64)) -> (Verdict, u64) {
        if !self.elements[r as usize].receives() || !self.elements[s as usize].sends() {
            return (Verdict::Inert, 0);
        }
        let thr = self.tolerance(r);
        let split = |x: Factors| {
            let (kernel, detail) = self.error(r, s, x);
            self.splits(r, s, kernel, detail, thr)
                .map(|source| Verdict::Split { source })
        };
        let unsure = Factors {
            f: f as f32,
            smooth: smooth as f32,
            contact: false,
            unlit: None,
            shadow: None,
        };
        if let Some(v) = split(unsure) {
            return (v, 0);
        }
        let (pr, ps) = (
            self.elements[r as usize].piece,
            self.elements[s as usize].piece,
        );
        // a receiver along a line where another surface stands on it gets no smoothness
        // credit when something may come between it and the source (that surface, most
        // often), and only a share of the tolerance: the points next to the line see less of
        // the source than rays from inside the receiver can tell. The receiver is split,
        // even when it is the smaller of the two: its error is on its side, and a source
        // split into pieces would send it to the line through their links, each under the
        // share and all with one sign (the gallery's small cube came out 1.9 % bright from
        // the walls' light at its foot that way). No rays are needed to decide that
        let occluders = self.geo.occluders(pr, ps);
        let clear = occluders.clear();
        let at_line = !clear && self.at_contact(r);
        let contact = self.rules.contact_share < 1.0 && at_line;
        if contact && self.splittable(r) {
            let (kernel, detail) = self.error(
                r,
                s,
                Factors {
                    f: f as f32,
                    smooth: 1.0,
                    contact,
                    unlit: None,
                    shadow: None,
                },
            );
            if kernel + detail > self.rules.contact_share * thr {
                return (Verdict::SplitReceiver, 0);
            }
        }
        let seed = pair_seed(self.identity(r), self.identity(s));
        let mut rays = 0;
        // a link between big pieces carries much of the light, and its visible fraction
        // is an average over a large, varied set of rays: more rays for the top levels, as
        // far as both pieces still have levels below them (a mesh's triangles are the top
        // level of their own patches, and most are as small as the finest elements: there
        // are many such pairs, and each carries little)
        let (el_r, el_s) = (&self.elements[r as usize], &self.elements[s as usize]);
        let below = (self.finest(r) - el_r.level).min(self.finest(s) - el_s.level);
        let top = el_r.level.min(el_s.level).max(2u32.saturating_sub(below));
        let grid = VISIBILITY_GRID << 2u32.saturating_sub(top);
        let mask = self.masks[pr.surface].as_ref();
        let mut v = if clear {
            Seen::CLEAR
        } else {
            visible_fraction_over(&occluders, pr, mask, ps, grid, seed, &mut rays)
        };
        // a partly visible pair's fresh rays are cast on the finer grid that puts four in
        // each step cell of the receiver, so that its visible fraction is a step over those
        // cells rather than over the quarters (a constant, at order 0, gains nothing from it). The judging rays have shown it partly visible, all that its verdict
        // reads: more of them would not change it (a finer grid that happened to find it
        // clear would only give it a smoothness credit that the first rays disproved)
        let fine = 2 * STEP;
        let partial = v.whole > 0.0 && v.whole < 1.0;
        let used = if self.k > 1 && partial {
            grid.max(fine)
        } else {
            grid
        };
        // all rays through, but something that may come between the two lies near the
        // receiver, apart from any line where it stands on it (the contact lines' error):
        // no smoothness credit either ([`Rules::near_occluders`]), as its shadow on the
        // receiver may be as narrow as their distance
        let near = v.whole >= 1.0
            && !clear
            && !at_line
            && self.rules.near_occluders > 0.0
            && self.geo.occluder_near(
                pr,
                ps,
                self.rules.near_occluders * transfer::diameter(&pr.corners(&self.geo.quads)),
            );
        // partly visible: no smoothness credit. Hidden as far as the sampled rays can tell: a
        // big pair's light may pass through a gap none of them found, but no more of it than
        // the rays' bound on what they missed ([`unseen_bound`])
        let x = Factors {
            f: f as f32,
            smooth: if v.whole <= 0.0 && !contact {
                unseen_bound(rays) as f32
            } else if v.whole < 1.0 || contact || near {
                1.0
            } else {
                smooth as f32
            },
            contact,
            unlit: None,
            shadow: None,
        };
        if let Some(v) = split(x) {
            return (v, rays);
        }
        // the pair, linked or hidden, carries a visible fraction from rays that did not judge
        // it: a pair is kept unsplit more often when its rays happened to miss an occluder
        // (a bar across a window, all of whose rays passed) or to find no gap, so the judging
        // rays' fraction errs with one sign over the pairs kept; fresh rays are independent
        // of the verdict. Each is weighted by the source's B where it ends, once B is known:
        // the share of the light, not of the rays
        let mut x = x;
        // As many fresh rays as the grid judged with: a grid half as long again (2.25 times
        // the rays) took the Cornell box 7.7 M rays against 4.3 M and the 7 × 7 room 118 M
        // against 68 M, for the same surface means within the reference's noise; the Cornell
        // box made of meshes is within 0.16 % of the box of parallelograms with these (the
        // requirement is 0.3 %; 0.31 % when the box had 70 k links and less noise averaged)
        if !clear {
            let fresh = used;
            if self.b_known() {
                v = self.share_of_light(r, s, fresh, Some(&occluders), &mut rays);
            } else if partial {
                // partly visible before B is known: the fraction is taken again with the
                // light after the first solve, and the judging rays' stand in until then
                // (fresh rays now, weighted alike, were a third of the Cornell box's rays)
                x.unlit = Some(fresh as u8);
            } else {
                v = visible_fraction_over(&occluders, pr, mask, ps, fresh, seed ^ 2, &mut rays);
                x.unlit = (v.whole < 1.0).then_some(fresh as u8);
            }
        }
        if v.whole > 0.0 {
            (Verdict::Link(x, v), rays)
        } else {
            (Verdict::Hidden(x), rays)
        }
    }

    /// Refines the interactions `pairs` (receiver, source) top-down, appending the accepted
    /// (recv, src, geom, V) to `out` in a fixed order. Each level's pairs are judged in
    /// parallel, in chunks of the budget's `chunk` pairs; the splits they ask for are then
    /// made in order, so the elements are numbered the same on every run. `held` links
    /// already made stay with the caller meanwhile (a re-refinement's kept ones) and count
    /// against the budget with those accepted here.
    pub(super) fn refine_all(
        &mut self,
        mut frontier: Vec<(u32, u32)>,
        held: usize,
        out: &mut Vec<(u32, u32, Factors, Seen)>,
        progress: &dyn Progress,
    ) -> Result<(), Cancelled> {
        while !frontier.is_empty() {
            let mut next = Vec::new();
            for chunk in frontier.chunks(self.budget.chunk) {
                progress.check()?;
                self.within_budget(held + out.len(), frontier.len())?;
                self.judge_level(chunk, out, &mut next, progress)?;
            }
            frontier = next;
        }
        self.within_budget(held + out.len(), 0)
    }

    /// Judges the pairs `chunk` of one level: accepted pairs go to `out` (or the cluster
    /// links, or the hidden pairs), the pairs that the splits they ask for make go to `next`.
    fn judge_level(
        &mut self,
        chunk: &[(u32, u32)],
        out: &mut Vec<(u32, u32, Factors, Seen)>,
        next: &mut Vec<(u32, u32)>,
        progress: &dyn Progress,
    ) -> Result<(), Cancelled> {
        // pairs with a cluster at an end go to their own oracle ([`super::clustered`]),
        // pairs of elements (of two facing patches: `may_link`) to this one
        let (clustered, pairs): (Vec<_>, Vec<_>) = chunk
            .iter()
            .copied()
            .partition(|&(r, s)| is_cluster(r) || is_cluster(s));
        let cluster_verdicts: Vec<(ClusterVerdict, u64)> = clustered
            .par_iter()
            .map(|&(r, s)| {
                if progress.cancelled() {
                    (ClusterVerdict::Inert, 0)
                } else {
                    self.judge_cluster(r, s)
                }
            })
            .collect();
        // the estimate depends on the pair's shape only: once per class of congruent
        // pairs (the estimate's points are symmetric on the receiver)
        let piece = |e: u32| self.elements[e as usize].piece;
        let (unique, slots) = first_of_each(&pairs, |&(r, s)| {
            Congruence::of(&self.geo.quads, piece(r), piece(s), self.unit, true).key
        });
        let estimates: Vec<(f64, f64)> = unique
            .par_iter()
            .map(|&(r, s)| self.estimate(r, s))
            .collect();
        // a level of a fine refinement judges millions of pairs (seconds of rays): each
        // pair looks at the cancel first, so that a cancel stops the level at once
        let verdicts: Vec<(Verdict, u64)> = pairs
            .par_iter()
            .zip(slots.par_iter())
            .map(|(&(r, s), &slot)| {
                if progress.cancelled() {
                    (Verdict::Inert, 0)
                } else {
                    self.judge(r, s, estimates[slot])
                }
            })
            .collect();
        progress.check()?;
        for (&(r, s), (verdict, rays)) in pairs.iter().zip(verdicts) {
            self.rays += rays;
            match verdict {
                Verdict::Split { .. } | Verdict::SplitReceiver => {
                    // the contact lines' split is the receiver's whatever the sizes (`judge`
                    // asks it only of a receiver that can be split); otherwise the larger
                    // piece, unless the source's own detail is most of the error
                    let split_r = match verdict {
                        Verdict::Split { source } => {
                            self.splittable(r)
                                && (!self.splittable(s)
                                    || (!source
                                        && (self.coarse(r)
                                            || self.elements[r as usize].area
                                                >= self.elements[s as usize].area)))
                        }
                        _ => true,
                    };
                    if split_r {
                        let c = self.split(r);
                        next.extend((0..4).map(|i| (c + i, s)));
                    } else {
                        let c = self.split(s);
                        next.extend((0..4).map(|i| (r, c + i)));
                    }
                }
                Verdict::Link(x, v) => out.push((r, s, x, v)),
                Verdict::Hidden(x) => self.hidden.push((r, s, x)),
                Verdict::Inert => {}
            }
        }
        for (&(r, s), (verdict, rays)) in clustered.iter().zip(cluster_verdicts) {
            self.rays += rays;
            match verdict {
                ClusterVerdict::Both => {
                    let [a, b] = self.clusters.get(r).children;
                    let children = [(a, a), (a, b), (b, a), (b, b)];
                    next.extend(children.into_iter().filter(|&p| self.may_link(p)));
                }
                ClusterVerdict::Receiver => {
                    for c in self.children_of(r) {
                        next.extend(self.may_link((c, s)).then_some((c, s)));
                    }
                }
                ClusterVerdict::Source => {
                    for c in self.children_of(s) {
                        next.extend(self.may_link((r, c)).then_some((r, c)));
                    }
                }
                ClusterVerdict::Link(g) => self.cluster_links.push(ClusterLink {
                    recv: r,
                    src: s,
                    visibility: g.visibility,
                    affine: g.affine,
                    smooth: g.smooth,
                    sampled: g.sampled,
                    members: g.members,
                    factors: None,
                    cut: None,
                }),
                ClusterVerdict::Hidden(smooth) => self.hidden_clusters.push((r, s, smooth)),
                ClusterVerdict::Inert => {}
            }
        }
        Ok(())
    }

    /// Whether the refinement still fits its [`Budget`]: the `links` made or accepted (and
    /// not yet built) and the `pairs` of the frontier. The two are bounded
    /// apart: a pair waiting to be judged holds [`PAIR_BYTES`], not a block, and many pairs
    /// of a fine level end split, hidden or inert rather than linked.
    fn within_budget(&mut self, links: usize, pairs: usize) -> Result<(), Cancelled> {
        self.too_large = if links > self.budget.links {
            Some(Overrun::Links)
        } else if pairs > self.budget.pairs {
            Some(Overrun::Pairs)
        } else {
            None
        };
        self.too_large.map_or(Ok(()), |_| Err(Cancelled))
    }

    /// Whether a pair that a cluster's split makes is worth judging: one with a cluster at an
    /// end is judged by its bounds; two elements (patches, or pieces of them) only when their
    /// patches face each other. Pairs of elements made by an element's split inherit that.
    fn may_link(&self, (r, s): (u32, u32)) -> bool {
        if is_cluster(r) || is_cluster(s) {
            return true;
        }
        let surface = |e: u32| self.elements[e as usize].piece.surface;
        self.geo.facing(surface(r), surface(s))
    }

    /// The children of a cluster (two) or of an element (four, split now).
    fn children_of(&mut self, id: u32) -> Vec<u32> {
        if is_cluster(id) {
            self.clusters.get(id).children.to_vec()
        } else {
            let first = self.split(id);
            (first..first + 4).collect()
        }
    }

    /// Integrates the blocks of accepted pairs, in parallel: one per class of congruent pairs
    /// ([`crate::three_d::congruence`]; a pair and its reverse are congruent, T_ba = T_abᵀ, since the
    /// kernel is symmetric and the bases orthonormal), mapped to the others, and appends the
    /// links to `links` in the order of `pending`. The pairs are taken a chunk at a time and
    /// let go as their links are made: the accepted pairs, with their visible fractions, and
    /// the links they become held together were the peak of a job.
    pub(super) fn make_links(
        &self,
        mut pending: Vec<(u32, u32, Factors, Seen)>,
        links: &mut Links,
        progress: &dyn Progress,
    ) -> Result<(), Cancelled> {
        let k = self.k;
        let piece = |e: u32| self.elements[e as usize].piece;
        // the class of each pair, a chunk of pairs at a time: a class's key (144 bytes) lives
        // only in the map of classes, and a pair keeps its slot and labels (its whole
        // congruence, kept for every pair, was a third of a 10⁵-triangle job's peak)
        const CHUNK: usize = 1 << 16;
        let mut index = rustc_hash::FxHashMap::default();
        let mut blocks: Vec<Vec<f64>> = Vec::new();
        let steps = Steps::new(k);
        links.reserve(pending.len());
        // the chunks in order, taken from the end of the reversed list, which then gives
        // their memory back
        pending.reverse();
        while !pending.is_empty() {
            let mut chunk = pending.split_off(pending.len().saturating_sub(CHUNK));
            pending.shrink_to_fit();
            chunk.reverse();
            let classes: Vec<Congruence> = chunk
                .par_iter()
                .map(|&(r, s, _, _)| {
                    Congruence::of(&self.geo.quads, piece(r), piece(s), self.unit, false)
                })
                .collect();
            let mut firsts: Vec<usize> = Vec::new();
            let mapped: Vec<(u32, Labels)> = classes
                .iter()
                .enumerate()
                .map(|(i, c)| {
                    let slot = *index.entry(c.key).or_insert_with(|| {
                        firsts.push(i);
                        (blocks.len() + firsts.len()) as u32 - 1
                    });
                    (slot, c.labels)
                })
                .collect();
            drop(classes);
            let new: Vec<Vec<f64>> = firsts
                .par_iter()
                .map(|&i| {
                    progress.check()?;
                    let (a, b) = (chunk[i].0, chunk[i].1);
                    let mut block = vec![0.0; k.pow(4)];
                    let evaluations = transfer::block(
                        &self.geo.quads,
                        piece(a),
                        piece(b),
                        Integrand::Galerkin { k },
                        self.accuracy,
                        &mut block,
                    );
                    self.evaluations
                        .fetch_add(evaluations, std::sync::atomic::Ordering::Relaxed);
                    Ok(mapped[i].1.to_class(&block, k))
                })
                .collect::<Result<_, Cancelled>>()?;
            blocks.extend(new);
            links.extend_with(chunk.len(), |i, block| {
                let (recv, src, factors, seen) = chunk[i];
                let (slot, labels) = &mapped[i];
                labels.from_class_into(&blocks[*slot as usize], k, block);
                match &self.elements[recv as usize].exposure {
                    // unless the source sends nothing to the covered part: then the block
                    // already holds the moments of the exposed part
                    Exposure::Partial(p) if self.sends_to_covered(recv, src) => {
                        seen.weigh_masked(p, k, block)
                    }
                    _ => seen.weigh(&steps, block),
                }
                if seen.detail != 1.0 {
                    let detail = f64::from(seen.detail);
                    block.iter_mut().for_each(|x| *x *= detail);
                }
                let factors = Factors {
                    shadow: Cells::of(&seen),
                    ..factors
                };
                Link { recv, src, factors }
            });
        }
        Ok(())
    }
}

/// The first item of each key, in order, and for every item the index of its key's first.
/// The keys are computed in parallel a few thousand at a time: a key of a congruence class is
/// 144 bytes, and a whole chunk of the frontier's keys at once (2¹⁸) was 37 MB.
fn first_of_each<K, T>(items: &[T], key: impl Fn(&T) -> K + Sync) -> (Vec<T>, Vec<usize>)
where
    K: std::hash::Hash + Eq + Send,
    T: Copy + Sync,
{
    let mut index = rustc_hash::FxHashMap::default();
    let mut firsts = Vec::new();
    let mut slots = Vec::with_capacity(items.len());
    for part in items.chunks(1 << 12) {
        let keys: Vec<K> = part.par_iter().map(&key).collect();
        for (key, &item) in keys.into_iter().zip(part) {
            slots.push(*index.entry(key).or_insert_with(|| {
                firsts.push(item);
                firsts.len() - 1
            }));
        }
    }
    (firsts, slots)
}

/// The largest emission channel of `quad` if `piece` overlaps its emission region, else 0.
pub(super) fn peak_emission(quad: &crate::scene::Quad, piece: Piece) -> f64 {
    let (rs, rt) = quad.emission_region;
    let overlaps =
        piece.s[0] < rs[1] && rs[0] < piece.s[1] && piece.t[0] < rt[1] && rt[0] < piece.t[1];
    if overlaps {
        quad.material.emission.iter().copied().fold(0.0, f64::max)
    } else {
        0.0
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::scene::{parse_value, Limits, Quad, SceneKind};
    use crate::three_d::hierarchy::sizing::Sizing;
    use crate::three_d::projection::Geometry;
    use crate::three_d::rules::Rules;

    /// The patches of a 3D document.
    fn patches(doc: serde_json::Value) -> Vec<crate::scene::Quad> {
        match parse_value(&doc, &Limits::default()).unwrap().scene.kind {
            SceneKind::ThreeD(scene) => scene.patches,
            _ => unreachable!(),
        }
    }

    /// A 4 × 4 floor (index 0) under a 4 × 4 light 3 above it (index 2), with `between`
    /// (index 1) standing on the floor or hanging between them.
    fn floor_under_light(between: serde_json::Value) -> Vec<crate::scene::Quad> {
        patches(serde_json::json!({"scene": {"kind": "3d", "surfaces": [
            {"name": "floor", "corners": [[0, 0, 0], [4, 0, 0], [4, 4, 0], [0, 4, 0]],
             "reflectance": 0.5},
            between,
            {"name": "light", "corners": [[0, 0, 3], [0, 4, 3], [4, 4, 3], [4, 0, 3]],
             "reflectance": 0.0, "emission": 1.0}
        ]}}))
    }

    /// [`floor_under_light`] with a wall standing on the floor, its foot a line at a quarter
    /// of the floor (x = 1, y from 1 to 3), 2 high.
    fn wall_on_floor_under_light() -> Vec<crate::scene::Quad> {
        floor_under_light(
            serde_json::json!({"name": "wall", "corners": [[1, 1, 0], [1, 3, 0], [1, 3, 2], [1, 1, 2]],
            "reflectance": 0.5}),
        )
    }

    /// A closed unit cube of six faces facing in, its ceiling (index 1) emitting.
    pub(in crate::three_d::hierarchy) fn cube() -> Vec<crate::scene::Quad> {
        let face = |name: &str, c: [[f64; 3]; 4], e: f64| serde_json::json!({"name": name, "corners": c, "reflectance": 0.5, "emission": e});
        let doc = serde_json::json!({"scene": {"kind": "3d", "surfaces": [
            face("floor", [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]], 0.0),
            face("ceiling", [[0., 0., 1.], [0., 1., 1.], [1., 1., 1.], [1., 0., 1.]], 1.0),
            face("south", [[0., 0., 0.], [0., 0., 1.], [1., 0., 1.], [1., 0., 0.]], 0.0),
            face("north", [[0., 1., 0.], [1., 1., 0.], [1., 1., 1.], [0., 1., 1.]], 0.0),
            face("west", [[0., 0., 0.], [0., 1., 0.], [0., 1., 1.], [0., 0., 1.]], 0.0),
            face("east", [[1., 0., 0.], [1., 0., 1.], [1., 1., 1.], [1., 1., 0.]], 0.0),
        ]}});
        patches(doc)
    }

    /// The hierarchy of `quads` at order 1 with elements down to half a metre.
    fn at_half_a_metre<'g>(geo: &'g Geometry, quads: &'g [Quad]) -> Hierarchy<'g> {
        Hierarchy::new(
            geo,
            quads,
            1,
            Sizing::new(&geo.quads, Some(0.5), None),
            1e-3,
            &Rules::default(),
        )
    }

    /// The ratio of a link's light to the polynomial it carries (`detail` of [`Seen`]), in
    /// a closed unit cube: 1 to rounding while the ceiling is one leaf, whose light is that
    /// polynomial; with all of the ceiling's light in its middle (four times its mean there,
    /// none elsewhere), which its polynomial, the pull of its leaves, spreads flat, for each
    /// quarter of the floor the ratio of the two transfers by quadrature (the point kernel,
    /// 8 × 8 points of the quarter against 64 × 64 of the ceiling, about 1.14) within 3 %
    /// from 16 × 16 rays.
    #[test]
    fn a_links_light_is_weighed_against_its_polynomial() {
        let quads = &cube();
        let geo = Geometry::new(quads);
        let mut h = at_half_a_metre(&geo, quads);
        h.solved = true;
        let (floor, ceiling) = (0u32, 1u32);
        let mut rays = 0;
        let leaf = h.share_of_light(floor, ceiling, 8, None, &mut rays);
        assert!((f64::from(leaf.detail) - 1.0).abs() < 1e-6, "{leaf:?}");
        // the light in the middle quarter of the ceiling, [¼, ¾]², four times the mean: in
        // the inner sixteenth of each of the ceiling's quarters
        let kk = h.k * h.k;
        let quarter = h.split(ceiling);
        // child `c` (`2 dt + ds`) of a parent, pulled into the parent's coefficients
        let filters = h.filters;
        let pull = |child: &[Rgb], c: u32, parent: &mut [Rgb]| {
            super::super::tree::pull(filters, child, (c / 2) as usize, (c % 2) as usize, parent)
        };
        let mut pulled = vec![[0.0; 3]; kk];
        for c in 0..4u32 {
            let sixteenth = h.split(quarter + c);
            let mut quarter_b = vec![[0.0; 3]; kk];
            for g in 0..4u32 {
                let el = &mut h.elements[(sixteenth + g) as usize];
                el.b = vec![[0.0; 3]; kk];
                if g == 3 - c {
                    el.b[0] = [4.0 * el.area.sqrt(); 3];
                }
                pull(&el.b, g, &mut quarter_b);
            }
            pull(&quarter_b, c, &mut pulled);
            h.elements[(quarter + c) as usize].b = quarter_b;
        }
        h.elements[ceiling as usize].b = pulled.clone();
        let quarters = h.split(floor);
        let (qf, qc) = (&geo.quads[0], &geo.quads[1]);
        let mut far = 0.0f64;
        for r in quarters..quarters + 4 {
            let p = h.elements[r as usize].piece;
            let (mut light, mut carried) = (0.0, 0.0);
            for i in 0..8 {
                for j in 0..8 {
                    let x = qf.at(
                        p.s[0] + (p.s[1] - p.s[0]) * (i as f64 + 0.5) / 8.0,
                        p.t[0] + (p.t[1] - p.t[0]) * (j as f64 + 0.5) / 8.0,
                    );
                    for u in 0..64 {
                        for v in 0..64 {
                            let (s, t) = ((u as f64 + 0.5) / 64.0, (v as f64 + 0.5) / 64.0);
                            let d = sub(qc.at(s, t), x);
                            let r2 = dot(d, d);
                            let k = dot(d, qf.n) * -dot(d, qc.n) / (r2 * r2);
                            light += k * h.light_at(ceiling, s, t);
                            carried += k * h.value_at(ceiling, &pulled, s, t);
                        }
                    }
                }
            }
            let exact = light / carried;
            far = far.max((exact - 1.0).abs());
            let seen = h.share_of_light(r, ceiling, 16, None, &mut rays);
            let ratio = f64::from(seen.detail);
            assert!(
                (ratio / exact - 1.0).abs() < 0.03,
                "quarter {r}: {ratio} {exact}"
            );
        }
        assert!(far > 0.1, "{far}");
    }

    /// The oracle's estimate for the pair (`r`, `s`), and its error (kernel and detail) as a
    /// receiver at a contact line: with no smoothness credit.
    fn contact_error(h: &Hierarchy, r: u32, s: u32) -> ((f64, f64), f64) {
        let estimate = h.estimate(r, s);
        let contact = Factors {
            f: estimate.0 as f32,
            smooth: 1.0,
            contact: true,
            unlit: None,
            shadow: None,
        };
        let (kernel, detail) = h.error(r, s, contact);
        assert!(kernel > 0.0);
        (estimate, kernel + detail)
    }

    /// A floor with a wall standing on it (its foot a line at a quarter of the floor) and a
    /// light above both: the floor's root element is at that contact line, and the wall may
    /// come between it and the light, so with an estimate between [`Rules::contact_share`] of the
    /// tolerance and the tolerance it is split on its side before any ray; with one under
    /// that share it is not. The floor's half beyond the line is not at it.
    #[test]
    fn a_receiver_at_a_contact_line_gets_a_share_of_the_tolerance() {
        let quads = &wall_on_floor_under_light();
        let geo = Geometry::new(quads);
        let mut h = at_half_a_metre(&geo, quads);
        let (floor, light) = (0u32, 2u32);
        assert!(h.at_contact(floor) && h.splittable(floor));
        let (estimate, error) = contact_error(&h, floor, light);
        h.threshold = error / (0.5 + 0.5 * h.rules.contact_share);
        let (verdict, rays) = h.judge(floor, light, estimate);
        assert!(matches!(verdict, Verdict::SplitReceiver), "{verdict:?}");
        assert_eq!(rays, 0);
        h.threshold = error / (0.5 * h.rules.contact_share);
        let (verdict, _) = h.judge(floor, light, estimate);
        assert!(
            !matches!(verdict, Verdict::Split { .. } | Verdict::SplitReceiver),
            "{verdict:?}"
        );
        // the floor's children beyond the line (s > ½) are not at it
        let first = h.split(floor);
        let beyond: Vec<bool> = (0..4).map(|i| h.at_contact(first + i)).collect();
        assert_eq!(beyond, vec![true, false, true, false]);
    }

    /// The contact lines' split is made on the receiver even where it is the smaller piece:
    /// the floor's quarter at the wall's foot (4 m²) under the light (16 m²) is split, and the
    /// light is not, though splitting the larger piece is the rule elsewhere. The error is
    /// the receiver's: pieces of the light would each pass the share and send it to the line
    /// together.
    #[test]
    fn a_receiver_at_a_contact_line_is_split_even_when_it_is_the_smaller() {
        let quads = &wall_on_floor_under_light();
        let geo = Geometry::new(quads);
        let mut h = at_half_a_metre(&geo, quads);
        let light = 2u32;
        let first = h.split(0);
        let quarter = first;
        assert!(h.at_contact(quarter) && h.splittable(quarter) && h.splittable(light));
        assert!(h.elements[quarter as usize].area < h.elements[light as usize].area);
        let (_, error) = contact_error(&h, quarter, light);
        h.threshold = error / (0.5 + 0.5 * h.rules.contact_share);
        let (mut out, mut next) = (Vec::new(), Vec::new());
        h.judge_level(
            &[(quarter, light)],
            &mut out,
            &mut next,
            &crate::progress::Silent,
        )
        .expect("not cancelled");
        let children = h.elements[quarter as usize].children;
        assert_ne!(children, NONE);
        assert_eq!(h.elements[light as usize].children, NONE);
        assert_eq!(
            next,
            (0..4).map(|i| (children + i, light)).collect::<Vec<_>>()
        );
        assert!(out.is_empty());
    }

    /// A small square (one element at its finest level: its edge is under twice the smallest
    /// element size) facing a long strip (finest level 3) across a gap: the oracle splits
    /// the strip while it is the larger piece, and stops where its elements are no larger
    /// than the receiver, though they could still be split, unless the source's own detail
    /// is most of the error; a receiver that can still be split always can be.
    #[test]
    fn a_split_is_made_only_where_it_lowers_the_estimate() {
        let doc = serde_json::json!({"scene": {"kind": "3d", "surfaces": [
            {"name": "small", "corners": [[0, 0, 1], [0, 1.9, 1], [1.9, 1.9, 1], [1.9, 0, 1]],
             "reflectance": 0.5},
            {"name": "strip", "corners": [[-4, -1, 0], [4, -1, 0], [4, 1, 0], [-4, 1, 0]],
             "reflectance": 0.5, "emission": 1.0}
        ]}});
        let quads = &patches(doc);
        let geo = Geometry::new(quads);
        let sizing = Sizing::new(&geo.quads, Some(1.0), None);
        let mut h = Hierarchy::new(&geo, quads, 1, sizing, 1e-3, &Rules::default());
        let (small, mut strip) = (0u32, 1u32);
        assert_eq!((h.finest(small), h.finest(strip)), (0, 3));
        // over the limit, the error the kernel's: the larger source is split (16, then 4
        // square units against the receiver's 3.61), and its elements of level 2 (2 × ½)
        // are not, though they could be
        for level in 0..2 {
            assert_eq!(
                h.splits(small, strip, 1.0, 0.0, 0.1),
                Some(true),
                "level {level}"
            );
            strip = h.split(strip);
        }
        assert!((h.elements[strip as usize].area - 1.0).abs() < 1e-12);
        assert!(h.splittable(strip));
        assert_eq!(h.splits(small, strip, 1.0, 0.0, 0.1), None);
        // a finer source would read B finer: split it when that is most of the error
        let first = h.split(1);
        assert_eq!(h.splits(small, first, 0.2, 0.9, 0.1), Some(true));
        // under the limit, nothing; over it, a receiver that can be split is
        assert_eq!(h.splits(first, small, 0.01, 0.0, 0.1), None);
        assert_eq!(h.splits(first, small, 1.0, 0.0, 0.1), Some(false));
    }

    /// The visible fraction of a pair of large pieces is sampled on a finer grid, as long as
    /// both have levels below them: a floor with a wall standing on it and a light above (the
    /// wall hides part of the light from the floor), at order 0 (one ray per point pair of
    /// an n × n grid, every pair facing): 16 × 16 rays for the roots, 8 × 8 for elements of
    /// level 1, 4 × 4 from level 2 on, and 4 × 4 for the roots of a scene whose surfaces
    /// cannot be split (a mesh's triangles are most often such).
    #[test]
    fn pairs_of_large_pieces_get_more_rays() {
        let quads = &wall_on_floor_under_light();
        let geo = Geometry::new(quads);
        let rays = |h: &Hierarchy, r: u32, s: u32| {
            let (verdict, rays) = h.judge(r, s, h.estimate(r, s));
            assert!(
                matches!(verdict, Verdict::Link(_, v) if v.whole < 1.0),
                "{verdict:?} {:?} {:?}",
                h.elements[r as usize].piece,
                h.elements[s as usize].piece
            );
            rays
        };
        let (floor, light) = (0u32, 2u32);
        // the rays that judge the pair (n²), and as many fresh ones for its link
        let judged_and_fresh = |n: usize| (2 * n * n) as u64;
        for (size, want) in [
            (0.5, [16, 8, 4].map(judged_and_fresh)),
            (8.0, [judged_and_fresh(4), 0, 0]),
        ] {
            let mut h = Hierarchy::new(
                &geo,
                quads,
                0,
                Sizing::new(&geo.quads, Some(size), None),
                1e-3,
                &Rules::default(),
            );
            // every pair is accepted: only the rays are counted, once B is known (before it, a
            // partly visible pair carries its judging rays' fraction to the first solve)
            h.threshold = f64::INFINITY;
            h.typical = [1.0; 3];
            h.solved = true;
            assert_eq!(rays(&h, floor, light), want[0], "size {size}");
            if size > 4.0 {
                assert!(!h.splittable(floor) && !h.splittable(light));
                continue;
            }
            // the floor's square of side 2, then 1, at the wall's back (x < 1) beside its foot;
            // the light's over the floor's next square (x > 1), so that the wall is between
            let child = |h: &mut Hierarchy, e: u32, s: f64, t: f64| {
                let first = h.split(e);
                (first..first + 4)
                    .find(|&c| {
                        let p = h.elements[c as usize].piece;
                        p.s[0] == s && p.t[0] == t
                    })
                    .unwrap()
            };
            let (mut r, mut s) = (floor, light);
            for (level, &want) in want.iter().enumerate().skip(1) {
                // floor: s along x, t along y; light: s along y, t along x
                let (rs, rt, ss, st) = if level == 1 {
                    (0.0, 0.0, 0.0, 0.0)
                } else {
                    (0.0, 0.25, 0.25, 0.25)
                };
                r = child(&mut h, r, rs, rt);
                s = child(&mut h, s, ss, st);
                assert_eq!(h.elements[r as usize].level, level as u32);
                assert_eq!(rays(&h, r, s), want, "level {level}");
            }
        }
    }

    /// A small source close in front of a large receiver, parallel to it (the bottom of a box
    /// 2 cm above a floor), is seen with a form factor of nearly 1 from the point under it,
    /// which lies between the points of the receiver's grid: F̂ is at least that form factor
    /// (in closed form, four corner rectangles: Howell's catalogue, B-3). Taken on the grid
    /// alone it was 6e-6 for such a box over a 10 m floor, and the floor's root took the
    /// box's light and spread it over the whole floor: the box's bottom 31 % off the tracer.
    #[test]
    fn a_small_source_just_above_a_large_receiver_is_estimated_at_its_peak() {
        let quads = &floor_under_light(serde_json::json!({"name": "bottom",
            "corners": [[0.6, 2.4, 0.02], [0.6, 3.4, 0.02], [1.6, 3.4, 0.02], [1.6, 2.4, 0.02]],
            "reflectance": 0.5}));
        let geo = Geometry::new(quads);
        let h = at_half_a_metre(&geo, quads);
        let (floor, bottom) = (0u32, 1u32);
        // a point under the corner of an a × b rectangle parallel to it at height c
        let corner = |a: f64, b: f64, c: f64| {
            let (x, y) = (a / c, b / c);
            let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
            (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / (2.0 * std::f64::consts::PI)
        };
        let under_centre = 4.0 * corner(0.5, 0.5, 0.02);
        assert!(under_centre > 0.99, "{under_centre}");
        let (f, _) = h.estimate(floor, bottom);
        assert!(
            f >= under_centre - 1e-9 && f <= 1.0,
            "F̂ = {f}, under its centre {under_centre}"
        );
    }

    /// A box's side 2 cm above the floor, at an angle to it, lights the strip of floor just
    /// in front of its lower edge with a form factor near ½, while the point right under that
    /// edge lies in the side's own plane and sees 0: F̂ takes the points under the source
    /// moved onto its front side, whether or not the source reaches the receiver's plane
    /// (moved only when it reached, F̂ came from the grid, about 0.1, and the bottom of a box
    /// 2 cm above a floor went from 7.7 % to 24 % off the tracer). Checked against midpoint
    /// quadrature of cos θ cos θ' / π r² over the side.
    #[test]
    fn a_tilted_source_just_above_a_receiver_is_estimated_in_front_of_it() {
        // the side faces −x: its normal (e₁ × e₃) points away from the floor's middle
        let quads = &floor_under_light(serde_json::json!({"name": "side",
            "corners": [[1.0, 3.0, 0.02], [1.0, 1.0, 0.02], [1.0, 1.0, 1.02], [1.0, 3.0, 1.02]],
            "reflectance": 0.5}));
        let geo = Geometry::new(quads);
        let h = at_half_a_metre(&geo, quads);
        let (floor, side) = (0u32, 1u32);
        assert!(geo.quads[1].n[0] < -0.99);
        // a hundredth of the floor's diameter in front of the middle of the side's lower edge
        let x = [1.0 - 0.01 * 32f64.sqrt(), 2.0, 0.0];
        let m = 400;
        let mut want = 0.0;
        for i in 0..m {
            for j in 0..m {
                let (y, z) = (
                    1.0 + 2.0 * (i as f64 + 0.5) / m as f64,
                    0.02 + (j as f64 + 0.5) / m as f64,
                );
                let r = [1.0 - x[0], y - x[1], z - x[2]];
                let r2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
                want += r[2] * r[0] / (std::f64::consts::PI * r2 * r2) * (2.0 / (m * m) as f64);
            }
        }
        assert!(want > 0.3, "{want}");
        let (f, _) = h.estimate(floor, side);
        assert!(
            f >= want - 1e-3 && f <= 0.5,
            "F̂ = {f}, in front of the edge {want}"
        );
    }

    /// A receiver with an occluder near it that none of the pair's rays meets, a chip 1 mm ×
    /// 1 cm 5 cm above the floor under the light, is linked without the smoothness credit
    /// ([`Rules::near_occluders`]); without the rule, the same rays all pass and the pair
    /// takes the credit.
    #[test]
    fn a_receiver_with_an_occluder_near_it_gets_no_smoothness_credit() {
        let quads = &floor_under_light(serde_json::json!({"name": "chip",
            "corners": [[1.0, 1.0, 0.05], [1.001, 1.0, 0.05], [1.001, 1.01, 0.05], [1.0, 1.01, 0.05]],
            "reflectance": 0.5}));
        let geo = Geometry::new(quads);
        let mut h = at_half_a_metre(&geo, quads);
        let (floor, light) = (0u32, 2u32);
        assert!(!h.at_contact(floor));
        // a tolerance no link misses: the verdict is a link, with the factors it was judged by
        h.threshold = 1e9;
        let smooth = |h: &Hierarchy| {
            let (verdict, _) = h.judge(floor, light, h.estimate(floor, light));
            let Verdict::Link(x, v) = verdict else {
                panic!("{verdict:?}")
            };
            (x.smooth, v.whole)
        };
        let (with, seen) = smooth(&h);
        assert_eq!(with, 1.0);
        assert_eq!(seen, 1.0, "the rays found the chip");
        h.rules = Rules::without_near_occluders();
        let (without, seen) = smooth(&h);
        assert_eq!(seen, 1.0);
        assert!(without < 1.0, "{without}");
    }

    /// A pair that none of its rays gets through (a board larger than both between a floor
    /// and a light) is judged by 3/n of its transfer, the rays' bound on what they missed,
    /// not by all of it: at the top level, 3/256.
    #[test]
    fn a_hidden_pair_is_judged_by_what_its_rays_may_have_missed() {
        let quads = &floor_under_light(
            serde_json::json!({"name": "board", "corners": [[-2, -2, 1], [6, -2, 1], [6, 6, 1], [-2, 6, 1]],
            "reflectance": 0.5}),
        );
        let geo = Geometry::new(quads);
        let sizing = Sizing::new(&geo.quads, Some(0.5), None);
        let mut h = Hierarchy::new(&geo, quads, 0, sizing, 1e-3, &Rules::default());
        let (floor, light) = (0u32, 2u32);
        let estimate = h.estimate(floor, light);
        let unsure = Factors {
            f: estimate.0 as f32,
            smooth: 1.0,
            contact: false,
            unlit: None,
            shadow: None,
        };
        let whole = h.error(floor, light, unsure).0;
        // a tolerance above the estimate before any ray (the kernel's smoothness factor,
        // d / (d + dist) = 0.65) and below the whole transfer, which the pair was judged by
        // when hidden before: now accepted as hidden
        assert!(estimate.1 < 0.7);
        h.threshold = 0.8 * whole;
        let (verdict, rays) = h.judge(floor, light, estimate);
        // 16 × 16 rays judge it, as many fresh ones find it hidden too
        assert_eq!(rays, 2 * 256);
        let Verdict::Hidden(x) = verdict else {
            panic!("{verdict:?}")
        };
        assert_eq!(x.smooth, 3.0 / 256.0);
        assert!(h.error(floor, light, x).0 < h.threshold);
        assert!(h.error(floor, light, unsure).0 > h.threshold);
    }
}
