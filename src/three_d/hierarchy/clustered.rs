//! Links with a cluster at one end or both: their oracle, their visible fraction and their
//! transfer in the Jacobi sweep (the clusters and the transfer's equations are in
//! [`crate::three_d::cluster`]).
//!
//! The oracle bounds what such a link leaves out as the irradiance it may carry times the
//! share that taking the ends as points misses:
//!
//! ```text
//! err = ρ_R · (Ê_S + w_R · R̂_S) · σ
//! Ê_S = min(Σ_j A_j E_j / (π dist²), max_j E_j)     (emitted light; R̂_S likewise for B − E)
//! σ   = (d_S / (d_S + dist))³ + d_m / (d_m + dist)   (a source facing all of R: [`Emitter`])
//! σ   = d / (d + dist)                               (otherwise)
//! ```
//!
//! with d_S the source's diameter, d_m the largest diameter of a receiving member (it receives
//! a constant), d the larger diameter of the two ends and dist the distance of the two boxes;
//! Σ A_j E_j / (π dist²) bounds the irradiance that S can give any point at distance dist
//! (every cosine ≤ 1), and no point receives more than the brightest member gives (a form
//! factor is at most 1). A partly visible pair has σ = 1, as the element links' oracle does
//! ([`super::refine`]), unless its receiver is an element at its finest level: that receives
//! the link's mean, which is wrong by the sampling error of the visible fraction V from n rays
//! and by V's correlation with the kernel over the pair, so σ = d / (d + dist) + √(V(1 − V)/n),
//! and splitting the source lowers only the first term (the second adds up over its parts).
//! A pair none of whose n rays got through has σ = 3/n, the rays' bound on what they missed
//! ([`crate::three_d::visibility::unseen_bound`]). A pair that is not split (linked or
//! hidden) carries V from n fresh rays, not from those that judged it, as the element pairs
//! do ([`super::refine`]): with the judging rays, a mesh window behind thin bars lit the
//! room's walls 1.2–3.3 % bright.
//! Once B is known, a link into a cluster gives each receiving member its own V, from a ray of
//! its own ([`Hierarchy::member_visibility`]); the link's one V made the members that
//! occluders hide gather light they cannot see, with one sign from every source. Every such
//! link casts them, whatever its judging rays saw: cast only where those rays saw a blocked
//! one, a small member that an occluder hides but that no judging ray reached (drawn by area,
//! they mostly start on the large members) kept the link's V = 1, and in a furnace a book's
//! top beside a taller neighbour came out 3.6 % bright, a row of books' tops up to 13.7 %.
//! (Cast where the fresh rays saw one, the links left with V = 1 were those whose fresh rays
//! all got through, and a wall behind a window's thin bars came out 1.35 % bright.)
//! The tolerances are those of the element links' oracle, and w_R is the weight of the
//! receiver's largest source ([`super::tolerance`]: a cluster may hold many surfaces, whose
//! shares add up; with w_R = 1 the Cornell box made of meshes came out 1 % dark on its
//! ceiling). When err is above the tolerance, the end
//! with the larger box is split: a cluster into its two children, an element into its four; a
//! cluster linked to itself into the four pairs of its children; but a source no larger than
//! a receiver at its finest level is not split (`Hierarchy::splits`).

use super::Hierarchy;
use crate::math::quadrature::Rule;
use crate::scene::Rgb;
use crate::three_d::cluster::{is_cluster, Bound, Clusters};
use crate::three_d::cover::{Exposure, Partial};
use crate::three_d::geometry::{
    add, centroid, covariance, dot, norm, scale, sub, sym, sym_axpy, Parallelogram, Piece, Sym, V3,
};
#[cfg(doc)]
use crate::three_d::rules::Rules;
use crate::three_d::transfer::point_polygon;
use crate::three_d::visibility::{pair_seed, unseen_bound, SplitMix};
use rayon::prelude::*;

/// The receiving members whose irradiance one run of cluster links computes in parallel
/// before adding it to their H ([`Hierarchy::gather_clusters`]): 24 MB of buffer.
const RUN_MEMBERS: usize = 1 << 20;

/// The stretches of members into which [`Hierarchy::gather_clusters`] adds a run's
/// irradiance in parallel: each stretch reads the whole run's list of receivers, so a few
/// per thread. Serial, that addition was a third of the 81 icospheres' gather (0.33 s of
/// 1.15 s a sweep).
const MERGE_STRETCHES: usize = 16;

/// The most kernels of cluster links from an element ([`Hierarchy::unit_irradiance`]) held
/// at once, one f32 each: 512 MiB (the 81 icospheres' 10⁵ triangles hold 54 M).
const KERNELS_HELD: usize = 1 << 27;

/// The clusters under one below which [`Hierarchy::emitters`] works sequentially.
const PARALLEL_EMITTERS: usize = 1 << 12;

/// Rays between two clusters for their visible fraction.
const CLUSTER_RAYS: usize = 16;

/// The facing pairs among which a member's ray is drawn ([`Hierarchy::member_visibility`]).
const MEMBER_CANDIDATES: usize = 8;

/// The source's points drawn once per link that members' rays end at
/// ([`Hierarchy::member_visibility`]).
const SOURCE_POINTS: usize = 32;

/// A member's candidates draw their source points toward it ([`Hierarchy::drawn_toward`])
/// down to parts of the source whose radius is below 1/`TOWARD_SPREAD` of their distance
/// from the member, over which the kernel varies by less than about (1 ± 1/4)²; a source
/// already that small from the member is drawn from the link's shared points.
const TOWARD_SPREAD: f64 = 4.0;

/// The levels of an element's four-way split that [`Hierarchy::drawn_toward`] goes down at
/// most: a part of a 256th of the element's side.
const TOWARD_LEVELS: usize = 8;

/// A held kernel reads a receiving member's form factor at its centroid where the member's
/// area is below 1/`CENTROID_SPREAD` of its squared distance r² from the source's sphere,
/// else at [`Hierarchy::member_points`]. The centroid's error is of second order, about
/// 0.4 A / r² of the form factor for a triangle under a square (6.6, 3.6, 1.2 and 0.34 % at
/// A / r² = ½, ⅛, 1/32 and 1/128; the unit test of `member_points`), mostly short where the
/// falloff is convex. Read there, the links from the walls' elements into a box of the room
/// with 3 × 3 boxes made of meshes delivered from 1.6 % less to 1.7 % more than quadrature
/// (unoccluded, grouped by wall), at the points within 0.2 %. Below 1/1000 the centroid is
/// within about 0.05 %, and the points would cost three or four times its work for nothing:
/// read at every member, the 81 icospheres' small triangles took 7 s more solving (19 → 26 s).
const CENTROID_SPREAD: f64 = 1000.0;

/// Draws of a receiving point before one on a covered part is taken after all
/// ([`Hierarchy::sample`]): an end with an exposed share f keeps a covered point with
/// probability (1 − f)¹⁶, and only such a point's ray may be wrongly blocked.
const COVERED_DRAWS: usize = 16;

/// A link with a cluster at one end or both.
#[derive(Debug, Clone)]
pub(super) struct ClusterLink {
    pub(super) recv: u32,
    pub(super) src: u32,
    /// The visible fraction V between the two ends.
    pub(super) visibility: f64,
    /// Whether every member of the source faces every point of the receiver: the light it
    /// sends is then the affine form of [`Emitter`], else its members' weights at each
    /// receiving member ([`SpreadSource`]).
    pub(super) affine: bool,
    /// The oracle's factor for what taking the ends as points leaves out; when partly
    /// visible, 1, or for a receiver at its finest level the factor with the sampling error
    /// of V added.
    pub(super) smooth: f64,
    /// The part of `smooth` that is the sampling error of `visibility` (see
    /// [`Hierarchy::split_lowers`]).
    pub(super) sampled: f64,
    /// Each receiving member's own visible fraction, in 1/255ths, in the clusters' order
    /// ([`Hierarchy::member_visibility`]): a partly visible link into a cluster.
    pub(super) members: Option<Box<[u8]>>,
    /// The link's kernel at each receiving member per unit of its source's mean B, for a
    /// source that is an element and whose light is affine ([`Hierarchy::unit_irradiance`]):
    /// worked out at the first sweep after the link is made, and kept.
    pub(super) factors: Option<Box<[f32]>>,
    /// The clusters and patches of a source cluster that face the receiver's centre, each
    /// wholly ([`Hierarchy::intensity_cut`]), whose weights it sends by where its normal cone
    /// straddles the direction of a receiving member ([`SpreadSource`]): worked out at the
    /// first sweep after the link is made, and kept.
    pub(super) cut: Option<Box<[u32]>>,
}

impl ClusterLink {
    /// The visible fraction of the `k`-th receiving member (in the clusters' order): its
    /// own where the link keeps one, else the link's.
    fn member_v(&self, k: usize) -> f64 {
        match &self.members {
            Some(m) => f64::from(m[k]) / 255.0,
            None => self.visibility,
        }
    }
}

/// What a source sends through its cluster links, per channel, summed over its members j
/// (area A_j, mean radiosity B̄_j, centroid y_j, normal n_j, the covariance C_j of a uniform
/// point on the member about y_j). At a point x that every member faces, the irradiance is
/// Σ_j ∫_j B̄_j n_j · (x − y) g(y) dy with g(y) = n_x · (y − x) / (π |x − y|⁴). Expanded about
/// a point c to second order in y − c, with the weights w_j(x) = A_j B̄_j n_j · (x − y_j)
/// (the factor n_j · (x − y) is affine in y, and its slope n_j is normal to the member, so
/// that C_j n_j = 0 and the cross term vanishes):
///
/// ```text
/// H(x) = W g(c) + ∇g(c) · Σ_j w_j (y_j − c) + ½ tr(∇²g(c) S) + O((d / r)³) W g
/// W = Σ_j w_j,   S = Σ_j w_j ((y_j − c)(y_j − c)ᵀ + C_j)
/// ```
///
/// The weights are affine in x, and so are their moments: W = J · x − K,
/// Σ_j w_j y_j = Q x − q and Σ_j w_j (y_j y_jᵀ + C_j) = Σ_k x_k P_k − P₀ (J = Σ A_j B̄_j n_j,
/// K = Σ A_j B̄_j n_j · y_j, Q = Σ A_j B̄_j y_j n_jᵀ, q = Σ A_j B̄_j (n_j · y_j) y_j,
/// P_k = Σ A_j B̄_j n_jk (y_j y_jᵀ + C_j), P₀ = Σ A_j B̄_j (n_j · y_j)(y_j y_jᵀ + C_j)). The
/// point c is the same for the three channels and for every x: the members' centroid weighted
/// by the light they send, Σ_j A_j B̄_j y_j / Σ_j A_j B̄_j with the channels summed
/// ([`Emitter::about`]), which is inside their hull. With m = Q x − q, S = Σ_k x_k P_k − P₀
/// − m cᵀ − c mᵀ + W c cᵀ, and with d = c − x, r = |d|, f = n_x · d:
///
/// ```text
/// π ∇g(c)  = n_x / r⁴ − 4 f d / r⁶
/// π ∇²g(c) = −4 (n_x dᵀ + d n_xᵀ) / r⁶ − 4 f I / r⁶ + 24 f d dᵀ / r⁸
/// ```
///
/// What is left is third order in the source's size over the distance, whatever the source's
/// shape. (Expanded about each channel's own centroid of the weights, c(x) = m / W, the
/// first-order term vanishes, but c then depends on the weights at x and on the channel: g
/// and its derivatives were evaluated three times, after the weights, and that was over a
/// quarter of a job of 10⁵ triangles.) Without the second-order term the transfer
/// overestimates, always (1/r⁴ is convex: a disc of radius a at height h on its axis gives
/// a²/h² for a²/(h² + a²)), and those errors add up over a scene's cluster links: a room
/// whose six walls were meshes came out 1.3 % bright (energy balance 1.013, and 0.9995 with
/// no cluster links).
#[derive(Debug, Clone, Copy, Default)]
struct Emitter {
    normal: [V3; 3],
    offset: Rgb,
    /// Q's rows, per channel.
    spread: [[V3; 3]; 3],
    lever: [V3; 3],
    /// P_k per channel, as the six entries of a symmetric matrix ([`sym`]).
    second: [[Sym; 3]; 3],
    second_offset: [Sym; 3],
    /// Σ_j A_j B̄_j and Σ_j A_j B̄_j y_j, the channels summed: the point the irradiance is
    /// expanded about ([`Emitter::about`]).
    light: f64,
    light_moment: V3,
}

/// A patch under the cluster tree as the clusters' transfer reads it: laid out in
/// [`crate::three_d::cluster::Clusters::order`], so that the members of a cluster are one run
/// of memory, which each sweep reads once per cluster link.
#[derive(Debug, Clone, Copy)]
pub(super) struct Member {
    centre: V3,
    normal: V3,
    area: f64,
}

/// The [`Member`]s of every cluster, in the clusters' order.
pub(super) fn members(clusters: &Clusters, quads: &[Parallelogram]) -> Vec<Member> {
    clusters
        .order()
        .iter()
        .map(|&p| Member {
            centre: clusters.centres[p as usize],
            normal: quads[p as usize].n,
            area: quads[p as usize].area,
        })
        .collect()
}

impl Emitter {
    fn member(area: f64, b: Rgb, y: V3, n: V3, cov: Sym) -> Emitter {
        let ab = b.map(|x| x * area);
        let ny = dot(n, y);
        let m = sym_axpy(1.0, &sym(y, y), &cov);
        Emitter {
            normal: ab.map(|w| scale(n, w)),
            offset: ab.map(|w| w * ny),
            spread: ab.map(|w| [0, 1, 2].map(|i| scale(n, w * y[i]))),
            lever: ab.map(|w| scale(y, w * ny)),
            second: ab.map(|w| [0, 1, 2].map(|k| m.map(|e| e * w * n[k]))),
            second_offset: ab.map(|w| m.map(|e| e * w * ny)),
            light: ab.iter().sum(),
            light_moment: scale(y, ab.iter().sum()),
        }
    }

    fn add(&self, o: &Emitter) -> Emitter {
        Emitter {
            normal: [0, 1, 2].map(|c| add(self.normal[c], o.normal[c])),
            offset: [0, 1, 2].map(|c| self.offset[c] + o.offset[c]),
            spread: [0, 1, 2].map(|c| [0, 1, 2].map(|i| add(self.spread[c][i], o.spread[c][i]))),
            lever: [0, 1, 2].map(|c| add(self.lever[c], o.lever[c])),
            second: [0, 1, 2]
                .map(|c| [0, 1, 2].map(|k| sym_axpy(1.0, &self.second[c][k], &o.second[c][k]))),
            second_offset: [0, 1, 2]
                .map(|c| sym_axpy(1.0, &self.second_offset[c], &o.second_offset[c])),
            light: self.light + o.light,
            light_moment: add(self.light_moment, o.light_moment),
        }
    }

    /// The point the irradiance is expanded about: the members' centroid weighted by the
    /// light they send, A_j B̄_j, the channels summed; `None` for a dark source.
    fn about(&self) -> Option<V3> {
        (self.light > 0.0).then(|| scale(self.light_moment, 1.0 / self.light))
    }

    /// The irradiance at a point `x` with normal `n` that every member faces, unoccluded,
    /// the three channels expanded about the point `c` ([`Emitter::about`]).
    fn irradiance(&self, c: V3, x: V3, n: V3) -> Rgb {
        self.expansion::<3>(c, x, n).map(|h| h.max(0.0))
    }

