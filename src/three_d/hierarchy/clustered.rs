//! Links with a cluster at one end or both: their oracle, their visible fraction and their
//! transfer in the Jacobi sweep (the clusters and the transfer's equations are in
//! [`crate::three_d::cluster`]).
//!
//! The oracle bounds what such a link leaves out as the irradiance it may carry times the
//! share that taking both ends as points misses:
//!
//! ```text
//! err = ρ_R · (Ê_S + w_R · R̂_S) · d / (d + dist)
//! Ê_S = min(Σ_j A_j E_j / (π dist²), max_j E_j)     (emitted light; R̂_S likewise for B − E)
//! ```
//!
//! with d the larger diameter and dist the distance of the two boxes; Σ A_j E_j / (π dist²)
//! bounds the irradiance that S can give any point at distance dist (every cosine ≤ 1), and
//! no point receives more than the brightest member gives (a form factor is at most 1). A
//! partly visible pair loses the factor d / (d + dist), as the element links' oracle does
//! ([`super::refine`]), with the same weights w_R and tolerances (with w_R = 1 the Cornell box
//! made of meshes came out 1 % dark on its ceiling). When err is above the
//! tolerance, the end with the larger box is split: a cluster into its two children, an
//! element into its four; a cluster linked to itself into the four pairs of its children.

use super::Hierarchy;
use crate::scene::Rgb;
use crate::three_d::cluster::{is_cluster, Bound};
use crate::three_d::cover::{Exposure, Partial};
use crate::three_d::geometry::{add, dot, norm, scale, sub, V3};
use crate::three_d::visibility::{pair_seed, SplitMix};
use rayon::prelude::*;

/// Rays between two clusters for their visible fraction.
pub const CLUSTER_RAYS: usize = 16;

/// The least distance between the boxes of a cluster link's ends, in their larger diameter.
/// Taking both ends as points is a fair kernel only for separated ends: the distance of any
/// two of their points is then within a factor 3 of the centres', and the transfer stays
/// below the form factor of a disc of the ends' size at that distance, which keeps the
/// iteration a contraction whatever B the source has when the link is accepted (a dark
/// source passes the oracle at any distance before the first solve).
pub const SEPARATION: f64 = 1.0;

/// A link with a cluster at one end or both.
#[derive(Debug, Clone)]
pub struct ClusterLink {
    pub recv: u32,
    pub src: u32,
    /// The unit vector from the source's centre to the receiver's.
    pub dir: V3,
    /// V / (π r²): the visible fraction over π times the squared distance of the centres.
    pub gain: f64,
    /// The oracle's factor d / (d + dist), or 1 when partly visible.
    pub smooth: f64,
}

/// What the oracle needs of a cluster's members, gathered once per refinement pass.
#[derive(Debug, Clone, Copy, Default)]
pub struct State {
    /// Σ A_j E_j and the largest E_j over the members (largest channel of the peak emission).
    pub emitted: f64,
    pub emitted_max: f64,
    /// Σ A_j B̄_j and the largest B̄_j (the mean of B, largest channel).
    pub reflected: f64,
    pub reflected_max: f64,
    /// The largest ρ, the largest w_R and the least tolerance over the members.
    pub rho: f64,
    pub weight: f64,
    pub tolerance: f64,
}

/// What the oracle makes of a pair with a cluster at an end.
#[derive(Debug, Clone, Copy)]
pub(super) enum ClusterVerdict {
    /// Split the receiver, the source, or (a cluster with itself) both.
    Receiver,
    Source,
    Both,
    Link(ClusterLinkGeometry),
    Hidden,
    Inert,
}

#[derive(Debug, Clone, Copy)]
pub(super) struct ClusterLinkGeometry {
    pub dir: V3,
    pub gain: f64,
    pub smooth: f64,
}

/// The shape of one end of a link: its bound, area and centre.
struct End {
    bound: Bound,
    centre: V3,
}