    /// The expansion of [`Emitter::irradiance`] in the first `N` channels, before it is
    /// clipped at 0: linear in the members' B about a fixed `c`.
    fn expansion<const N: usize>(&self, c: V3, x: V3, n: V3) -> [f64; N] {
        use std::f64::consts::PI;
        let d = sub(c, x);
        let r2 = dot(d, d);
        let f = dot(n, d);
        if r2 <= 0.0 || f <= 0.0 {
            return [0.0; N];
        }
        // π g, π ∇g and π ∇²g at c, with g(y) = n · (y − x) / (π |y − x|⁴):
        // π ∇²g = −4 (n dᵀ + d nᵀ) / r⁶ − 4 f I / r⁶ + 24 f d dᵀ / r⁸
        let inv = 1.0 / r2;
        let inv4 = inv * inv;
        let inv6 = inv4 * inv;
        let g = f * inv4;
        let grad = sub(scale(n, inv4), scale(d, 4.0 * f * inv6));
        let (a, b, diagonal) = (-4.0 * inv6, 24.0 * f * inv6 * inv, -4.0 * f * inv6);
        // ∇²g with its off-diagonal entries twice, as tr(∇²g P) counts them
        let hessian: Sym = [
            2.0 * a * n[0] * d[0] + b * d[0] * d[0] + diagonal,
            2.0 * a * n[1] * d[1] + b * d[1] * d[1] + diagonal,
            2.0 * a * n[2] * d[2] + b * d[2] * d[2] + diagonal,
            2.0 * (a * (n[0] * d[1] + n[1] * d[0]) + b * d[0] * d[1]),
            2.0 * (a * (n[0] * d[2] + n[2] * d[0]) + b * d[0] * d[2]),
            2.0 * (a * (n[1] * d[2] + n[2] * d[1]) + b * d[1] * d[2]),
        ];
        let hc = [
            hessian[0] * c[0] + 0.5 * (hessian[3] * c[1] + hessian[4] * c[2]),
            hessian[1] * c[1] + 0.5 * (hessian[3] * c[0] + hessian[5] * c[2]),
            hessian[2] * c[2] + 0.5 * (hessian[4] * c[0] + hessian[5] * c[1]),
        ];
        let chc = dot(c, hc);
        let mut out = [0.0; N];
        for (ch, out) in out.iter_mut().enumerate() {
            // the weights' sum W and moment m at x
            let w = dot(self.normal[ch], x) - self.offset[ch];
            let s = &self.spread[ch];
            let l = &self.lever[ch];
            let m = [
                dot(s[0], x) - l[0],
                dot(s[1], x) - l[1],
                dot(s[2], x) - l[2],
            ];
            let first = dot(grad, m) - w * dot(grad, c);
            // tr(∇²g P(x)) with P(x) = Σ_k x_k P_k − P₀
            let p = &self.second[ch];
            let o = &self.second_offset[ch];
            let mut trace = 0.0;
            for e in 0..6 {
                trace += hessian[e] * (x[0] * p[0][e] + x[1] * p[1][e] + x[2] * p[2][e] - o[e]);
            }
            let second = trace - 2.0 * dot(m, hc) + w * chc;
            *out = (w * g + first + 0.5 * second) / PI;
        }
        out
    }
}

/// What the oracle needs of a cluster's members, gathered once per refinement pass.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct State {
    /// Σ A_j E_j and the largest E_j over the members (largest channel of the peak emission).
    emitted: f64,
    emitted_max: f64,
    /// Σ A_j B̄_j and the largest B̄_j (the mean of B, largest channel).
    reflected: f64,
    reflected_max: f64,
    /// The largest ρ, the largest w_R and the least tolerance over the members.
    rho: f64,
    weight: f64,
    tolerance: f64,
}

/// What the oracle makes of a pair with a cluster at an end.
#[derive(Debug, Clone)]
pub(super) enum ClusterVerdict {
    /// Split the receiver, the source, or (a cluster with itself) both.
    Receiver,
    Source,
    Both,
    Link(ClusterLinkGeometry),
    /// No ray got through: no link, with the oracle's factor for what the rays may have
    /// missed.
    Hidden(f64),
    Inert,
}

#[derive(Debug, Clone)]
pub(super) struct ClusterLinkGeometry {
    pub(super) visibility: f64,
    pub(super) affine: bool,
    pub(super) smooth: f64,
    pub(super) sampled: f64,
    pub(super) members: Option<Box<[u8]>>,
}

/// How [`Hierarchy::sample`] draws a point of an end: by area on a receiving end (again
/// while it falls on a covered part), by area or by the light its members send on a
/// sending one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Draw {
    Receiving,
    Area,
    Light,
}

/// A point drawn on an end of a cluster link ([`Hierarchy::sample`]).
struct Sample {
    x: V3,
    surface: usize,
    normal: V3,
    /// The element whose tree holds the point's B: a member patch's root, or the end.
    element: u32,
    /// The point in its surface's parameters.
    at: (f64, f64),
}

/// The shape of one end of a link: its bound, centre and the largest diameter of a member.
struct End {
    bound: Bound,
    centre: V3,
    member: f64,
}

impl Hierarchy<'_> {
    /// The bound and centre of a cluster or element.
    fn end(&self, id: u32) -> End {
        if is_cluster(id) {
            let c = self.clusters.get(id);
            return End {
                bound: c.bound,
                centre: c.centre,
                member: c.member_diameter,
            };
        }
        let c = self.elements[id as usize].piece.corners(&self.geo.quads);
        let bound = Bound::of_polygon(
            &c,
            self.geo.quads[self.elements[id as usize].piece.surface].n,
        );
        End {
            member: bound.diameter(),
            bound,
            centre: self.element_centre(id),
        }
    }

    /// The centroid of a cluster or an element.
    pub(super) fn centre_of(&self, id: u32) -> V3 {
        if is_cluster(id) {
            self.clusters.get(id).centre
        } else {
            self.element_centre(id)
        }
    }

    /// The centroid of an element.
    fn element_centre(&self, e: u32) -> V3 {
        self.elements[e as usize].piece.centre(&self.geo.quads)
    }

    /// Calls `f(element, area, centroid, normal)` for each member of a cluster (the root
    /// elements of its patches), or for the element itself.
    fn for_members(&self, id: u32, mut f: impl FnMut(u32, f64, V3, V3)) {
        if is_cluster(id) {
            let span = self.clusters.span(id);
            for (&p, m) in self.clusters.order()[span.clone()]
                .iter()
                .zip(&self.members[span])
            {
                f(p, m.area, m.centre, m.normal);
            }
        } else {
            let el = &self.elements[id as usize];
            let n = self.geo.quads[el.piece.surface].n;
            f(id, el.area, self.element_centre(id), n);
        }
    }

    /// The [`Emitter`] of every cluster from the members' B, children before parents: the
    /// two subtrees of a large cluster in parallel (in every sweep; sequential, it took the
    /// 81 icospheres 0.14 s a sweep, on 2 cores 0.075 s).
    fn emitters(&self, out: &mut Vec<Emitter>) {
        // every slot is written below, children before parents
        out.resize(self.clusters.nodes.len(), Emitter::default());
        if !out.is_empty() {
            let root = crate::three_d::cluster::CLUSTER;
            self.subtree_emitters(root, out, PARALLEL_EMITTERS);
        }
    }

    /// The [`Emitter`]s of cluster `id` and of the clusters under it into `out`, which holds
    /// exactly those, `id`'s first. The clusters are in preorder ([`Clusters`]): a cluster
    /// of k members is followed by its first child's subtree, then its second's, k − 1
    /// clusters in all (each a binary split of its members). Subtrees of `parallel` clusters
    /// or more are filled in parallel.
    fn subtree_emitters(&self, id: u32, out: &mut [Emitter], parallel: usize) {
        let [a, b] = self.clusters.get(id).children;
        let (head, rest) = out.split_first_mut().expect("the cluster's own slot");
        let big = rest.len() >= parallel;
        let (left, right) = rest.split_at_mut(self.member_count(a) - 1);
        let fill = |child: u32, part: &mut [Emitter]| -> Emitter {
            if is_cluster(child) {
                self.subtree_emitters(child, part, parallel);
                part[0]
            } else {
                self.emitter(child, &[])
            }
        };
        let (x, y) = if big {
            rayon::join(|| fill(a, left), || fill(b, right))
        } else {
            (fill(a, left), fill(b, right))
        };
        *head = x.add(&y);
    }

    /// The [`Emitter`] of a cluster (from `clusters`) or of an element (from its B).
    fn emitter(&self, id: u32, clusters: &[Emitter]) -> Emitter {
        if is_cluster(id) {
            return clusters[(id & !crate::three_d::cluster::CLUSTER) as usize];
        }
        let el = &self.elements[id as usize];
        self.element_emitter(id, el.sent0().map(|x| x / el.area.sqrt()))
    }

    /// The [`Emitter`] of element `e` with the mean B `mean`, about its centroid.
    fn element_emitter(&self, e: u32, mean: Rgb) -> Emitter {
        let el = &self.elements[e as usize];
        let q = &self.geo.quads[el.piece.surface];
        let cov = covariance(&el.piece.corners(&self.geo.quads), q.tri);
        Emitter::member(el.area, mean, self.element_centre(e), q.n, cov)
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
            weight: self.indirect.largest(surface),
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

    /// Weighs the clusters' members by the light they send now, for drawing a source's points
    /// by it ([`Hierarchy::cluster_visibility`]).
    pub(super) fn weigh_light(&mut self) {
        let elements = &self.elements;
        self.clusters.weigh_light(|p| {
            let root = &elements[p];
            root.mean_of(&[root.sent0()])
        });
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
    pub(super) fn cluster_outgrown(&self, r: u32, s: u32, smooth: f64, sampled: f64) -> bool {
        let (er, es) = (self.end(r), self.end(s));
        if !self.split_lowers(r, er.bound.diameter(), es.bound.diameter(), smooth, sampled) {
            return false;
        }
        let (sr, ss) = (self.state(r), self.state(s));
        self.cluster_error(&sr, &ss, er.bound.distance(&es.bound), smooth) > sr.tolerance
    }

    /// Whether splitting a pair with a cluster at an end, receiver `r` of diameter `dr` and a
    /// source of diameter `ds`, may lower its estimate `smooth`, of which `sampled` is the
    /// sampling error of the visible fraction: the estimate's size factor is the larger end's,
    /// which a receiver at its finest level keeps when the source is no larger (as for pairs
    /// of elements, `Hierarchy::splits`); and the sampling error adds up over the source's
    /// parts, so splitting the source lowers only the rest.
    fn split_lowers(&self, r: u32, dr: f64, ds: f64, smooth: f64, sampled: f64) -> bool {
        is_cluster(r) || self.splittable(r) || (ds > dr && smooth - sampled > sampled)
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
        if !self.takes_part(r, true) || !self.takes_part(s, false) || !er.bound.facing(&es.bound) {
            return (ClusterVerdict::Inert, 0);
        }
        let (sr, ss) = (self.state(r), self.state(s));
        let dist = er.bound.distance(&es.bound);
        let (dr, ds) = (er.bound.diameter(), es.bound.diameter());
        let size = dr.max(ds);
        let can = |id: u32| is_cluster(id) || self.splittable(id);
        let split = || {
            // the end with the larger box, unless it is an element at its finest level
            if (dr >= ds && can(r)) || !can(s) {
                ClusterVerdict::Receiver
            } else {
                ClusterVerdict::Source
            }
        };
        // taking the ends as points: with an affine source ([`Emitter`]) what is left is
        // third order in the source's size over the distance, and first order in a
        // receiving member's (it receives a constant); otherwise first order in the larger
        let affine = es.bound.before(&er.bound);
        let smooth = if affine {
            ((ds / (ds + dist)).powi(3) + er.member / (er.member + dist)).min(1.0)
        } else {
            size / (size + dist)
        };
        // a split only where it lowers the estimate (ends closer than [`Rules::separation`] are
        // split regardless: there the ends are not points)
        let lowers = self.split_lowers(r, dr, ds, smooth, 0.0);
        if dist < self.rules.separation * size
            || (lowers && self.cluster_error(&sr, &ss, dist, smooth) > sr.tolerance)
        {
            return (split(), 0);
        }
        let seed = pair_seed(self.cluster_identity(r), self.cluster_identity(s));
        let (v, valid, rays) = self.cluster_visibility(r, s, seed);
        // partly visible: a receiver that can be split gets no smoothness credit (a shadow
        // edge is not what its members' constants can follow). One at its finest level
        // receives the link's mean, which is wrong by the sampling error of V and by V's
        // correlation with the kernel over the pair, first order in the larger end's size
        let (smooth, sampled) = if v >= 1.0 {
            (smooth, 0.0)
        } else if v <= 0.0 {
            // hidden: no more of the transfer may be missing than the rays' bound, which
            // adds up over the source's parts as a sampling error does
            let unseen = unseen_bound(valid as u64);
            (unseen, unseen)
        } else if can(r) {
            (1.0, 0.0)
        } else {
            let sampled = (v * (1.0 - v) / valid as f64).sqrt();
            ((size / (size + dist) + sampled).min(1.0), sampled)
        };
        let lowers = self.split_lowers(r, dr, ds, smooth, sampled);
        if v < 1.0 && lowers && self.cluster_error(&sr, &ss, dist, smooth) > sr.tolerance {
            return (split(), rays);
        }
        if norm(sub(er.centre, es.centre)) <= 0.0 {
            return (split(), rays);
        }
        // the link, or its absence, carries V from rays that did not judge it (see the
        // element links' oracle, [`super::refine`]: the judging rays' V errs with one sign
        // over the pairs that were not split)
        let (v, _, more) = self.cluster_visibility(r, s, seed ^ 2);
        let mut rays = rays + more;
        if v <= 0.0 {
            return (ClusterVerdict::Hidden(smooth), rays);
        }
        // each member's own V (see the module doc), whatever the judging rays saw: they are
        // drawn by area over the members, and a small member that an occluder hides may get
        // none. A book's top beside a taller neighbour 3 mm away took the far wall's light
        // through links from the whole book that all 16 rays had passed (from its large
        // sides), with V = 1 against 0.2 for the top: in a furnace (every surface E = 1,
        // ρ = ½, B = 2 exactly) that top came out 3.6 % bright, and a row of ten such books
        // up to 13.7 %. Before B is known a source's points are drawn by the light it emits,
        // or by area with the kernel alone where it emits none, and every cluster link is
        // judged again after the first solve (`Hierarchy::rerefine`): no members' rays until
        // then, which would be cast twice
        let members = if self.b_known() && is_cluster(r) {
            let (m, more) = self.member_visibility(r, s, seed ^ 3);
            rays += more;
            Some(m)
        } else {
            None
        };
        (
            ClusterVerdict::Link(ClusterLinkGeometry {
                visibility: v,
                affine,
                smooth,
                sampled,
                members,
            }),
            rays,
        )
    }

    /// Whether an end receives (`receiving`) or sends anything: not a covered element, nor a
    /// cluster of covered patches ([`crate::three_d::cover`]), unless it sends its emission.
    fn takes_part(&self, id: u32, receiving: bool) -> bool {
        if is_cluster(id) {
            return self.clusters.takes_part(id);
        }
        let el = &self.elements[id as usize];
        if receiving {
            el.receives()
        } else {
            el.sends()
        }
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

    /// A point of a cluster (of a member picked by the area that takes part in the transfer,
    /// [`crate::three_d::cluster::Clusters::weigh`]) or of an element, with its surface and
    /// normal. A `receiving` end's point is drawn again while it falls on a covered part, as
    /// the element links' are ([`crate::three_d::visibility::visible_fraction_over`]): such a
    /// part receives nothing ([`add_constant`] delivers the moments of its exposed part), and
    /// counting its blocked rays too would take its share of the light twice. A sending end's
    /// point may fall there: a partly covered element's polynomial is that of its exposed part
    /// continued over the whole element, and its blocked rays take the continuation back out.
    fn sample(&self, id: u32, draw: Draw, rng: &mut SplitMix) -> Sample {
        let receiving = draw == Draw::Receiving;
        let mut point = Sample {
            x: [0.0; 3],
            surface: 0,
            normal: [0.0; 3],
            element: 0,
            at: (0.0, 0.0),
        };
        for _ in 0..COVERED_DRAWS {
            // the element the point lies in: a member patch's root, or the end itself
            let (element, piece) = if is_cluster(id) {
                let u = rng.next_f64();
                let p = if draw == Draw::Light {
                    self.clusters.pick_by_light(id, u)
                } else {
                    self.clusters.pick(id, u)
                };
                (p as u32, crate::three_d::geometry::Piece::whole(p))
            } else {
                (id, self.elements[id as usize].piece)
            };
            let q = &self.geo.quads[piece.surface];
            let (s, t) = uniform_in(&piece, q.tri, rng);
            point = Sample {
                x: q.at(s, t),
                surface: piece.surface,
                normal: q.n,
                element,
                at: (s, t),
            };
            let covered = || {
                self.masks[piece.surface]
                    .as_ref()
                    .is_some_and(|m| m.covered(s, t))
            };
            if !receiving || !covered() {
                break;
            }
        }
        point
    }

    /// The visible fraction between two ends: of [`CLUSTER_RAYS`] pairs of points, the share
    /// of the light they carry (those that face each other, each weighted by the kernel
    /// between its points and by the source's B where the ray ends,
    /// [`Hierarchy::radiosity_at`]) that nothing stops (1 when none face, and weighted by the
    /// kernel alone while the source is dark, before the first solve).
    ///
    /// The link gives every receiving member V times its unoccluded transfer, so the light
    /// it delivers in all is right when V is the share of that transfer that is not
    /// stopped: the kernel-weighted fraction, as the element links' is
    /// ([`crate::three_d::visibility::visible_fraction_over`]). Counted unweighted, a pair of
    /// points far apart, which carries little and is the more likely to be stopped on its way,
    /// counts as much as a near one: a fraction that errs low, with one sign over the links.
    ///
    /// A cluster's points are drawn in strata, an equal number from each of its two children
    /// (weighted back by the children's areas), not by area over all its members. A link
    /// gives every receiving member the same V, so it is right for a member only where V
    /// does not depend on the member. Where one child hides the other from the source (a
    /// seat over its feet, seen from the ceiling), drawing by area found the small child so
    /// rarely that the link passed as wholly visible: in a furnace the foot's top, under a
    /// seat 5 mm above it, gathered 0.46 of a form factor more than its whole hemisphere
    /// through thousands of such links, each within the tolerance, all erring the same way
    /// (B 2.6 against 2). With strata, a child that its sibling hides shows up as a blocked
    /// ray, and the pair is judged partly visible, which splits it where it matters.
    pub(super) fn cluster_visibility(&self, r: u32, s: u32, seed: u64) -> (f64, usize, u64) {
        let mut rng = SplitMix(seed);
        let by_light = is_cluster(s) && self.clusters.light(s) > 0.0;
        let (sr, ss) = (self.strata(r, false), self.strata(s, by_light));
        let sending = if by_light { Draw::Light } else { Draw::Area };
        // per pair of strata: the pairs drawn, those facing, and the light of the facing
        // ones, in all and unstopped (by kernel and source B, and by kernel alone for a
        // source whose B is still 0)
        let mut drawn = [[0usize; 2]; 2];
        let mut valid = [[0usize; 2]; 2];
        let mut light = [[[0.0f64; 2]; 2]; 2];
        let mut open = [[[0.0f64; 2]; 2]; 2];
        // the kernel's weight is kept finite as the element links' is (the smaller end's
        // area over π added to r²): ends that are judged may be near, or one inside the other
        let disc = self.end_area(r).min(self.end_area(s)) / std::f64::consts::PI;
        let mut rays = 0u64;
        for k in 0..CLUSTER_RAYS {
            let (a, b) = (k % sr.len(), (k / sr.len()) % ss.len());
            let recv = self.sample(sr[a].0, Draw::Receiving, &mut rng);
            let send = self.sample(ss[b].0, sending, &mut rng);
            let (x, i, y, j) = (recv.x, recv.surface, send.x, send.surface);
            drawn[a][b] += 1;
            let Some(kernel) = facing_kernel(&recv, &send, disc) else {
                continue;
            };
            valid[a][b] += 1;
            rays += 1;
            let w = [kernel * self.drawn_light(&send, by_light), kernel];
            let through = !self.geo.bvh.occluded(x, y, [i, j]);
            for (c, w) in w.into_iter().enumerate() {
                light[c][a][b] += w;
                if through {
                    open[c][a][b] += w;
                }
            }
        }
        let facing: usize = valid.iter().flatten().sum();
        // each stratum's mean light per pair drawn, weighted by its ends' areas
        let fraction = |c: usize| {
            let (mut v, mut weight) = (0.0, 0.0);
            for (a, &(_, wa)) in sr.iter().enumerate() {
                for (b, &(_, wb)) in ss.iter().enumerate() {
                    if drawn[a][b] > 0 {
                        let per = wa * wb / drawn[a][b] as f64;
                        v += per * open[c][a][b];
                        weight += per * light[c][a][b];
                    }
                }
            }
            (weight > 0.0).then(|| v / weight)
        };
        match fraction(0).or_else(|| fraction(1)) {
            Some(v) => (v, facing, rays),
            None => (1.0, 0, rays),
        }
    }

    /// B where a ray from `send` starts, over its patch's mean B when the point was drawn by
    /// the light its cluster's members send (in proportion to that mean: the ray is then
    /// weighted by its part of it).
    fn drawn_light(&self, send: &Sample, by_light: bool) -> f64 {
        let (s, t) = send.at;
        let here = self.radiosity_at(send.element, s, t);
        if !by_light {
            return here;
        }
        let patch = &self.elements[send.element as usize];
        let mean = patch.mean_of(&[patch.sent0()]);
        if mean > 0.0 {
            here / mean
        } else {
            0.0
        }
    }

    /// Each receiving member's own visible fraction from source `s`, in 1/255ths, in the
    /// clusters' order: 1 or 0 as one ray gets through or not (1 where no pair faces: the
    /// member then gathers next to nothing from the source). Returns the rays cast.
    ///
    /// The ray's ends are one of [`MEMBER_CANDIDATES`] facing pairs, each a uniform point of
    /// the member (not on a covered part) and a point of the source: one of [`SOURCE_POINTS`]
    /// drawn as the link's are, once per link, where the source is within 1/[`TOWARD_SPREAD`]
    /// of its distance from the member, else one drawn toward the member
    /// ([`Hierarchy::drawn_toward`]); the pair is drawn in proportion to the light it carries
    /// over the chance of its source point (the kernel times the source's B, over the share
    /// of the source's light or area the point was drawn by).
    /// The ray then estimates the light-weighted V that the transfer needs, not the share of
    /// uniform pairs, which differs from it by V's correlation with the kernel over the pair:
    /// a box's side sees the near part of a wall past its neighbours and the far part over
    /// them. With uniform pairs the boxes of the room with 3 × 3 boxes made of meshes
    /// gathered 0.15 % less on the mean than with 256 rays a member; and a fresh draw of the
    /// source's point for each candidate cost the 81 icospheres' refinement a quarter more.
    ///
    /// The link's one V is right in all but not per member: the members that occluders hide
    /// gather V times their unoccluded transfer where they should gather none, and those in
    /// view too little, with one sign from every source. A member's own rays are an estimate
    /// of its own V whose error changes sign from link to link and averages out over a
    /// member's many links.
    pub(super) fn member_visibility(&self, r: u32, s: u32, seed: u64) -> (Box<[u8]>, u64) {
        let mut rng = SplitMix(seed);
        let by_light = is_cluster(s) && self.clusters.light(s) > 0.0;
        let sending = if by_light { Draw::Light } else { Draw::Area };
        let source_area = self.end_area(s);
        let span = self.clusters.span(r);
        let (sc, sr) = self.end(s).bound.sphere();
        // the measure the shared points are drawn by: over it, the chance of a point
        // (for a candidate's weight on the scale of those drawn toward the member)
        let total_light = if by_light {
            self.clusters.light(s)
        } else {
            source_area
        };
        // the source's points, each with the light its ray is weighted by
        let points: Vec<(Sample, f64)> = (0..SOURCE_POINTS)
            .map(|_| {
                let send = self.sample(s, sending, &mut rng);
                let light = if by_light {
                    self.drawn_light(&send, true)
                } else {
                    1.0
                };
                (send, light)
            })
            .collect();
        let mut rays = 0u64;
        let out = self.clusters.order()[span.clone()]
            .iter()
            .zip(&self.members[span])
            .map(|(&p, m)| {
                // a member whose plane leaves the source behind it receives nothing from it
                if leaves_behind(m.normal, m.centre, (sc, sr)) {
                    return 255;
                }
                let disc = self.elements[p as usize].area.min(source_area) / std::f64::consts::PI;
                // a source that spreads over much of the member's view: each candidate's
                // point drawn toward the member, else one of the link's shared points
                let toward = norm(sub(sc, m.centre)) < TOWARD_SPREAD * sr;
                // one pair among the first facing candidates, drawn in proportion to the
                // light it carries over the chance of its source point (a weighted
                // reservoir of one)
                let (mut chosen, mut total, mut facing) = (None, 0.0, 0);
                for _ in 0..COVERED_DRAWS {
                    let recv = self.sample(p, Draw::Receiving, &mut rng);
                    let drawn;
                    let (send, light) = if toward {
                        drawn = self.drawn_toward(s, m.centre, m.normal, by_light, &mut rng);
                        (&drawn.0, drawn.1)
                    } else {
                        let (send, light) =
                            &points[(rng.next_u64() % SOURCE_POINTS as u64) as usize];
                        (send, *light * total_light)
                    };
                    let Some(kernel) = facing_kernel(&recv, send, disc) else {
                        continue;
                    };
                    let w = kernel * light;
                    total += w;
                    if w > 0.0 && rng.next_f64() * total < w {
                        chosen = Some((recv.x, recv.surface, send.x, send.surface));
                    }
                    facing += 1;
                    if facing == MEMBER_CANDIDATES {
                        break;
                    }
                }
                let Some((x, i, y, j)) = chosen else {
                    return 255;
                };
                rays += 1;
                if self.geo.bvh.occluded(x, y, [i, j]) {
                    0
                } else {
                    255
                }
            })
            .collect();
        (out, rays)
    }

    /// A point of source `s` drawn toward a receiving member at `x` with normal `n`, with its
    /// light over the chance of drawing it (B(y) / p(y), or 1 / p(y) where the source is
    /// weighted by area): the source's cluster tree, then the four-way split of the member or
    /// element it reaches, are gone down, each child taken in proportion to an estimate of
    /// what it sends to x (its light, or area, times the kernel from its centre, its radius
    /// added to the distance), until the part's radius is below 1/[`TOWARD_SPREAD`] of its
    /// distance from x; the point is then drawn in that part by light (a cluster) or area.
    ///
    /// A member's one ray is chosen among its candidates in proportion to their weights, so
    /// its expectation is the share of the light that gets through only as far as the
    /// candidates' weights are alike: drawn by the light alone, a source whose kernel peaks
    /// on a small part of it (a wall's strip beside the ceiling triangle that receives)
    /// rarely offers that part, and the ray goes to the far part, which is the one hidden
    /// (the unit test: a plate under a long strip of which it sees only the near end).
    fn drawn_toward(
        &self,
        s: u32,
        x: V3,
        n: V3,
        by_light: bool,
        rng: &mut SplitMix,
    ) -> (Sample, f64) {
        // what a part of centre c and radius r, of light (or area) w, may send toward x:
        // w cos θx cos θy / r², each cosine bounded over the part's sphere (the source's
        // cosine by the part's normal cone, or at least the sphere's spread r / |d|), r²
        // kept from 0 by the part's radius
        let estimate = |c: V3, r: f64, w: f64, cone: &Bound| {
            let d = sub(c, x);
            let (r2, f) = (dot(d, d) + r * r, dot(n, d) + r);
            if w <= 0.0 || f <= 0.0 {
                return 0.0;
            }
            let away = scale(d, -1.0 / r2.sqrt());
            let cy = cone.largest_cosine(away).max(r / r2.sqrt()).min(1.0);
            w * f * cy / (r2 * r2.sqrt())
        };
        let measure = |id: u32| {
            if by_light {
                self.clusters.light(id)
            } else {
                self.clusters.weight(id)
            }
        };
        let part = |id: u32| {
            if is_cluster(id) {
                let bound = self.clusters.get(id).bound;
                let (c, r) = bound.sphere();
                (c, r, bound)
            } else {
                let piece = &self.elements[id as usize].piece;
                let (quads, q) = (&self.geo.quads, &self.geo.quads[piece.surface]);
                let corners = piece.corners(quads);
                let bound = Bound::of_polygon(&corners, q.n);
                (centroid(&corners, q.tri), piece.radius(quads), bound)
            }
        };
        let mut id = s;
        let mut chance = 1.0;
        while is_cluster(id) {
            let (c, r) = self.clusters.get(id).bound.sphere();
            if norm(sub(c, x)) >= TOWARD_SPREAD * r {
                break;
            }
            let [ea, eb] = self.clusters.get(id).children.map(|child| {
                let (c, r, bound) = part(child);
                estimate(c, r, measure(child), &bound)
            });
            let [a, b] = self.clusters.get(id).children;
            if ea + eb <= 0.0 {
                break;
            }
            let pa = ea / (ea + eb);
            if rng.next_f64() < pa {
                (id, chance) = (a, chance * pa);
            } else {
                (id, chance) = (b, chance * (1.0 - pa));
            }
        }
        if is_cluster(id) {
            let send = self.sample(id, if by_light { Draw::Light } else { Draw::Area }, rng);
            let light = if by_light {
                self.drawn_light(&send, true)
            } else {
                1.0
            };
            return (send, light * measure(id) / chance);
        }
        // an element (a member's root, or the source itself): its four-way split
        let element = id;
        let surface = self.elements[element as usize].piece.surface;
        let q = &self.geo.quads[surface];
        let mut piece = self.elements[element as usize].piece;
        let mut area = self.elements[element as usize].area;
        for _ in 0..TOWARD_LEVELS {
            let corners = piece.corners(&self.geo.quads);
            let radius = piece.radius(&self.geo.quads);
            if norm(sub(centroid(&corners, q.tri), x)) >= TOWARD_SPREAD * radius {
                break;
            }
            let children: [Piece; 4] = std::array::from_fn(|c| piece.child(q.tri, c));
            // a flat part's cosine at the source is exact: n_S · (x − y) is the same at
            // every one of its points
            let plane = Bound::of_polygon(&corners, q.n);
            let weights = children.map(|child| {
                let centre = child.centre(&self.geo.quads);
                estimate(centre, 0.5 * radius, 0.25 * area, &plane)
            });
            let sum: f64 = weights.iter().sum();
            if sum <= 0.0 {
                break;
            }
            let mut u = rng.next_f64() * sum;
            let mut pick = 3;
            for (c, &w) in weights.iter().enumerate() {
                if u < w {
                    pick = c;
                    break;
                }
                u -= w;
            }
            // the last child with weight, should rounding leave u beyond them all
            while weights[pick] <= 0.0 {
                pick -= 1;
            }
            chance *= weights[pick] / sum;
            piece = children[pick];
            area *= 0.25;
        }
        let (ps, pt) = uniform_in(&piece, q.tri, rng);
        let send = Sample {
            x: q.at(ps, pt),
            surface,
            normal: q.n,
            element,
            at: (ps, pt),
        };
        let b = if by_light {
            self.radiosity_at(element, ps, pt)
        } else {
            1.0
        };
        (send, b * area / chance)
    }

    /// The strata of an end's points ([`Hierarchy::cluster_visibility`]): a cluster's two
    /// children with the areas of them that take part, or the end itself.
    fn strata(&self, id: u32, by_light: bool) -> smallvec::SmallVec<[(u32, f64); 2]> {
        let mut out = smallvec::SmallVec::new();
        if is_cluster(id) {
            for c in self.clusters.get(id).children {
                let w = if by_light {
                    self.clusters.light(c)
                } else {
                    self.clusters.weight(c)
                };
                if w > 0.0 {
                    out.push((c, w));
                }
            }
        }
        if out.is_empty() {
            out.push((id, 1.0));
        }
        out
    }

    /// The constant H (as h₀ = H √A) that cluster link `l` delivers to each member of its
    /// receiver, each at its own centroid, into `out` (one slot per member, in their order).
    fn cluster_link_irradiance(&self, l: &ClusterLink, lights: &Lights, out: &mut [Rgb]) {
        let mut slots = out.iter_mut();
        let mut put = |h: Rgb| {
            if let Some(slot) = slots.next() {
                *slot = h;
            }
        };
        // each member's V: its own where the link keeps one, else the link's
        let mut k = 0;
        let mut next_v = || {
            let v = l.member_v(k);
            k += 1;
            v
        };
        // an affine link from an element: its factors, held or (beyond the cap) worked out now
        let worked_out;
        let factors = match &l.factors {
            Some(f) => Some(f),
            None if l.affine && !is_cluster(l.src) => {
                worked_out = self.unit_irradiance(l);
                Some(&worked_out)
            }
            None => None,
        };
        if let Some(factors) = factors {
            let el = &self.elements[l.src as usize];
            let mean = el.sent0().map(|x| x / el.area.sqrt());
            // a dark source sends nothing (as [`Emitter::about`] has it)
            if mean.iter().sum::<f64>() <= 0.0 {
                out.fill([0.0; 3]);
                return;
            }
            for (slot, &f) in out.iter_mut().zip(factors.iter()) {
                *slot = mean.map(|b| (b * f64::from(f)).max(0.0));
            }
            return;
        }
        if l.affine {
            let source = self.emitter(l.src, &lights.emitters);
            let Some(about) = source.about() else {
                out.fill([0.0; 3]);
                return;
            };
            // a member whose plane leaves the source's sphere behind it receives nothing: the
            // point the transfer expands about is inside that sphere (a mean of the members'
            // centroids, B̄ ≥ 0), so the transfer would find n · d < 0 there, after the work
            let (sc, sr) = self.end(l.src).bound.sphere();
            self.for_members(l.recv, |_, area, x, n| {
                let v = next_v();
                if leaves_behind(n, x, (sc, sr)) {
                    put([0.0; 3]);
                    return;
                }
                let h = source.irradiance(about, x, n);
                // a constant H on the member: h₀ = H √A
                put(h.map(|h| v * h * area.sqrt()));
            });
            return;
        }
        if is_cluster(l.src) && is_cluster(l.recv) {
            self.spread_into_cluster(l, lights, out);
            return;
        }
        // an element source, or a cluster into an element: the receiver's one member is its
        // centre, toward which the link's cut is worked out
        let source = self.spread_source(l.src, lights);
        self.for_members(l.recv, |_, area, x, n| {
            let v = next_v();
            let h = source.direct(x, n).unwrap_or_else(|| {
                let bound = &self.clusters.get(l.src).bound;
                self.parts_at(&self.cut_of(l), lights, x, n, bound)
            });
            // a constant H on the member: h₀ = H √A
            put(h.map(|h| v * h * area.sqrt()));
        });
    }

    /// Source `src` of a link that is not affine, as [`SpreadSource::direct`] reads it at
    /// each receiving member.
    fn spread_source<'e>(&'e self, src: u32, lights: &'e Lights) -> SpreadSource<'e> {
        SpreadSource {
            light: self.source_light(src, lights),
            centre: self.centre_of(src),
        }
    }

    /// The cut of link `l`'s source toward its receiver's centre: the one it keeps
    /// ([`ClusterLink::cut`]), or worked out now ([`Hierarchy::intensity_cut`]).
    fn cut_of<'l>(&self, l: &'l ClusterLink) -> std::borrow::Cow<'l, [u32]> {
        match &l.cut {
            Some(cut) => std::borrow::Cow::Borrowed(cut),
            None => {
                let mut cut = Vec::new();
                self.intensity_cut(l.src, self.toward_receiver(l), &mut cut);
                std::borrow::Cow::Owned(cut)
            }
        }
    }

    /// The unoccluded irradiance at a receiving element's point `x` with normal `n` of the
    /// clusters and patches `cut`, each read apart and only where it sends toward x
    /// ([`Weights::add_at`]).
    fn parts_at(&self, cut: &[u32], lights: &Lights, x: V3, n: V3, bound: &Bound) -> Rgb {
        let (mut w, mut m) = ([0.0; 3], [0.0; 3]);
        for &k in cut {
            self.part_weights(k, lights).add_at(x, &mut w, &mut m);
        }
        weighted_irradiance(w, m, x, n, bound)
    }

    /// The light of a link from a cluster that is not affine into a cluster, delivered to
    /// each receiving member into `out` as [`Hierarchy::cluster_link_irradiance`] does: at a
    /// member toward which the source's normals straddle, the weights of its whole cut
    /// toward the receiver's centre, summed once for the link. Read part by part, each only
    /// where it sends toward the member (as an element receiver reads them,
    /// [`Hierarchy::parts_at`]), a ball's cut toward another ball held 14 parts, nine in
    /// ten of them straddling the receiver, 206 M reads of a part in each sweep of the 81
    /// icospheres, and their solve took 48 s instead of 19 s. Summed, a part in the cut
    /// whose plane leaves a member behind it takes a little light from that member instead
    /// of giving it none.
    fn spread_into_cluster(&self, l: &ClusterLink, lights: &Lights, out: &mut [Rgb]) {
        let source = self.spread_source(l.src, lights);
        let mut parts: Option<Weights> = None;
        let mut k = 0;
        self.for_members(l.recv, |_, area, x, n| {
            let h = source.direct(x, n).unwrap_or_else(|| {
                let sum = parts.get_or_insert_with(|| {
                    self.cut_of(l).iter().fold(Weights::NONE, |sum, &p| {
                        sum.plus(&self.part_weights(p, lights))
                    })
                });
                let (mut w, mut m) = ([0.0; 3], [0.0; 3]);
                sum.add_at(x, &mut w, &mut m);
                weighted_irradiance(w, m, x, n, &self.clusters.get(l.src).bound)
            });
            // a constant H on the member: h₀ = H √A
            let v = l.member_v(k);
            out[k] = h.map(|h| v * h * area.sqrt());
            k += 1;
        });
    }

    /// The [`Weights`] of a cluster or patch of a cut ([`Hierarchy::intensity_cut`]).
    fn part_weights(&self, k: u32, lights: &Lights) -> Weights {
        if is_cluster(k) {
            return lights.weights[(k & !crate::three_d::cluster::CLUSTER) as usize];
        }
        let (normal, light) = match lights.patches.get(k as usize) {
            Some(&patch) => patch,
            None => self.patch_light(k),
        };
        // a cut's patches are roots: their centroids are the clusters'
        Weights::of_patch(normal, light, self.clusters.centres[k as usize])
    }

    /// The transfer of affine link `l` from an element to each receiving member (as
    /// [`Hierarchy::cluster_link_irradiance`] delivers it, V and √A included) per unit of
    /// the element's mean B: the member's point-to-polygon form factor to the element at its
    /// centroid, in closed form ([`point_polygon`]), so that the transfer is this factor times
    /// B̄ in each channel, a multiplication per member in every sweep.
    ///
    /// The element sends its mean B̄ through such a link, and for a constant B the closed form
    /// is exact. The element's [`Emitter`], the second-order expansion that a cluster source
    /// needs, leaves out a remainder of fourth order in the source's size over its distance,
    /// a few percent for a source as large as its distance, and of one sign over the like
    /// links of a scene: in the room with 3 × 3 boxes made of meshes, the walls' elements 2.5
    /// units across lit the boxes' sides 0.5–1.6 % short through their cluster links (see
    /// benches/README). The closed form costs about four arc tangents a member, once per link.
    fn unit_irradiance(&self, l: &ClusterLink) -> Box<[f32]> {
        let source = self.elements[l.src as usize].piece.corners(&self.geo.quads);
        let (sc, sr) = self.end(l.src).bound.sphere();
        let mut out = Vec::with_capacity(self.member_count(l.recv));
        let mut k = 0;
        self.for_members(l.recv, |e, area, x, n| {
            let v = l.member_v(k);
            k += 1;
            let h = if leaves_behind(n, x, (sc, sr)) {
                0.0
            } else {
                self.held_form_factor(e, area, x, n, &source, (sc, sr)) * v * area.sqrt()
            };
            out.push(h as f32);
        });
        out.into_boxed_slice()
    }

    /// The form factor of receiving member (or element) `e` (of `area`, centroid `x` and
    /// normal `n`) to an element `source` in sphere `(sc, sr)`: at its centroid where that
    /// will do ([`CENTROID_SPREAD`]), else the mean at [`Hierarchy::member_points`].
    fn held_form_factor(
        &self,
        e: u32,
        area: f64,
        x: V3,
        n: V3,
        source: &[V3; 4],
        (sc, sr): (V3, f64),
    ) -> f64 {
        let gap = norm(sub(x, sc)) - sr;
        if gap > 0.0 && gap * gap > CENTROID_SPREAD * area {
            return point_polygon(x, n, source);
        }
        let points = self.member_points(e);
        points
            .iter()
            .map(|&y| point_polygon(y, n, source))
            .sum::<f64>()
            / points.len() as f64
    }

    /// The points of a receiving member (or element) `e` at which a held kernel is read
    /// where its centroid would not do ([`CENTROID_SPREAD`]), each of equal weight: a rule of
    /// degree 2 on a triangle and of degree 3 on a parallelogram, so that the member's mean
    /// form factor is taken with an error of third order in its size over the distance
    /// instead of second. On a parallelogram, the 2 × 2 tensor Gauss points
    /// ([`Rule::gauss`]); on a triangle, the symmetric rule of the three points
    /// (2/3, 1/6, 1/6), one point fewer than the conical product rule of the same degree
    /// ([`crate::math::triangle::TriangleRule`]), whose weights also differ.
    fn member_points(&self, e: u32) -> smallvec::SmallVec<[V3; 4]> {
        let el = &self.elements[e as usize];
        let c = el.piece.corners(&self.geo.quads);
        if self.geo.quads[el.piece.surface].tri {
            let at = |a: V3, b: V3, d: V3| add(scale(a, 2.0 / 3.0), scale(add(b, d), 1.0 / 6.0));
            return smallvec::smallvec![
                at(c[0], c[1], c[2]),
                at(c[1], c[2], c[0]),
                at(c[2], c[0], c[1])
            ];
        }
        let gauss = &Rule::gauss(2).nodes;
        let (e1, e3) = (sub(c[1], c[0]), sub(c[3], c[0]));
        gauss
            .iter()
            .flat_map(|&v| gauss.iter().map(move |&u| (u, v)))
            .map(|(u, v)| add(c[0], add(scale(e1, u), scale(e3, v))))
            .collect()
    }

    /// The unit direction from link `l`'s source's centre to its receiver's: the one its
    /// [`ClusterLink::cut`] is worked out for.
    fn toward_receiver(&self, l: &ClusterLink) -> V3 {
        let toward = sub(self.centre_of(l.recv), self.centre_of(l.src));
        scale(toward, 1.0 / norm(toward))
    }

    /// Works out [`Hierarchy::unit_irradiance`] for the links that lack it, in their order,
    /// while the kernels held stay within `cap` ([`KERNELS_HELD`]); the links beyond it
    /// expand their source's light in each sweep. And the [`ClusterLink::cut`] of the links
    /// that lack it.
    fn hold_unit_irradiance(&mut self, cap: usize) {
        let mut links = std::mem::take(&mut self.cluster_links);
        let mut held: usize = links
            .iter()
            .filter_map(|l| l.factors.as_ref())
            .map(|f| f.len())
            .sum();
        let todo: Vec<bool> = links
            .iter()
            .map(|l| {
                let n = self.member_count(l.recv);
                let take = l.affine && !is_cluster(l.src) && l.factors.is_none() && held + n <= cap;
                held += if take { n } else { 0 };
                take
            })
            .collect();
        let this = &*self;
        links
            .par_iter_mut()
            .zip(todo)
            .filter(|(_, take)| *take)
            .for_each(|(l, _)| l.factors = Some(this.unit_irradiance(l)));
        links
            .par_iter_mut()
            .filter(|l| !l.affine && is_cluster(l.src) && l.cut.is_none())
            .for_each(|l| {
                let omega = this.toward_receiver(l);
                if this.clusters.get(l.src).bound.side(omega).is_none() {
                    let mut cut = Vec::new();
                    this.intensity_cut(l.src, omega, &mut cut);
                    l.cut = Some(cut.into_boxed_slice());
                }
            });
        self.cluster_links = links;
    }

    /// What [`SpreadSource::direct`] reads of `id`: an element's normal and B̄ A / π,
    /// whose intensity it takes toward each receiving member (toward the centre of a ball
    /// resting on a floor, the floor's elements sent its bottom triangles, which they see
    /// edge-on, 3–4 times their light, and the triangles came out 5–7 % bright), or a
    /// cluster's normal cone and [`Weights`].
    fn source_light<'e>(&'e self, id: u32, lights: &'e Lights) -> SourceLight<'e> {
        if !is_cluster(id) {
            let (normal, light) = match lights.patches.get(id as usize) {
                Some(&patch) => patch,
                None => self.patch_light(id),
            };
            return SourceLight::Element { normal, light };
        }
        let index = (id & !crate::three_d::cluster::CLUSTER) as usize;
        SourceLight::Cluster {
            bound: &self.clusters.nodes[index].bound,
            weights: &lights.weights[index],
        }
    }

    /// An element's normal and B̄ A / π (= b₀ √A / π in the orthonormal basis).
    fn patch_light(&self, e: u32) -> (V3, Rgb) {
        let el = &self.elements[e as usize];
        let w = el.area.sqrt() / std::f64::consts::PI;
        (
            self.geo.quads[el.piece.surface].n,
            el.sent0().map(|b| w * b),
        )
    }

    /// The [`Lights`] of the sweep, from the members' B.
    #[cfg(test)]
    fn lights(&self) -> Lights {
        let mut lights = Lights::default();
        self.relight_into(&mut lights);
        lights
    }

    /// Fills `lights` from the members' B, in the allocations it has (100 MB of [`Emitter`]s
    /// for 10⁵ triangles, in every sweep).
    fn relight_into(&self, lights: &mut Lights) {
        self.emitters(&mut lights.emitters);
        lights.weights.clear();
        lights
            .weights
            .par_extend(lights.emitters.par_iter().map(Weights::of_emitter));
        lights.patches.clear();
        lights.patches.par_extend(
            (0..self.quads.len() as u32)
                .into_par_iter()
                .map(|p| self.patch_light(p)),
        );
    }

    /// The clusters and patches under `id` (itself included) that hold, between them, its
    /// members that face the unit `omega`, each wholly, into `out`: a subtree whose normals
    /// all face ω is taken whole, one whose normals all face away is left out, and only
    /// those whose normal cone straddles the plane normal to ω are opened
    /// ([`crate::three_d::cluster::Bound::side`]); the [`Weights`] of the members facing ω
    /// are then the sum of theirs. Which they are depends on the geometry alone, so a link
    /// works them out once and reads their light in every sweep: opening the subtrees along
    /// a ball's terminator in every sweep visited 59 clusters and patches per link, 16 M in
    /// each sweep of 81 icospheres.
    fn intensity_cut(&self, id: u32, omega: V3, out: &mut Vec<u32>) {
        if !is_cluster(id) {
            let el = &self.elements[id as usize];
            if dot(self.geo.quads[el.piece.surface].n, omega) > 0.0 {
                out.push(id);
            }
            return;
        }
        let cluster = self.clusters.get(id);
        match cluster.bound.side(omega) {
            Some(true) => out.push(id),
            Some(false) => {}
            None => {
                let [a, b] = cluster.children;
                self.intensity_cut(a, omega, out);
                self.intensity_cut(b, omega, out);
            }
        }
    }

    /// The kernel that cluster link `l` applies between its receiving member `i` and its
    /// source member `j` (as [`Hierarchy::for_members`] names them): the irradiance at `i`
    /// per unit of B on `j` and per unit of `j`'s area, the rest of the source dark, as
    /// [`Hierarchy::cluster_link_irradiance`] delivers it (a constant over `i`). For eq. (5)
    /// ([`super::kernel_error`]). An element source's affine transfer is its closed form; a
    /// cluster's is sent from where its light comes from, which depends on its members' B
    /// ([`Emitter::about`], [`Weights`]): here `j`'s alone, expanded about
    /// its own centroid where `i` is in front of it.
    pub(super) fn cluster_link_kernel(&self, l: &ClusterLink, i: u32, j: u32) -> f64 {
        let member = |end: u32, e: u32| {
            if is_cluster(end) {
                let q = &self.geo.quads[e as usize];
                (self.clusters.centres[e as usize], q.n)
            } else {
                let el = &self.elements[e as usize];
                (self.element_centre(e), self.geo.quads[el.piece.surface].n)
            }
        };
        let (x, nx) = member(l.recv, i);
        let v = if is_cluster(l.recv) {
            l.member_v(self.clusters.place(i) - self.clusters.span(l.recv).start)
        } else {
            l.visibility
        };
        let area = self.elements[j as usize].area;
        if is_cluster(l.src) {
            let (y, ny) = member(l.src, j);
            if dot(ny, sub(x, y)) <= 0.0 {
                return 0.0;
            }
            let alone = self.element_emitter(j, [1.0; 3]);
            let about = alone.about().expect("a member of unit B sends light");
            return v * alone.irradiance(about, x, nx)[0] / area;
        }
        // an element sends through its closed form ([`Hierarchy::unit_irradiance`])
        if l.affine {
            let (sc, sr) = self.end(l.src).bound.sphere();
            if leaves_behind(nx, x, (sc, sr)) {
                return 0.0;
            }
            let source = self.elements[j as usize].piece.corners(&self.geo.quads);
            let member_area = self.elements[i as usize].area;
            return v * self.held_form_factor(i, member_area, x, nx, &source, (sc, sr)) / area;
        }
        let centre = self.centre_of(l.src);
        let (_, ny) = member(l.src, j);
        let d = sub(centre, x);
        let (cx, r2) = (dot(nx, d), dot(d, d));
        if cx <= 0.0 || r2 <= 0.0 {
            return 0.0;
        }
        // an element's intensity toward the member, from its centroid
        let r = r2.sqrt();
        let cy = dot(ny, scale(d, -1.0 / r));
        if cy <= 0.0 {
            return 0.0;
        }
        v * cx * cy / (std::f64::consts::PI * r2 * r)
    }

    /// How many members receive through a link into `id`.
    fn member_count(&self, id: u32) -> usize {
        if is_cluster(id) {
            self.clusters.members(id).len()
        } else {
            1
        }
    }

    /// Adds the cluster links' irradiance to their receivers' H: a run of links at a time,
    /// the links of a run in parallel, then their receivers' members, stretches of them in
    /// parallel, each member's sum over the links in their order (so that the sums do not
    /// depend on the threads, and the buffer on the number of links). A run
    /// holds links until their receivers' members reach [`RUN_MEMBERS`] (a link into a
    /// cluster of a thousand triangles fills a thousand slots: runs of a fixed number of
    /// links took 190 MB of buffer in a 35 k-triangle scene).
    pub(super) fn gather_clusters(&mut self) {
        self.hold_unit_irradiance(KERNELS_HELD);
        let mut lights = std::mem::take(&mut self.lights);
        self.relight_into(&mut lights);
        // the H each member gathers, in the clusters' order: a cluster's members are one run
        let mut gathered = vec![[0.0; 3]; self.clusters.order().len()];
        let mut buffer: Vec<Rgb> = Vec::new();
        let mut start = 0;
        while start < self.cluster_links.len() {
            let mut end = start;
            let mut members = 0;
            while end < self.cluster_links.len() && (end == start || members < RUN_MEMBERS) {
                members += self.member_count(self.cluster_links[end].recv);
                end += 1;
            }
            let links = &self.cluster_links[start..end];
            let counts: Vec<usize> = links.iter().map(|l| self.member_count(l.recv)).collect();
            // every slot is written by its link: the buffer grows, but is not cleared
            let total = counts.iter().sum();
            if buffer.len() < total {
                buffer.resize(total, [0.0; 3]);
            }
            let mut slices = Vec::with_capacity(links.len());
            let mut rest = &mut buffer[..total];
            for &c in &counts {
                let (a, b) = rest.split_at_mut(c);
                slices.push(a);
                rest = b;
            }
            let this = &*self;
            slices
                .into_par_iter()
                .zip(links.par_iter())
                .for_each(|(out, l)| this.cluster_link_irradiance(l, &lights, out));
            // each cluster receiver's members in `gathered` and where their H is in `buffer`
            let mut spans = Vec::with_capacity(links.len());
            let mut at = 0;
            for l in start..end {
                let recv = self.cluster_links[l].recv;
                if is_cluster(recv) {
                    let span = self.clusters.span(recv);
                    let n = span.len();
                    spans.push((span, at));
                    at += n;
                } else {
                    add_constant(&mut self.elements[recv as usize], buffer[at]);
                    at += 1;
                }
            }
            // the members in parallel, a stretch of them each, every member's sum over the
            // run's links in their order
            let stretch = gathered.len().div_ceil(MERGE_STRETCHES).max(1);
            gathered
                .par_chunks_mut(stretch)
                .enumerate()
                .for_each(|(i, part)| {
                    let lo = i * stretch;
                    let hi = lo + part.len();
                    for (span, from) in &spans {
                        let (a, b) = (span.start.max(lo), span.end.min(hi));
                        if a < b {
                            let h = &buffer[from + (a - span.start)..][..b - a];
                            for (g, h) in part[a - lo..b - lo].iter_mut().zip(h) {
                                (0..3).for_each(|ch| g[ch] += h[ch]);
                            }
                        }
                    }
                });
            start = end;
        }
        for (&p, h) in self.clusters.order().iter().zip(&gathered) {
            if *h != [0.0; 3] {
                add_constant(&mut self.elements[p as usize], *h);
            }
        }
        self.lights = lights;
    }
}