impl Hierarchy<'_> {
    /// The bound and centre of a cluster or element.
    fn end(&self, id: u32) -> End {
        if is_cluster(id) {
            let c = self.clusters.get(id);
            return End {
                bound: c.bound,
                centre: c.centre,
            };
        }
        let el = &self.elements[id as usize];
        let q = &self.geo.quads[el.piece.surface];
        let c = el.piece.corners(&self.geo.quads);
        let centre = if q.tri {
            scale(add(add(c[0], c[1]), c[2]), 1.0 / 3.0)
        } else {
            scale(add(c[0], c[2]), 0.5)
        };
        End {
            bound: Bound::of_polygon(&c, q.n),
            centre,
        }
    }

    /// Calls `f(element, area, normal)` for each member of a cluster (the root elements of its
    /// patches), or for the element itself.
    pub(super) fn for_members(&self, id: u32, mut f: impl FnMut(u32, f64, V3)) {
        if is_cluster(id) {
            for &p in self.clusters.members(id) {
                let q = &self.geo.quads[p as usize];
                f(p, q.area, q.n);
            }
        } else {
            let el = &self.elements[id as usize];
            f(id, el.area, self.geo.quads[el.piece.surface].n);
        }
    }

    /// The oracle's state of every cluster from its members, children before parents.
    pub(super) fn measure_clusters(&self) -> Vec<State> {
        let tree = &self.clusters;
        let mut out = vec![State::default(); tree.nodes.len()];
        let leaf = |p: u32| self.element_state(p);
        for i in (0..tree.nodes.len()).rev() {
            let [a, b] = tree.nodes[i].children;
            let get = |c: u32, out: &[State]| {
                if is_cluster(c) {
                    out[(c & !crate::three_d::cluster::CLUSTER) as usize]
                } else {
                    leaf(c)
                }
            };
            let (x, y) = (get(a, &out), get(b, &out));
            out[i] = State {
                emitted: x.emitted + y.emitted,
                emitted_max: x.emitted_max.max(y.emitted_max),
                reflected: x.reflected + y.reflected,
                reflected_max: x.reflected_max.max(y.reflected_max),
                rho: x.rho.max(y.rho),
                weight: x.weight.max(y.weight),
                tolerance: x.tolerance.min(y.tolerance),
            };
        }
        out
    }

    /// The oracle's state of one element.
    fn element_state(&self, e: u32) -> State {
        let el = &self.elements[e as usize];
        let surface = el.piece.surface;
        let c = el.b[0];
        let mean = (c[0].max(c[1]).max(c[2]) / el.area.sqrt()).max(0.0);
        State {
            emitted: el.area * el.peak,
            emitted_max: el.peak,
            reflected: el.area * mean,
            reflected_max: mean,
            rho: self.rho[surface],
            weight: self.indirect[surface],
            tolerance: self.tolerance(e),
        }
    }

    fn state(&self, id: u32) -> State {
        if is_cluster(id) {
            self.cluster_state[(id & !crate::three_d::cluster::CLUSTER) as usize]
        } else {
            self.element_state(id)
        }
    }

    /// The oracle's estimate for a pair with a cluster at an end, with the factor `smooth`.
    fn cluster_error(&self, r: &State, s: &State, dist: f64, smooth: f64) -> f64 {
        let bound = |sum: f64, max: f64| {
            if dist > 0.0 {
                (sum / (std::f64::consts::PI * dist * dist)).min(max)
            } else {
                max
            }
        };
        let e = bound(s.emitted, s.emitted_max);
        let b = bound(s.reflected, s.reflected_max);
        r.rho * (e + r.weight * b) * smooth
    }

    /// Whether a cluster link (or hidden cluster pair) now carries more than its receiver's
    /// tolerance allows, with the factor `smooth` it was accepted with.
    pub(super) fn cluster_outgrown(&self, r: u32, s: u32, smooth: f64) -> bool {
        let (er, es) = (self.end(r), self.end(s));
        let (sr, ss) = (self.state(r), self.state(s));
        self.cluster_error(&sr, &ss, er.bound.distance(&es.bound), smooth) > sr.tolerance
    }

    /// The verdict on a pair with a cluster at an end; read-only, so that a frontier of pairs
    /// is judged in parallel. Returns the rays cast.
    pub(super) fn judge_cluster(&self, r: u32, s: u32) -> (ClusterVerdict, u64) {
        if r == s {
            return (
                if is_cluster(r) {
                    ClusterVerdict::Both
                } else {
                    ClusterVerdict::Inert
                },
                0,
            );
        }
        let (er, es) = (self.end(r), self.end(s));
        if !er.bound.facing(&es.bound) {
            return (ClusterVerdict::Inert, 0);
        }
        let (sr, ss) = (self.state(r), self.state(s));
        let dist = er.bound.distance(&es.bound);
        let (dr, ds) = (er.bound.diameter(), es.bound.diameter());
        let size = dr.max(ds);
        let split = || {
            // the end with the larger box, unless it is an element at its finest level
            let can = |id: u32| is_cluster(id) || self.splittable(id);
            if (dr >= ds && can(r)) || !can(s) {
                ClusterVerdict::Receiver
            } else {
                ClusterVerdict::Source
            }
        };
        let smooth = size / (size + dist);
        if dist < SEPARATION * size || self.cluster_error(&sr, &ss, dist, smooth) > sr.tolerance {
            return (split(), 0);
        }
        let seed = pair_seed(self.cluster_identity(r), self.cluster_identity(s));
        let (v, rays) = self.cluster_visibility(r, s, seed);
        let smooth = if v < 1.0 { 1.0 } else { smooth };
        if v < 1.0 && self.cluster_error(&sr, &ss, dist, smooth) > sr.tolerance {
            return (split(), rays);
        }
        if v <= 0.0 {
            return (ClusterVerdict::Hidden, rays);
        }
        let d = sub(er.centre, es.centre);
        let r2 = dot(d, d);
        let len = r2.sqrt();
        if len <= 0.0 {
            return (split(), rays);
        }
        (
            ClusterVerdict::Link(ClusterLinkGeometry {
                dir: scale(d, 1.0 / len),
                gain: v / (std::f64::consts::PI * r2),
                smooth,
            }),
            rays,
        )
    }

    fn cluster_identity(&self, id: u32) -> u64 {
        if is_cluster(id) {
            (1 << 63) | id as u64
        } else {
            let el = &self.elements[id as usize];
            ((el.piece.surface as u64) << 40)
                | ((el.level as u64) << 32)
                | (u64::from(el.piece.upper) << 31)
                | ((el.cell[1] as u64) << 16)
                | el.cell[0] as u64
        }
    }

    /// A point of a cluster (of a member picked by area) or of an element, with its surface
    /// and normal.
    fn sample(&self, id: u32, rng: &mut SplitMix) -> (V3, usize, V3) {
        let piece = if is_cluster(id) {
            crate::three_d::geometry::Piece::whole(self.clusters.pick(id, rng.next_f64()))
        } else {
            self.elements[id as usize].piece
        };
        let q = &self.geo.quads[piece.surface];
        let (mut u, mut v) = (rng.next_f64(), rng.next_f64());
        let (s, t) = if q.tri {
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            piece.at_local(u, v)
        } else {
            (
                piece.s[0] + u * (piece.s[1] - piece.s[0]),
                piece.t[0] + v * (piece.t[1] - piece.t[0]),
            )
        };
        (q.at(s, t), piece.surface, q.n)
    }

    /// The visible fraction between two ends: of [`CLUSTER_RAYS`] pairs of points, those
    /// that face each other, the share with nothing between them (1 when none face).
    fn cluster_visibility(&self, r: u32, s: u32, seed: u64) -> (f64, u64) {
        let mut rng = SplitMix(seed);
        let (mut open, mut valid, mut rays) = (0usize, 0usize, 0u64);
        for _ in 0..CLUSTER_RAYS {
            let (x, i, n) = self.sample(r, &mut rng);
            let (y, j, m) = self.sample(s, &mut rng);
            let d = sub(y, x);
            if dot(n, d) <= 0.0 || dot(m, d) >= 0.0 || norm(d) == 0.0 {
                continue;
            }
            valid += 1;
            rays += 1;
            if !self.geo.bvh.occluded(x, y, [i, j]) {
                open += 1;
            }
        }
        if valid == 0 {
            (1.0, rays)
        } else {
            (open as f64 / valid as f64, rays)
        }
    }

    /// Adds the cluster links' irradiance to their receivers' H: each link's source
    /// intensity toward the receiver in parallel, then its receiver's members in order.
    pub(super) fn gather_clusters(&mut self) {
        let kk = self.k * self.k;
        let intensity: Vec<Rgb> = self
            .cluster_links
            .par_iter()
            .map(|l| {
                let mut sum = [0.0; 3];
                self.for_members(l.src, |e, area, n| {
                    let c = dot(n, l.dir);
                    if c > 0.0 {
                        // B̄ A = b₀ √A in the orthonormal basis
                        let b = self.elements[e as usize].b[0];
                        let w = c * area.sqrt();
                        (0..3).for_each(|ch| sum[ch] += w * b[ch]);
                    }
                });
                sum.map(|x| x * l.gain)
            })
            .collect();
        let mut adds: Vec<(u32, Rgb)> = Vec::new();
        for (l, i) in self.cluster_links.iter().zip(&intensity) {
            self.for_members(l.recv, |e, area, n| {
                let c = -dot(n, l.dir);
                if c > 0.0 {
                    // a constant H on the member: h₀ = H √A
                    let w = c * area.sqrt();
                    adds.push((e, i.map(|x| x * w)));
                }
            });
        }
        let mut moments = vec![[0.0; 3]; kk];
        let mut constant = vec![[0.0; 3]; kk];
        for (e, h) in adds {
            let el = &mut self.elements[e as usize];
            match &el.exposure {
                Exposure::Open => (0..3).for_each(|ch| el.h[0][ch] += h[ch]),
                Exposure::Covered => {}
                // the moments ∫ χ φ H of a constant over the exposed part
                Exposure::Partial(p) => {
                    constant[0] = h;
                    Partial::apply(&p.gram, &constant, &mut moments);
                    for (a, m) in el.h.iter_mut().zip(&moments) {
                        (0..3).for_each(|ch| a[ch] += m[ch]);
                    }
                }
            }
        }
    }
}