/// The light that the clusters and patches send in a sweep: each cluster's [`Emitter`] and,
/// side by side for the links that are not affine ([`SpreadSource`]), its [`Weights`] and
/// each patch's normal and B̄ A / π. An [`Emitter`] is 1 KB and an element's B is behind a
/// pointer: read from them at each of the 16 M clusters and patches that a sweep of 81
/// icospheres (10⁵ triangles) opens, the sweep's cluster links took 1.7–2.0 s and the whole
/// solve 28.8 s; 24.8 s with these (the same B to the bit).
#[derive(Default)]
pub(super) struct Lights {
    emitters: Vec<Emitter>,
    weights: Vec<Weights>,
    patches: Vec<(V3, Rgb)>,
}

/// A source of a cluster link that is not affine, as [`SpreadSource::direct`] reads it
/// ([`Hierarchy::source_light`]).
enum SourceLight<'e> {
    /// An element: its normal, and B̄ A / π.
    Element { normal: V3, light: Rgb },
    /// A cluster: its bound (the normal cone), and its members' [`Weights`].
    Cluster {
        bound: &'e Bound,
        weights: &'e Weights,
    },
}

/// What the members j of a part of a source send toward a point x in front of them, as
/// weights affine in x: w_j(x) = A_j B̄_j n_j · (x − y_j), per channel their sum J · x − K,
/// and their moment Σ_j w_j(x) y_j = Q x − q with the channels summed (the [`Emitter`]'s
/// moments of the part). The irradiance at x is Σ_j w_j(x) g(y_j) with
/// g(y) = n_x · (y − x) / (π |y − x|⁴), and about the centroid of the weights,
/// c(x) = (Q x − q) / Σ (J · x − K), its term of first order in y − c vanishes:
///
/// ```text
/// H(x) = (J · x − K) g(c(x)) + O((d / r)²)
/// ```
///
/// Taken as an intensity toward x sent from one point c instead, Σ_j A_j B̄_j n_j · (x − c),
/// each member's cosine is read at c rather than at its own centroid, an error of first
/// order in the source's size over r that is large where a member is seen edge-on: the sides
/// of a box 9 units below a ceiling sent it twice their light, and the box's links 8 %
/// too much (benches/README, "A cluster's light weighted at the receiving point").
#[derive(Debug, Clone, Copy)]
struct Weights {
    normal: [V3; 3],
    offset: Rgb,
    /// Q's rows and q, the channels summed.
    spread: [V3; 3],
    lever: V3,
}

impl Weights {
    /// The weights of a cluster's members, from its [`Emitter`].
    fn of_emitter(e: &Emitter) -> Weights {
        Weights {
            normal: e.normal,
            offset: e.offset,
            spread: [0, 1, 2].map(|i| add(add(e.spread[0][i], e.spread[1][i]), e.spread[2][i])),
            lever: add(add(e.lever[0], e.lever[1]), e.lever[2]),
        }
    }

    /// The weights of one patch with normal `normal`, B̄ A / π `light` and centroid `y`.
    fn of_patch(normal: V3, light: Rgb, y: V3) -> Weights {
        let ab = light.map(|l| l * std::f64::consts::PI);
        let sum: f64 = ab.iter().sum();
        let ny = dot(normal, y);
        Weights {
            normal: ab.map(|w| scale(normal, w)),
            offset: ab.map(|w| w * ny),
            spread: [0, 1, 2].map(|i| scale(normal, sum * y[i])),
            lever: scale(y, sum * ny),
        }
    }

    /// The weights of no member.
    const NONE: Weights = Weights {
        normal: [[0.0; 3]; 3],
        offset: [0.0; 3],
        spread: [[0.0; 3]; 3],
        lever: [0.0; 3],
    };

    /// The weights of this part's members and `other`'s.
    fn plus(&self, other: &Weights) -> Weights {
        Weights {
            normal: [0, 1, 2].map(|c| add(self.normal[c], other.normal[c])),
            offset: [0, 1, 2].map(|c| self.offset[c] + other.offset[c]),
            spread: [0, 1, 2].map(|i| add(self.spread[i], other.spread[i])),
            lever: add(self.lever, other.lever),
        }
    }

    /// Adds the weights at `x` and their moment into `w` and `m`, where the part sends toward
    /// x (its weights summed over the channels are positive).
    fn add_at(&self, x: V3, w: &mut Rgb, m: &mut V3) {
        let (at, moment) = self.at(x);
        if at.iter().sum::<f64>() <= 0.0 {
            return;
        }
        (0..3).for_each(|ch| w[ch] += at[ch]);
        *m = add(*m, moment);
    }

    /// The weights at `x` per channel, J · x − K, and their moment Q x − q.
    fn at(&self, x: V3) -> (Rgb, V3) {
        (
            [0, 1, 2].map(|ch| dot(self.normal[ch], x) - self.offset[ch]),
            [0, 1, 2].map(|i| dot(self.spread[i], x) - self.lever[i]),
        )
    }
}

/// The irradiance at `x` with normal `n` of members within `bound` whose weights at x sum to
/// `w` with the moment `m` ([`Weights`]): w g(c) about their centroid c = m / Σ w, held
/// within the members' box.
///
/// The weights of members whose planes leave x behind them are negative, so where they
/// nearly cancel the rest, m / Σ w may lie anywhere, x itself included, and g(c) has no
/// bound: in the 81 icospheres one link lit a triangle with 0.2 (a thousand times its other
/// links) or 0.02 as its source's B moved that centroid by a little, and the sweeps
/// alternated between the two for 500 sweeps without converging. The members' light comes
/// from within their box, and so does the centre it is sent from.
fn weighted_irradiance(w: Rgb, m: V3, x: V3, n: V3, bound: &Bound) -> Rgb {
    let sum: f64 = w.iter().sum();
    if sum <= 0.0 {
        return [0.0; 3];
    }
    let d = sub(bound.nearest(scale(m, 1.0 / sum)), x);
    let (r2, f) = (dot(d, d), dot(n, d));
    if f <= 0.0 || r2 <= 0.0 {
        return [0.0; 3];
    }
    let g = f / (std::f64::consts::PI * r2 * r2);
    w.map(|w| (w * g).max(0.0))
}

/// The source of a cluster link that is not affine, read at each receiving member
/// ([`Hierarchy::spread_source`]).
struct SpreadSource<'e> {
    light: SourceLight<'e>,
    /// Its centroid (weighted by area).
    centre: V3,
}

impl SpreadSource<'_> {
    /// The unoccluded irradiance at a point `x` with normal `n` where it does not need the
    /// source's parts: an element sends its intensity B̄ A (n_S · ω)₊ / π toward x from its
    /// centroid, a cluster whose members all face the direction of x by its weights at x
    /// ([`Weights`]), one whose members all face away nothing; `None` for a cluster whose
    /// normals straddle the plane normal to that direction (it sends by its parts).
    fn direct(&self, x: V3, n: V3) -> Option<Rgb> {
        let d = sub(self.centre, x);
        let r2 = dot(d, d);
        if r2 <= 0.0 {
            return Some([0.0; 3]);
        }
        let omega = scale(d, -1.0 / r2.sqrt());
        match &self.light {
            SourceLight::Element { normal, light } => {
                let (cs, cx) = (dot(*normal, omega), dot(n, d));
                if cs <= 0.0 || cx <= 0.0 {
                    return Some([0.0; 3]);
                }
                let f = cs * cx / (r2 * r2.sqrt());
                Some(light.map(|l| l * f))
            }
            SourceLight::Cluster { bound, weights } => match bound.side(omega)? {
                false => Some([0.0; 3]),
                true => {
                    let (mut w, mut m) = ([0.0; 3], [0.0; 3]);
                    weights.add_at(x, &mut w, &mut m);
                    Some(weighted_irradiance(w, m, x, n, bound))
                }
            },
        }
    }
}

/// The kernel between a receiving and a sending point that face each other, kept finite by
/// `disc` added to r² (see [`Hierarchy::cluster_visibility`]); `None` where either faces away.
fn facing_kernel(recv: &Sample, send: &Sample, disc: f64) -> Option<f64> {
    let d = sub(send.x, recv.x);
    let (cx, cy) = (dot(recv.normal, d), -dot(send.normal, d));
    if cx <= 0.0 || cy <= 0.0 {
        return None;
    }
    let r2 = dot(d, d);
    Some(cx * cy / (r2 * (r2 + disc)))
}

/// A uniform point of `piece` (a triangle's when `tri`), in its surface's parameters.
fn uniform_in(piece: &Piece, tri: bool, rng: &mut SplitMix) -> (f64, f64) {
    let (mut u, mut v) = (rng.next_f64(), rng.next_f64());
    if tri {
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        piece.at_local(u, v)
    } else {
        (
            piece.s[0] + u * (piece.s[1] - piece.s[0]),
            piece.t[0] + v * (piece.t[1] - piece.t[0]),
        )
    }
}

/// Whether the plane through `x` with normal `n` leaves the whole sphere behind it: a member
/// there receives nothing from a source inside the sphere.
fn leaves_behind(n: V3, x: V3, (centre, radius): (V3, f64)) -> bool {
    dot(n, sub(centre, x)) < -radius
}

/// Adds the irradiance `h` (the coefficient h₀ of a constant) to an element's H, on its
/// exposed part.
fn add_constant(el: &mut super::tree::Element, h: Rgb) {
    const MAX_KK: usize = crate::three_d::transfer::MAX_K * crate::three_d::transfer::MAX_K;
    match &el.exposure {
        Exposure::Open => (0..3).for_each(|ch| el.h[0][ch] += h[ch]),
        Exposure::Covered => {}
        // the moments ∫ χ φ H of a constant over the exposed part
        Exposure::Partial(p) => {
            let kk = el.h.len();
            let mut constant = [[0.0; 3]; MAX_KK];
            let mut moments = [[0.0; 3]; MAX_KK];
            constant[0] = h;
            Partial::apply(&p.gram, &constant[..kk], &mut moments[..kk]);
            for (a, m) in el.h.iter_mut().zip(&moments[..kk]) {
                (0..3).for_each(|ch| a[ch] += m[ch]);
            }
        }
    }
}

#[cfg(test)]
mod tests {

    use super::*;
    use crate::three_d::geometry::sym_of;
    use crate::three_d::rules::Rules;

    /// A member of a test source: area, B, centroid, normal and corners.
    type Member = (f64, Rgb, V3, V3, [V3; 4]);

    /// The members of a source: 8 × 8 squares 1/8 a side on a plane through the origin
    /// facing +z, or folded into a roof along the y axis when `fold` > 0 (each face tilted
    /// by `fold`), with B growing across them.
    fn members(fold: f64) -> Vec<Member> {
        let mut out = Vec::new();
        for i in 0..8 {
            for j in 0..8 {
                let (x, y) = (i as f64 / 8.0 - 0.4375, j as f64 / 8.0 - 0.4375);
                let tilt = if x < 0.0 { -fold } else { fold };
                let n = [tilt.sin(), 0.0, tilt.cos()];
                let at = |u: f64, v: f64| [u, v, -u.abs() * fold.tan()];
                let h = 1.0 / 16.0;
                let c = [
                    at(x - h, y - h),
                    at(x + h, y - h),
                    at(x + h, y + h),
                    at(x - h, y + h),
                ];
                let area = norm(crate::three_d::geometry::cross(
                    sub(c[1], c[0]),
                    sub(c[3], c[0]),
                ));
                let b = 1.0 + x + 0.5 * y;
                out.push((area, [b, 2.0 * b, 0.5], at(x, y), n, c));
            }
        }
        out
    }

    /// The members' irradiance at `x` (normal `n`), in closed form (each member uniform).
    fn exact(members: &[Member], x: V3, n: V3) -> Rgb {
        let mut h = [0.0; 3];
        for (_, b, _, _, c) in members {
            let f = crate::three_d::transfer::point_polygon(x, n, c);
            (0..3).for_each(|ch| h[ch] += b[ch] * f);
        }
        h
    }

    fn worst_error(fold: f64, distance: f64) -> f64 {
        let members = members(fold);
        let sum = members
            .iter()
            .map(|(a, b, y, n, c)| Emitter::member(*a, *b, *y, *n, covariance(c, false)))
            .fold(Emitter::default(), |s, e| s.add(&e));
        let about = sum.about().unwrap();
        let mut worst: f64 = 0.0;
        for (dx, dy) in [(0.0, 0.0), (0.3, 0.1), (-0.5, 0.4), (0.2, -0.6)] {
            let x = [dx * distance, dy * distance, distance];
            let n = normalize([-dx, -dy, -1.0]);
            let (exact, affine) = (exact(&members, x, n), sum.irradiance(about, x, n));
            for c in 0..3 {
                worst = worst.max((affine[c] - exact[c]).abs() / exact[c]);
            }
        }
        worst
    }

    /// What the transfer leaves out is third order in the source's size over the distance,
    /// against the closed-form irradiance of its members, for a flat source and for one
    /// folded into a roof, with B varying over it: within the oracle's factor
    /// (d / (d + dist))³ (d = √2, the source's diameter), and each doubling of the distance
    /// divides the error by about eight. The three channels' B differ in shape (one is
    /// uniform), so the point the expansion is about is none of their own centroids.
    /// Without the second-order term it was second order: 8.3 % at distance 2.
    #[test]
    fn the_affine_source_is_third_order_in_its_size() {
        let d = 2f64.sqrt();
        for fold in [0.0, 0.4] {
            let distances = [2.0, 4.0, 8.0, 16.0];
            let errors: Vec<f64> = distances.iter().map(|&r| worst_error(fold, r)).collect();
            eprintln!("fold {fold}: {errors:?}");
            for (e, r) in errors.iter().zip(distances) {
                assert!(*e < (d / (d + r)).powi(3), "fold {fold}: {errors:?}");
            }
            for w in errors.windows(2) {
                let rate = (w[0] / w[1]).log2();
                assert!(rate > 2.7, "fold {fold}: {errors:?}");
            }
        }
    }

    /// The covariance of a triangle and of a parallelogram about their centroids, against
    /// the mean of (y − c)(y − c)ᵀ over an n × n grid of points (the triangle's staircase
    /// edge makes that mean wrong by O(1/n) of the largest entry).
    #[test]
    fn covariances_are_those_of_a_uniform_point() {
        let c = [
            [0.0, 0.0, 0.0],
            [2.0, 0.5, 0.0],
            [2.5, 1.5, 1.0],
            [0.5, 1.0, 1.0],
        ];
        for triangle in [false, true] {
            let n = 400;
            let (mut sum, mut count, mut mean) = ([0.0; 6], 0.0, [0.0; 3]);
            let mut points = Vec::new();
            for i in 0..n {
                for j in 0..n {
                    let (u, v) = ((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
                    let p = if triangle {
                        if u + v > 1.0 {
                            continue;
                        }
                        add(
                            c[0],
                            add(scale(sub(c[1], c[0]), u), scale(sub(c[2], c[0]), v)),
                        )
                    } else {
                        add(
                            c[0],
                            add(scale(sub(c[1], c[0]), u), scale(sub(c[3], c[0]), v)),
                        )
                    };
                    points.push(p);
                    mean = add(mean, p);
                    count += 1.0;
                }
            }
            mean = scale(mean, 1.0 / count);
            for p in points {
                sum = sym_axpy(1.0 / count, &sym_of(sub(p, mean)), &sum);
            }
            let cov = covariance(&c, triangle);
            let largest = cov.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            for k in 0..6 {
                let tolerance = if triangle { 2.0 / n as f64 } else { 1e-4 };
                assert!(
                    (cov[k] - sum[k]).abs() < tolerance * largest,
                    "{triangle}: {cov:?} {sum:?}"
                );
            }
        }
    }

    use crate::three_d::geometry::normalize;

    /// A 0.2 × 0.2 tile at z = 0 facing up, under a 2 × 2 light at `height` facing down (a
    /// mesh of 128 triangles, one cluster tree), with a board at z = 2 over x ∈ [0, 1] when
    /// `board`; elements no smaller than 1, so the tile is at its finest level.
    fn tile_under_light(height: f64, board: bool) -> Vec<crate::scene::Quad> {
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        for j in 0..=8 {
            for i in 0..=8 {
                positions.push([i as f64 / 4.0 - 1.0, j as f64 / 4.0 - 1.0, height]);
            }
        }
        for j in 0..8 {
            for i in 0..8 {
                let (a, b) = (j * 9 + i, j * 9 + i + 1);
                let (c, d) = (b + 9, a + 9);
                // facing −z, down to the tile
                triangles.push([a, d, c]);
                triangles.push([a, c, b]);
            }
        }
        let mut surfaces = vec![
            serde_json::json!({"name": "tile", "corners": [[-0.1, -0.1, 0], [0.1, -0.1, 0], [0.1, 0.1, 0], [-0.1, 0.1, 0]],
             "reflectance": 0.5}),
            serde_json::json!({"name": "light", "mesh": {"positions": positions, "triangles": triangles},
             "reflectance": 0.0, "emission": 1.0}),
        ];
        if board {
            surfaces.push(serde_json::json!({"name": "board",
                "corners": [[0, -1, 2], [0, 1, 2], [1, 1, 2], [1, -1, 2]], "reflectance": 0.5}));
        }
        super::super::tests::patches(
            &serde_json::json!({"scene": {"kind": "3d", "surfaces": surfaces},
            "solver": {"method": "hierarchical"}}),
        )
    }

    /// The hierarchy of `quads` at order 1 with elements no smaller than 0.25, linked and
    /// solved.
    fn solved<'a>(
        geo: &'a crate::three_d::projection::Geometry,
        quads: &'a [crate::scene::Quad],
    ) -> Hierarchy<'a> {
        let sizing = super::super::sizing::Sizing::new(&geo.quads, Some(0.25), None);
        let mut h = Hierarchy::new(geo, quads, 1, sizing, 1e-3, &Rules::default());
        h.link_all(&crate::progress::Silent).unwrap();
        while h.sweep() > 1e-9 {}
        h
    }

    /// Each cluster's [`Emitter`], its subtrees filled in parallel or not, is the sum of its
    /// children's, to the bit: the clusters are in the preorder that
    /// [`Hierarchy::subtree_emitters`] splits them by.
    #[test]
    fn each_clusters_emitter_is_its_childrens_sum() {
        let quads = super::super::tests::corner_under_a_meshed_ceiling();
        let geo = crate::three_d::projection::Geometry::new(&quads);
        let h = solved(&geo, &quads);
        let n = h.clusters.nodes.len();
        assert!(n > 8, "{n} clusters");
        let fill = |parallel: usize| {
            let mut out = vec![Emitter::default(); n];
            h.subtree_emitters(crate::three_d::cluster::CLUSTER, &mut out, parallel);
            out
        };
        let bits = |e: &Emitter| format!("{e:?}");
        let (each, none) = (fill(1), fill(usize::MAX));
        for (i, node) in h.clusters.nodes.iter().enumerate() {
            let [a, b] = node.children;
            let sum = h.emitter(a, &none).add(&h.emitter(b, &none));
            assert_eq!(bits(&none[i]), bits(&sum), "cluster {i}");
            assert_eq!(bits(&each[i]), bits(&sum), "cluster {i}, in parallel");
        }
        assert!(none.iter().any(|e| e.light > 0.0), "some light");
    }

    /// A cluster link's kernel ([`Hierarchy::cluster_link_kernel`], what eq. (5) samples),
    /// applied to its source's B, is the transfer the link makes, for a source of one member
    /// (a cluster's expands its parts about where their light comes from, which depends on
    /// their B): exactly (to rounding) for a source seen as its intensity, to single
    /// precision where the link holds its kernel. The corner of a room under a meshed
    /// ceiling of the solver's tests, after one solve, has links of both kinds.
    #[test]
    fn a_cluster_links_kernel_applied_to_its_members_b_is_its_transfer() {
        let quads = super::super::tests::corner_under_a_meshed_ceiling();
        let geo = crate::three_d::projection::Geometry::new(&quads);
        let h = solved(&geo, &quads);
        let lights = h.lights();
        let mut checked = [0, 0, 0];
        for l in &h.cluster_links {
            let mut sources = Vec::new();
            h.for_members(l.src, |e, area, _, _| sources.push((e, area)));
            if sources.len() > 1 {
                continue;
            }
            let mut receivers = Vec::new();
            h.for_members(l.recv, |e, area, _, _| receivers.push((e, area)));
            let mut out = vec![[0.0; 3]; receivers.len()];
            h.cluster_link_irradiance(l, &lights, &mut out);
            // an element's affine transfer is held as its kernel at each member in single
            // precision, as the element links' blocks are: the closed form itself, to that
            let tol = if l.factors.is_some() {
                let mut expanded = vec![[0.0; 3]; receivers.len()];
                let bare = ClusterLink {
                    factors: None,
                    ..l.clone()
                };
                h.cluster_link_irradiance(&bare, &lights, &mut expanded);
                for (got, want) in out.iter().zip(&expanded) {
                    for ch in 0..3 {
                        let limit = f64::from(f32::EPSILON) * want[ch].abs();
                        assert!((got[ch] - want[ch]).abs() <= limit, "{got:?} {want:?}");
                    }
                }
                checked[2] += 1;
                f64::from(f32::EPSILON)
            } else {
                1e-12
            };
            for (&(i, ai), got) in receivers.iter().zip(&out) {
                let h_i: f64 = sources
                    .iter()
                    .map(|&(j, aj)| {
                        let b = h.elements[j as usize].b[0][1] / aj.sqrt();
                        h.cluster_link_kernel(l, i, j) * aj * b
                    })
                    .sum();
                let want = h_i * ai.sqrt();
                assert!(
                    (got[1] - want).abs() <= tol * want.abs().max(1e-12),
                    "{got:?} against {want} (affine: {})",
                    l.affine
                );
            }
            checked[usize::from(l.affine)] += 1;
        }
        eprintln!("{checked:?} links checked (intensity, affine, of them held as kernels)");
        assert!(checked.iter().all(|&n| n > 0), "{checked:?}");
    }

    /// Under a cap, the kernels held stay within it, and the links deliver
    /// the same light, held or expanded (to the single precision of what is held).
    #[test]
    fn the_kernels_held_stay_within_their_cap() {
        let quads = super::super::tests::corner_under_a_meshed_ceiling();
        let geo = crate::three_d::projection::Geometry::new(&quads);
        let mut h = solved(&geo, &quads);
        let delivered = |h: &Hierarchy| {
            let lights = h.lights();
            h.cluster_links
                .iter()
                .map(|l| {
                    let mut out = vec![[0.0; 3]; h.member_count(l.recv)];
                    h.cluster_link_irradiance(l, &lights, &mut out);
                    out
                })
                .collect::<Vec<_>>()
        };
        let held = |h: &Hierarchy| -> usize {
            h.cluster_links
                .iter()
                .filter_map(|l| l.factors.as_ref())
                .map(|f| f.len())
                .sum()
        };
        let all_held = delivered(&h);
        let all = held(&h);
        assert!(all > 0);
        h.cluster_links.iter_mut().for_each(|l| l.factors = None);
        h.hold_unit_irradiance(all / 2);
        let total = held(&h);
        assert!(total > 0 && total <= all / 2, "{total} of {all}");
        for (got, want) in delivered(&h)
            .iter()
            .flatten()
            .zip(all_held.iter().flatten())
        {
            for ch in 0..3 {
                let limit = f64::from(f32::EPSILON) * want[ch].abs();
                assert!((got[ch] - want[ch]).abs() <= limit, "{got:?} {want:?}");
            }
        }
    }

    /// The light of a cluster that is not linear toward its receiver
    /// ([`SpreadSource::direct`], [`Hierarchy::parts_at`]): a unit box whose top sends ten times what its sides
    /// do, at a point seen from its top and two sides, against the members' closed forms.
    /// By the members' weights at the point, about their centroid, the error is 1.25 %,
    /// 0.74 %, 0.21 % and 0.056 % at 2, 4, 8 and 16 units from its centre: second order
    /// once the distance is a few sizes. As an intensity sent from its centroid weighted by
    /// area it was 26 % and 15 % at 2 and 4 units (first order); from the centre of that
    /// intensity 8.5 %, 1.5 %, 0.12 % and 0.09 % (the sides' cosines read at that point, not
    /// at their own planes).
    #[test]
    fn a_box_lit_unevenly_sends_its_light_from_where_it_is() {
        let top = [
            [0.0, 1.0, 0.0],
            [0.0, 1.0, 1.0],
            [1.0, 1.0, 1.0],
            [1.0, 1.0, 0.0],
        ];
        let mut sides = Vec::new();
        let mut triangles = Vec::new();
        // the four sides, counter-clockwise seen from outside
        for (a, b) in [
            ([0.0, 0.0], [1.0, 0.0]),
            ([1.0, 0.0], [1.0, 1.0]),
            ([1.0, 1.0], [0.0, 1.0]),
            ([0.0, 1.0], [0.0, 0.0]),
        ] {
            let i = sides.len();
            sides.extend([
                [a[0], 0.0, a[1]],
                [b[0], 0.0, b[1]],
                [b[0], 1.0, b[1]],
                [a[0], 1.0, a[1]],
            ]);
            triangles.extend([[i, i + 1, i + 2], [i, i + 2, i + 3]]);
        }
        let quads = super::super::tests::patches(&serde_json::json!({"scene": {"kind": "3d",
            "surfaces": [
                {"name": "top", "mesh": {"positions": top, "triangles": [[0, 1, 2], [0, 2, 3]]},
                 "reflectance": 0.0, "emission": 1.0},
                {"name": "sides", "mesh": {"positions": sides, "triangles": triangles},
                 "reflectance": 0.0, "emission": 0.1}]},
            "solver": {"method": "hierarchical"}}));
        let geo = crate::three_d::projection::Geometry::new(&quads);
        let h = solved(&geo, &quads);
        let lights = h.lights();
        let root = (0..h.clusters.nodes.len() as u32)
            .map(|i| crate::three_d::cluster::CLUSTER | i)
            .find(|&c| h.clusters.span(c).len() == 10)
            .expect("a cluster of the whole box");
        let centre = [0.5, 0.5, 0.5];
        let omega = {
            let d = [0.3, 1.0, 0.2];
            scale(d, 1.0 / norm(d))
        };
        let mut last = f64::INFINITY;
        for distance in [2.0, 4.0, 8.0, 16.0] {
            let x = add(centre, scale(omega, distance));
            let n = scale(omega, -1.0);
            let got = h
                .spread_source(root, &lights)
                .direct(x, n)
                .unwrap_or_else(|| {
                    let mut cut = Vec::new();
                    h.intensity_cut(root, omega, &mut cut);
                    h.parts_at(&cut, &lights, x, n, &h.clusters.get(root).bound)
                })[1];
            let want: f64 = (0..10)
                .map(|p| {
                    let el = &h.elements[p];
                    let q = &geo.quads[el.piece.surface];
                    if dot(q.n, sub(x, q.at(0.0, 0.0))) <= 0.0 {
                        return 0.0;
                    }
                    let b = el.sent0()[1] / el.area.sqrt();
                    b * point_polygon(x, n, &el.piece.corners(&geo.quads))
                })
                .sum();
            let error = (got / want - 1.0).abs();
            eprintln!("{distance}: {got} against {want}: {:.3} %", 100.0 * error);
            // the error of first order is gone: within 2 % at 2 units, where the box's
            // half-diagonal is 0.87 (from its centroid weighted by area 26 %, from the centre
            // of its intensity 8.5 %); then second order: each doubling of the distance at
            // least 3.5 times smaller
            if distance == 2.0 {
                assert!(error < 0.02, "at 2: {:.3} %", 100.0 * error);
            } else if distance >= 8.0 {
                assert!(error <= last / 3.5, "at {distance}: {error} after {last}");
            }
            last = error;
        }
    }

    /// A held kernel reads a member's form factor to an element at the member's points
    /// ([`Hierarchy::member_points`]): a triangle of unit legs under a unit square of floor,
    /// `d` above it and off to one side, against the form factor's mean over the triangle by
    /// quadrature. From d = 2 on the error falls by at least 6× per doubling of d (third
    /// order, 8× in the limit; 0.086, 0.010, 0.0008 % at d = 2, 4, 8), where the centroid's
    /// falls by 4× at most (second order; 3.6, 1.2, 0.34 %); and the parallelogram's four
    /// points likewise.
    #[test]
    fn a_members_held_kernel_is_its_mean_form_factor_to_third_order() {
        let errors = |tri: bool| -> Vec<(f64, f64)> {
            [1.0, 2.0, 4.0, 8.0]
                .iter()
                .map(|&d| {
                    let member = if tri {
                        serde_json::json!({"name": "member", "mesh": {"positions": [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
                            "triangles": [[0, 1, 2]]}, "reflectance": 0.5})
                    } else {
                        serde_json::json!({"name": "member", "corners": [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]],
                            "reflectance": 0.5})
                    };
                    let doc = serde_json::json!({"scene": {"kind": "3d", "surfaces": [member,
                        {"name": "square", "corners": [[0.5, 0, d], [0.5, 1, d], [1.5, 1, d], [1.5, 0, d]],
                         "reflectance": 0.5, "emission": 1.0}]},
                        "solver": {"method": "hierarchical"}});
                    let quads = super::super::tests::patches(&doc);
                    let geo = crate::three_d::projection::Geometry::new(&quads);
                    let sizing = super::super::sizing::Sizing::new(&geo.quads, Some(1.0), None);
                    let h = Hierarchy::new(&geo, &quads, 1, sizing, 1e-3, &Rules::default());
                    let (q, source) = (&geo.quads[0], h.elements[1].piece.corners(&geo.quads));
                    let form_factor = |x: V3| point_polygon(x, q.n, &source);
                    // the mean by the midpoint rule on 128² cells (the triangle's folded)
                    let n = 128;
                    let mut exact = 0.0;
                    for i in 0..n {
                        for j in 0..n {
                            let (mut u, mut v) = ((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
                            if tri && u + v > 1.0 {
                                (u, v) = (1.0 - u, 1.0 - v);
                            }
                            exact += form_factor(q.at(u, v));
                        }
                    }
                    exact /= (n * n) as f64;
                    let points = h.member_points(0);
                    let held = points.iter().map(|&x| form_factor(x)).sum::<f64>() / points.len() as f64;
                    let centroid = form_factor(h.element_centre(0));
                    ((held / exact - 1.0).abs(), (centroid / exact - 1.0).abs())
                })
                .collect()
        };
        for tri in [true, false] {
            let e = errors(tri);
            // third order once the distance is above the member's size
            for w in e[1..].windows(2) {
                assert!(w[0].0 > 6.0 * w[1].0, "triangle {tri}: {e:?}");
            }
            // and well below the centroid's error even where it is not
            assert!(e[0].0 < e[0].1 / 4.0, "triangle {tri}: {e:?}");
        }
    }

    /// A cluster's cut toward ω ([`Hierarchy::intensity_cut`]) holds the members that face ω,
    /// and their weights ([`Hierarchy::part_weights`]) at a point x two units along ω add up
    /// to Σ_j A_j B̄_j n_j · (x − y_j) over them, and their moment to Σ_j w_j(x) y_j, to
    /// rounding, for every cluster of a closed sphere (the normal cones of its upper clusters
    /// hold every direction, those of its lower ones few) lit unevenly from a plate beside
    /// it, toward 200 directions each.
    /// Members whose weights nearly cancel put their centroid m / Σ w anywhere, here a
    /// millimetre above the receiving point x; their light still comes from their box, a
    /// unit square 1 above x, so the irradiance is at most Σ w / (π · 1²), however m falls.
    #[test]
    fn a_clusters_light_is_sent_from_within_its_box() {
        let square = [
            [-0.5, 1.0, -0.5],
            [0.5, 1.0, -0.5],
            [0.5, 1.0, 0.5],
            [-0.5, 1.0, 0.5],
        ];
        let bound = Bound::of_polygon(&square, [0.0, -1.0, 0.0]);
        let w = [1e-3; 3];
        let sum: f64 = w.iter().sum();
        let m = scale([0.0, 1e-3, 0.0], sum);
        let h = weighted_irradiance(w, m, [0.0; 3], [0.0, 1.0, 0.0], &bound);
        for c in 0..3 {
            assert!(h[c] > 0.0, "{h:?}");
            assert!(h[c] <= w[c] / std::f64::consts::PI * (1.0 + 1e-12), "{h:?}");
        }
    }

    #[test]
    fn a_clusters_cut_weighs_as_the_members_that_face_its_direction() {
        let (rings, segments) = (8, 16);
        let mut positions = vec![[0.0, 0.0, 1.0]];
        for i in 1..rings {
            let theta = std::f64::consts::PI * i as f64 / rings as f64;
            for j in 0..segments {
                let phi = 2.0 * std::f64::consts::PI * j as f64 / segments as f64;
                positions.push([
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                ]);
            }
        }
        positions.push([0.0, 0.0, -1.0]);
        let last = positions.len() - 1;
        let at = |i: usize, j: usize| 1 + (i - 1) * segments + j % segments;
        let mut triangles = Vec::new();
        for j in 0..segments {
            // counter-clockwise seen from outside
            triangles.push([0, at(1, j), at(1, j + 1)]);
            triangles.push([last, at(rings - 1, j + 1), at(rings - 1, j)]);
            for i in 1..rings - 1 {
                triangles.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                triangles.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        let quads = super::super::tests::patches(&serde_json::json!({"scene": {"kind": "3d",
            "surfaces": [
                {"name": "ball", "mesh": {"positions": positions, "triangles": triangles},
                 "reflectance": [0.8, 0.5, 0.2]},
                {"name": "plate", "corners": [[3, -1, -1], [3, -1, 1], [3, 1, 1], [3, 1, -1]],
                 "reflectance": 0.0, "emission": 1.0}]},
            "solver": {"method": "hierarchical"}}));
        let geo = crate::three_d::projection::Geometry::new(&quads);
        let h = solved(&geo, &quads);
        let lights = h.lights();
        let mut rng = SplitMix(11);
        let mut opened = 0;
        for index in 0..h.clusters.nodes.len() {
            let id = crate::three_d::cluster::CLUSTER | index as u32;
            let mut members = Vec::new();
            h.for_members(id, |e, area, x, n| members.push((e, area, x, n)));
            for _ in 0..200 {
                let z = 2.0 * rng.next_f64() - 1.0;
                let phi = 2.0 * std::f64::consts::PI * rng.next_f64();
                let r = (1.0 - z * z).sqrt();
                let omega = [r * phi.cos(), r * phi.sin(), z];
                let at = scale(omega, 2.0);
                let (mut want, mut moment) = ([0.0; 3], [0.0; 3]);
                for &(e, area, y, n) in &members {
                    if dot(n, omega) <= 0.0 {
                        continue;
                    }
                    // A B̄ = b₀ √A
                    let b = h.elements[e as usize].sent0();
                    let w = b.map(|b| b * area.sqrt() * dot(n, sub(at, y)));
                    (0..3).for_each(|ch| want[ch] += w[ch]);
                    moment = add(moment, scale(y, w.iter().sum()));
                }
                let mut cut = Vec::new();
                h.intensity_cut(id, omega, &mut cut);
                let (mut over, mut got) = ([0.0; 3], [0.0; 3]);
                for &k in &cut {
                    let (w, m) = h.part_weights(k, &lights).at(at);
                    (0..3).for_each(|ch| over[ch] += w[ch]);
                    got = add(got, m);
                }
                // the largest weight a member may have at x, three units from any of them
                let bright = members
                    .iter()
                    .map(|&(e, a, _, _)| 3.0 * a.sqrt() * h.elements[e as usize].sent0()[0])
                    .sum::<f64>();
                for ch in 0..3 {
                    assert!(
                        (over[ch] - want[ch]).abs() <= 1e-12 * bright,
                        "cluster {index}'s cut toward {omega:?}: {over:?} against {want:?}"
                    );
                }
                assert!(
                    norm(sub(got, moment)) <= 1e-11 * bright,
                    "cluster {index}'s moment toward {omega:?}: {got:?} against {moment:?}"
                );
                opened += usize::from(h.clusters.nodes[index].bound.side(omega).is_none());
            }
        }
        // the test reaches subtrees that are opened, and ones that are not
        let all = 200 * h.clusters.nodes.len();
        assert!(opened > 0 && opened < all, "{opened} of {all} opened");
        assert!(h.elements.iter().any(|e| e.sent0()[0] > 0.0));
    }

    /// Ends closer than [`Rules::separation`] times their size are split whatever their
    /// estimate (there the ends are not points): the tile and the light 2 above it (diameter 2.83) are
    /// split at any tolerance, and the light's halves (diameter 2.24 at distance 2) as well,
    /// its quarters (1.41) are linked; 4 above, the light is linked whole.
    #[test]
    fn ends_closer_than_their_size_are_split_whatever_their_estimate() {
        for (height, unsplit) in [(2.0, 2), (4.0, 0)] {
            let quads = tile_under_light(height, false);
            let geo = crate::three_d::projection::Geometry::new(&quads);
            let sizing = super::super::sizing::Sizing::new(&geo.quads, Some(1.0), None);
            let mut h = Hierarchy::new(&geo, &quads, 1, sizing, 1e-3, &Rules::default());
            h.threshold = f64::INFINITY;
            h.cluster_state = h.measure_clusters();
            let (tile, mut light) = (0u32, h.clusters.roots[1]);
            assert!(is_cluster(light) && !h.splittable(tile));
            for depth in 0..=unsplit {
                let (er, es) = (h.end(tile), h.end(light));
                let (dist, size) = (
                    er.bound.distance(&es.bound),
                    er.bound.diameter().max(es.bound.diameter()),
                );
                let verdict = h.judge_cluster(tile, light).0;
                if depth < unsplit {
                    assert!(dist < h.rules.separation * size, "{height} {depth}");
                    assert!(matches!(verdict, ClusterVerdict::Source), "{verdict:?}");
                    light = h.clusters.get(light).children[0];
                } else {
                    assert!(dist >= h.rules.separation * size, "{height} {depth}");
                    assert!(matches!(verdict, ClusterVerdict::Link(_)), "{verdict:?}");
                }
            }
        }
    }

    /// A small tile at its finest level under a meshed light, half of which a board hides:
    /// the light's cluster is split while what taking it as a point misses (d / (d + dist))
    /// is more than the sampling error of the visible fraction, and no further: a part
    /// partly visible and smaller than that is linked even over the tolerance, since
    /// splitting it would only add links whose sampling errors add up to the same. With
    /// σ = 1 (no credit for a partly visible pair) every such part would be split.
    #[test]
    fn a_partly_visible_source_is_split_only_while_its_size_is_most_of_the_error() {
        let quads = tile_under_light(4.0, true);
        let geo = crate::three_d::projection::Geometry::new(&quads);
        let sizing = super::super::sizing::Sizing::new(&geo.quads, Some(1.0), None);
        let mut h = Hierarchy::new(&geo, &quads, 1, sizing, 1e-4, &Rules::default());
        h.cluster_state = h.measure_clusters();
        let tile = 0u32;
        assert!(!h.splittable(tile));
        let light = *h.clusters.roots.iter().find(|&&r| is_cluster(r)).unwrap();
        let (mut split, mut linked, mut over) = (0, 0, 0);
        let mut open = vec![light];
        while let Some(s) = open.pop() {
            if !is_cluster(s) {
                continue;
            }
            let (er, es) = (h.end(tile), h.end(s));
            let (dr, ds) = (er.bound.diameter(), es.bound.diameter());
            let dist = er.bound.distance(&es.bound);
            let geometric = dr.max(ds) / (dr.max(ds) + dist);
            let at_one = h.cluster_error(&h.state(tile), &h.state(s), dist, 1.0);
            match h.judge_cluster(tile, s).0 {
                ClusterVerdict::Source => {
                    split += 1;
                    open.extend(h.clusters.get(s).children);
                }
                // partly visible to the rays that judged it (the link's own V is from fresh
                // rays, and may be 1; a pair they found hidden has σ = its sampled part alone)
                ClusterVerdict::Link(g) if g.sampled > 0.0 && g.smooth != g.sampled => {
                    linked += 1;
                    assert!((g.smooth - geometric - g.sampled).abs() < 1e-12);
                    assert!(ds > dr && at_one > h.threshold, "σ = 1 would split it");
                    let err = h.cluster_error(&h.state(tile), &h.state(s), dist, g.smooth);
                    if err > h.threshold {
                        over += 1;
                        assert!(geometric <= g.sampled, "{geometric} {}", g.sampled);
                    }
                }
                _ => {}
            }
        }
        assert!(
            split >= 2 && over >= 1,
            "{split} splits, {linked} partly visible links, {over} over the tolerance"
        );
    }

    /// A receiving cluster of a board and a small plate 2 cm under it, lit from above: the
    /// board hides the plate from the light. Its points drawn by area over the members
    /// (the plate is 1/400 of the area) would all land on the board in 96 % of the draws of
    /// 16, and the link would take V = 1 for the plate too; drawn in strata, half of them
    /// land on the plate, and every seed finds the pair partly visible, the plate's share of
    /// the light stopped: its share of the area (1/401) times its kernel over the board's
    /// mean one (the plate lies under the light's centre, where the kernel is highest: within
    /// a factor of two of the board's mean, whose corners see the light at 2 m from 0.7 m
    /// aside).
    #[test]
    fn a_member_its_cluster_hides_is_drawn_and_seen_hidden() {
        let square = |y: f64, h: f64| {
            serde_json::json!({"positions": [[-h, y, -h], [-h, y, h], [h, y, h], [h, y, -h]],
                "triangles": [[0, 1, 2], [0, 2, 3]]})
        };
        let doc = serde_json::json!({"scene": {"kind": "3d", "surfaces": [
            {"name": "board", "mesh": square(1.0, 0.5), "reflectance": 0.5},
            {"name": "plate", "mesh": square(0.98, 0.025), "reflectance": 0.5},
            {"name": "light", "corners": [[-0.25, 3, -0.25], [0.25, 3, -0.25], [0.25, 3, 0.25], [-0.25, 3, 0.25]],
             "reflectance": 0.0, "emission": 1.0}]},
            "solver": {"method": "hierarchical"}});
        let plate = 0.05f64.powi(2) / (1.0 + 0.05f64.powi(2));
        with_two_meshes(&doc, |h, both| {
            let light = 4;
            for seed in 0..20 {
                let (v, valid, _) = h.cluster_visibility(both, light, seed);
                assert_eq!(valid, CLUSTER_RAYS, "every pair faces");
                let stopped = (1.0 - v) / plate;
                assert!((1.0..2.0).contains(&stopped), "seed {seed}: V = {v}");
            }
        });
    }

    /// A link gives every receiving member V times its unoccluded transfer, so V must be the
    /// share of the light that is not stopped, not of the rays. A receiving cluster of two
    /// small plates (0.1 m across), one 1.1 m from a small light and one 3 m from it behind
    /// a board: half of the rays reach the far plate and are stopped, but it carries a sixth
    /// of the light. V is the near plate's share of the two plates' transfers from the
    /// light, integrated exactly ([`crate::three_d::transfer::block`]), to the sampling
    /// error of the kernel over plates a tenth of their distance across (1 %); counted by
    /// rays it was ½.
    #[test]
    fn a_cluster_links_visible_fraction_is_the_share_of_the_light() {
        let doc = two_plates_and_a_board();
        with_two_meshes(&doc, |h, plates| {
            let light = 5usize;
            assert!(h.geo.quads[light].n[1] < 0.0 && !h.geo.quads[light].tri);
            // ∫∫ K over each plate's two triangles and the light
            let transfer = |members: std::ops::Range<usize>| -> f64 {
                members
                    .map(|p| {
                        let mut block = vec![0.0; 1];
                        crate::three_d::transfer::block(
                            &h.geo.quads,
                            crate::three_d::geometry::Piece::whole(p),
                            crate::three_d::geometry::Piece::whole(light),
                            crate::three_d::transfer::Integrand::Galerkin { k: 1 },
                            h.accuracy,
                            &mut block,
                        );
                        block[0] * (h.geo.quads[p].area * h.geo.quads[light].area).sqrt()
                    })
                    .sum()
            };
            let (near, far) = (transfer(0..2), transfer(2..4));
            let want = near / (near + far);
            assert!(want > 0.8, "{want}");
            for seed in 0..20 {
                let (v, valid, _) = h.cluster_visibility(plates, light as u32, seed);
                assert_eq!(valid, CLUSTER_RAYS, "every pair faces");
                assert!(
                    (v - want).abs() < 0.01 * want,
                    "seed {seed}: V = {v}, want {want}"
                );
            }
        });
    }

    /// A link gives each receiving member of a partly visible pair its own V: the plates of
    /// the test above, one in the light's view and one behind the board (every segment from
    /// it to the light crosses the board), get 1 and 0, where the link's one V gave both
    /// 0.8 or more.
    #[test]
    fn each_member_of_a_partly_visible_receiver_gets_its_own_visible_fraction() {
        let doc = two_plates_and_a_board();
        with_two_meshes(&doc, |h, plates| {
            let light = 5u32;
            for seed in 0..20 {
                let (v, rays) = h.member_visibility(plates, light, seed);
                assert_eq!(rays, 4, "one ray a member");
                for (k, &p) in h.clusters.members(plates).iter().enumerate() {
                    let want = if p < 2 { 255 } else { 0 };
                    assert_eq!(v[k], want, "seed {seed}: member {p}");
                }
            }
        });
    }

    /// A member's one ray is drawn in proportion to the light it carries: a plate 1 m under
    /// a strip 4 m long that starts above it, with a board halfway hiding the strip's first
    /// metre, which sends most of the plate's light. By area three quarters of the strip is
    /// in view; by the light, F(visible part) / F(strip) at the plate's centre (closed form).
    /// Over 400 links the members' mean V is within a quarter of the gap between the two of
    /// the light's share (uniform pairs would land on the area's).
    #[test]
    fn a_members_ray_is_drawn_by_the_light_it_carries() {
        let plate = |x: f64| {
            let h = 0.05;
            serde_json::json!({"positions": [[x - h, 0, -h], [x - h, 0, h], [x + h, 0, h], [x + h, 0, -h]],
                "triangles": [[0, 1, 2], [0, 2, 3]]})
        };
        let doc = serde_json::json!({"scene": {"kind": "3d", "surfaces": [
            {"name": "plate", "mesh": plate(0.0), "reflectance": 0.5},
            {"name": "other", "mesh": plate(-3.0), "reflectance": 0.5},
            {"name": "strip", "corners": [[0, 1, -0.5], [4, 1, -0.5], [4, 1, 0.5], [0, 1, 0.5]],
             "reflectance": 0.0, "emission": 1.0},
            {"name": "board", "corners": [[-0.5, 0.5, -1], [0.5, 0.5, -1], [0.5, 0.5, 1], [-0.5, 0.5, 1]],
             "reflectance": 0.5}]},
            "solver": {"method": "hierarchical"}});
        let rect = |x0: f64| {
            [
                [x0, 1.0, -0.5],
                [4.0, 1.0, -0.5],
                [4.0, 1.0, 0.5],
                [x0, 1.0, 0.5],
            ]
        };
        let up = [0.0, 1.0, 0.0];
        let by_light =
            point_polygon([0.0; 3], up, &rect(1.0)) / point_polygon([0.0; 3], up, &rect(0.0));
        let by_area = 0.75;
        assert!(by_light < 0.4, "{by_light}");
        with_two_meshes(&doc, |h, plates| {
            let strip = 4u32;
            let (mut sum, mut n) = (0.0, 0);
            for seed in 0..400 {
                let (v, _) = h.member_visibility(plates, strip, seed);
                for (k, &p) in h.clusters.members(plates).iter().enumerate() {
                    if p < 2 {
                        sum += f64::from(v[k]) / 255.0;
                        n += 1;
                    }
                }
            }
            let mean = sum / n as f64;
            assert!(
                (mean - by_light).abs() < 0.25 * (by_area - by_light),
                "mean V {mean}: by the light {by_light}, by area {by_area}"
            );
        });
    }

    /// A plate 0.1 m across, 0.25 m under a strip 8 m long and 1 m wide that starts above
    /// it, with a board halfway that hides all of the strip but its first quarter metre
    /// (3 % of its area). Returns the document (the strip a parallelogram, or with `meshed` a mesh of
    /// 128 triangles) and that share, the light-weighted V of the plate.
    fn plate_under_a_long_strip(meshed: bool) -> (serde_json::Value, f64) {
        let plate = |x: f64| {
            let h = 0.05;
            serde_json::json!({"positions": [[x - h, 0, -h], [x - h, 0, h], [x + h, 0, h], [x + h, 0, -h]],
                "triangles": [[0, 1, 2], [0, 2, 3]]})
        };
        let (height, length) = (0.25, 8.0);
        let strip = if meshed {
            let steps = 64;
            let mut positions = Vec::new();
            for i in 0..=steps {
                let x = length * i as f64 / steps as f64;
                positions.push(serde_json::json!([x, height, -0.5]));
                positions.push(serde_json::json!([x, height, 0.5]));
            }
            let triangles: Vec<_> = (0..steps)
                .flat_map(|i| {
                    let (a, b, c, d) = (2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3);
                    [serde_json::json!([a, c, b]), serde_json::json!([b, c, d])]
                })
                .collect();
            serde_json::json!({"name": "strip", "mesh": {"positions": positions, "triangles": triangles},
                "reflectance": 0.0, "emission": 1.0})
        } else {
            serde_json::json!({"name": "strip",
                "corners": [[0, height, -0.5], [length, height, -0.5], [length, height, 0.5], [0, height, 0.5]],
                "reflectance": 0.0, "emission": 1.0})
        };
        let doc = serde_json::json!({"scene": {"kind": "3d", "surfaces": [
            {"name": "plate", "mesh": plate(0.0), "reflectance": 0.5},
            {"name": "other", "mesh": plate(-3.0), "reflectance": 0.5},
            strip,
            {"name": "board", "corners": [[0.125, 0.125, -2], [0.125, 0.125, 2], [6, 0.125, 2], [6, 0.125, -2]],
             "reflectance": 0.5}]},
            "solver": {"method": "hierarchical"}});
        // from a point x0 of the plate, the board's edge (0.125 along, at half the height)
        // leaves the strip in view up to 0.25 − x0
        let rect = |x0: f64, x1: f64| {
            [
                [x0, height, -0.5],
                [x1, height, -0.5],
                [x1, height, 0.5],
                [x0, height, 0.5],
            ]
        };
        let down = [0.0, 1.0, 0.0];
        // the plate's light and its light in view, by the midpoint rule over it
        let (mut seen, mut all) = (0.0, 0.0);
        let n = 16;
        for i in 0..n {
            for j in 0..n {
                let at = |k: usize| -0.05 + 0.1 * (k as f64 + 0.5) / n as f64;
                let p = [at(i), 0.0, at(j)];
                let shifted = |c: [V3; 4]| c.map(|v| sub(v, p));
                let edge = 0.25 - p[0];
                seen += point_polygon([0.0; 3], down, &shifted(rect(0.0, edge)));
                all += point_polygon([0.0; 3], down, &shifted(rect(0.0, length)));
            }
        }
        (doc, seen / all)
    }

    /// The mean V over `links` draws of the plate's two triangles' rays
    /// ([`plate_under_a_long_strip`]).
    fn plate_mean_v(h: &Hierarchy, plates: u32, strip: u32, links: u64) -> f64 {
        let (mut sum, mut n) = (0.0, 0);
        for seed in 0..links {
            let (v, _) = h.member_visibility(plates, strip, seed);
            for (k, &p) in h.clusters.members(plates).iter().enumerate() {
                if p < 2 {
                    sum += f64::from(v[k]) / 255.0;
                    n += 1;
                }
            }
        }
        sum / n as f64
    }

    /// A member's candidates draw their source points toward it: under a long strip of
    /// which it sees only the near end (73 % of its light on 3 % of the area), its mean V
    /// over 1 000 links must be within 0.05 of the closed form, the share of the light in
    /// view (the gallery's 5 % of a cell; the standard error of 2 000 rays is 0.01). Drawn
    /// by the light alone, it was 0.19 from the parallelogram: a candidate in the near end
    /// turned up in a quarter of the members' eight. Drawn toward the member, 0.727 from the
    /// parallelogram and 0.697 from the mesh, whose parts' estimates are the cruder (its
    /// cluster tree's spheres); 0.733 from either with 64 candidates.
    #[test]
    fn a_members_candidates_are_drawn_toward_it() {
        let (doc, share) = plate_under_a_long_strip(false);
        assert!(share > 0.7 && share < 0.75, "{share}");
        with_two_meshes(&doc, |h, plates| {
            let mean = plate_mean_v(h, plates, 4, 1000);
            assert!(
                (mean - share).abs() < 0.05,
                "mean V {mean}, the light's share {share}"
            );
        });
        // the strip a mesh: the source's cluster tree is gone down first, drawn by its light
        let (doc, share) = plate_under_a_long_strip(true);
        let quads = super::super::tests::patches(&doc);
        let geo = crate::three_d::projection::Geometry::new(&quads);
        let sizing = super::super::sizing::Sizing::new(&geo.quads, Some(1.0), None);
        let mut h = Hierarchy::new(&geo, &quads, 1, sizing, 1e-3, &Rules::default());
        h.weigh_light();
        let cluster_of = |wanted: std::ops::Range<u32>| {
            (0..h.clusters.nodes.len() as u32)
                .map(|i| i | crate::three_d::cluster::CLUSTER)
                .find(|&c| {
                    let mut m = h.clusters.members(c).to_vec();
                    m.sort_unstable();
                    m == wanted.clone().collect::<Vec<_>>()
                })
                .expect("a cluster of just these patches")
        };
        let (plates, strip) = (cluster_of(0..4), cluster_of(4..132));
        assert!(h.clusters.light(strip) > 0.0);
        let mean = plate_mean_v(&h, plates, strip, 1000);
        assert!(
            (mean - share).abs() < 0.05,
            "mean V {mean}, the light's share {share}"
        );
    }

    /// Two small plates (0.1 m across, meshes of two triangles), one 1.1 m below a small
    /// light and one 3 m from it behind a board.
    fn two_plates_and_a_board() -> serde_json::Value {
        let plate = |x: f64, y: f64| {
            let h = 0.05;
            serde_json::json!({"positions": [[x - h, y, -h], [x - h, y, h], [x + h, y, h], [x + h, y, -h]],
                "triangles": [[0, 1, 2], [0, 2, 3]]})
        };
        serde_json::json!({"scene": {"kind": "3d", "surfaces": [
            {"name": "near", "mesh": plate(0.5, 2.0), "reflectance": 0.5},
            {"name": "far", "mesh": plate(-0.5, 0.0), "reflectance": 0.5},
            {"name": "board", "corners": [[-1.5, 1, -1], [-1.5, 1, 1], [0, 1, 1], [0, 1, -1]],
             "reflectance": 0.5},
            {"name": "light", "corners": [[-0.05, 3, -0.05], [0.05, 3, -0.05], [0.05, 3, 0.05], [-0.05, 3, 0.05]],
             "reflectance": 0.0, "emission": 1.0}]},
            "solver": {"method": "hierarchical"}})
    }

    /// Runs `check` on the hierarchy of a document whose two meshes (of two triangles each)
    /// make one cluster of four members, with that cluster.
    fn with_two_meshes(doc: &serde_json::Value, check: impl FnOnce(&Hierarchy, u32)) {
        with_cluster_of(doc, 4, |h, both| check(h, both));
    }

    /// Runs `check` on the unlinked hierarchy of a document (order 1, elements down to 1)
    /// with its top cluster of `members` members.
    fn with_cluster_of<T>(
        doc: &serde_json::Value,
        members: usize,
        check: impl FnOnce(&mut Hierarchy, u32) -> T,
    ) -> T {
        let quads = super::super::tests::patches(doc);
        let geo = crate::three_d::projection::Geometry::new(&quads);
        let sizing = super::super::sizing::Sizing::new(&geo.quads, Some(1.0), None);
        let mut h = Hierarchy::new(&geo, &quads, 1, sizing, 1e-3, &Rules::default());
        let cluster = *h
            .clusters
            .starts
            .iter()
            .find(|&&r| is_cluster(r) && h.clusters.members(r).len() == members)
            .expect("a cluster of that many members");
        check(&mut h, cluster)
    }

    /// The worst relative error, over the faces of an octahedron of unit diameter resting on
    /// a floor, of the light that a 1 × 1 square of floor of unit B, `distance` from the
    /// octahedron's centre, sends each face through one cluster link, against the face's form
    /// factor to the square (by quadrature); and how many faces it lights.
    fn octahedron_beside_a_square(distance: f64) -> (f64, usize) {
        let v = |x: f64, y: f64, z: f64| serde_json::json!([x, y + 0.5, z]);
        let (h, near, far) = (0.5, distance - 0.5, distance + 0.5);
        let doc = serde_json::json!({"scene": {"kind": "3d", "surfaces": [
            {"name": "floor",
             "corners": [[near, 0, -0.5], [near, 0, 0.5], [far, 0, 0.5], [far, 0, -0.5]],
             "reflectance": 0.0, "emission": 1.0},
            {"name": "octahedron", "mesh": {
                "positions": [v(h, 0.0, 0.0), v(-h, 0.0, 0.0), v(0.0, h, 0.0), v(0.0, -h, 0.0),
                              v(0.0, 0.0, h), v(0.0, 0.0, -h)],
                "triangles": [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4],
                              [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]},
             "reflectance": 0.5}]},
            "solver": {"method": "hierarchical"}});
        with_cluster_of(&doc, 8, light_each_face)
    }

    /// A wholly visible link into cluster `recv` from the root element of `h`'s first surface,
    /// whose B is made a unit constant.
    fn from_unit_first_surface(h: &mut Hierarchy, recv: u32, affine: bool) -> ClusterLink {
        let root = &mut h.elements[0];
        assert_eq!(root.piece.surface, 0);
        root.b.iter_mut().for_each(|b| *b = [0.0; 3]);
        root.b[0] = [root.area.sqrt(); 3];
        ClusterLink {
            recv,
            src: 0,
            visibility: 1.0,
            affine,
            smooth: 1.0,
            sampled: 0.0,
            members: None,
            factors: None,
            cut: None,
        }
    }

    /// The worst relative error of the light that the unit B of `h`'s first surface, a
    /// square, sends each member of the cluster `octahedron` through one cluster link, against
    /// the member's form factor to the square; and how many members it lights.
    fn light_each_face(h: &mut Hierarchy, octahedron: u32) -> (f64, usize) {
        let link = from_unit_first_surface(h, octahedron, false);
        let mut out = vec![[0.0; 3]; 8];
        h.cluster_link_irradiance(&link, &h.lights(), &mut out);
        let square = &h.geo.quads[0];
        let (mut worst, mut lit) = (0.0f64, 0);
        for (k, got) in out.iter().enumerate() {
            let face = h.clusters.order()[h.clusters.span(octahedron).start + k] as usize;
            let [a, b, c, _] = h.elements[face].piece.corners(&h.geo.quads);
            let n = h.geo.quads[face].n;
            // the face's mean irradiance: 48 × 48 points on the square, 210 on the face
            let (m, f) = (48, 20);
            let mut sum = 0.0;
            for i in 0..m {
                for j in 0..m {
                    let (s, t) = ((i as f64 + 0.5) / m as f64, (j as f64 + 0.5) / m as f64);
                    let y = square.at(s, t);
                    for p in 0..f {
                        for q in 0..f - p {
                            let u = (p as f64 + 1.0 / 3.0) / f as f64;
                            let w = (q as f64 + 1.0 / 3.0) / f as f64;
                            let x = add(add(scale(a, 1.0 - u - w), scale(b, u)), scale(c, w));
                            let d = sub(y, x);
                            let r2 = dot(d, d);
                            let (cx, cy) = (dot(n, d), -dot(square.n, d));
                            if cx > 0.0 && cy > 0.0 {
                                sum += cx * cy / (std::f64::consts::PI * r2 * r2);
                            }
                        }
                    }
                }
            }
            let want = sum / (m * m) as f64 / (f * (f + 1) / 2) as f64 * square.area;
            let got = got[1] / h.elements[face].area.sqrt();
            if want == 0.0 {
                assert_eq!(got, 0.0, "face {face}");
                continue;
            }
            lit += 1;
            worst = worst.max((got / want - 1.0).abs());
        }
        (worst, lit)
    }

    /// An element's affine link lights each receiving member with the member's form factor
    /// to the element at its points ([`Hierarchy::held_form_factor`]): a 2 × 2 panel of unit
    /// B at height 1, over two small triangles below its corner, against that form factor by
    /// quadrature (400 × 400 points).
    /// The element's second-order expansion, which the link took before, is off by more than
    /// 1 % here (its remainder is of fourth order in the panel's size over its distance).
    #[test]
    fn an_elements_affine_link_lights_each_member_with_its_form_factor() {
        let doc = serde_json::json!({"scene": {"kind": "3d", "surfaces": [
            {"name": "panel", "corners": [[-1, 1, -1], [1, 1, -1], [1, 1, 1], [-1, 1, 1]],
             "reflectance": 0.0, "emission": 1.0},
            {"name": "chips", "mesh": {
                "positions": [[0.9, 0, 0.9], [0.9, 0, 1.0], [1.0, 0, 1.0], [1.0, 0, 0.9]],
                "triangles": [[0, 1, 2], [0, 2, 3]]},
             "reflectance": 0.5}]},
            "solver": {"method": "hierarchical"}});
        with_cluster_of(&doc, 2, |h, chips| {
            let link = from_unit_first_surface(h, chips, true);
            let factors = h.unit_irradiance(&link);
            let square = &h.geo.quads[0];
            let expansion = h.element_emitter(0, [1.0; 3]);
            let centre = h.element_centre(0);
            let mut k = 0;
            h.for_members(chips, |e, area, x, n| {
                let form_factor = |x: V3| {
                    let m = 400;
                    let mut sum = 0.0;
                    for i in 0..m {
                        for j in 0..m {
                            let (s, t) = ((i as f64 + 0.5) / m as f64, (j as f64 + 0.5) / m as f64);
                            let d = sub(square.at(s, t), x);
                            let r2 = dot(d, d);
                            sum += dot(n, d) * -dot(square.n, d) / (std::f64::consts::PI * r2 * r2);
                        }
                    }
                    sum / (m * m) as f64 * square.area
                };
                // the chips are close enough to the panel for their points
                let points = h.member_points(e);
                let want =
                    points.iter().map(|&y| form_factor(y)).sum::<f64>() / points.len() as f64;
                let got = f64::from(factors[k]) / area.sqrt();
                assert!(
                    (got / want - 1.0).abs() < 1e-5,
                    "member {k}: {got} against {want}"
                );
                let expanded = expansion.expansion::<1>(centre, x, n)[0];
                assert!(
                    (expanded / want - 1.0).abs() > 0.01,
                    "the expansion: {expanded} against {want}"
                );
                eprintln!("member {k}: closed form {got}, expansion {expanded}, quadrature {want}");
                k += 1;
            });
            assert_eq!(k, 2);
        });
    }

    /// A planar source's light reaches each member of a cluster beside it at the member's own
    /// angle, so that the link's error falls with the ends' size over their distance: a square
    /// of floor beside an octahedron resting on the floor lights the four faces toward it with
    /// errors that more than halve each time the distance doubles (10.3 %, 3.4 %, 1.3 % at
    /// 2.5, 5 and 10: the bottom faces see the square at cosines of 0–0.15 at the floor,
    /// whose variation over them is of the order of their mean, so that the rate lies between
    /// the first order and the second). Taken toward the octahedron's centre, the bottom faces
    /// got the cosine at its height, half again their mean, at any distance: 30 %, 40 %, 46 %;
    /// the bottom triangles of a ball resting on a floor, which the floor's elements lit so at
    /// 3–4 times their light, came out 5–7 % bright.
    #[test]
    fn a_planar_source_lights_each_member_at_its_own_angle() {
        let at = [2.5, 5.0, 10.0].map(octahedron_beside_a_square);
        assert!(at.iter().all(|&(_, lit)| lit == 4), "{at:?}");
        assert!(at[1].0 < at[0].0 / 2.0 && at[2].0 < at[1].0 / 2.0, "{at:?}");
    }
}
