//! Eq. (5) of the slides, ∫∫(K − K̂)² / ∫∫K², sampled at random pairs of points, for scenes
//! where integrating it is out of reach: with triangles, the pairs of patches are too many for
//! a quadrature over each (10¹⁰ at 10⁵ triangles), and the cluster links hold no block whose
//! squares Parseval could sum; on many parallelograms, whose s² quadratures take longer than
//! the solve ([`INTEGRATED_PAIRS`]).
//!
//! The links tile the pairs of points that exchange light, so both integrals are sums over
//! the links of integrals over their ends R × S. Each of M samples picks a link l with
//! probability p_l, a point x uniform by area on R and y on S, and adds
//! A_R A_S / p_l times (K − K̂)² and K² to the two sums: K(x, y) = V cos θx cos θy / π r², V by
//! one ray, and K̂(x, y) the link's own kernel:
//!
//! - an element link's block T: Σ_ab T_ab ψ_a(x) ψ_b(y), ψ the elements' orthonormal
//!   functions (tensor Legendre on a parallelogram's element, Dubiner on a triangle's);
//! - a cluster link's transfer per unit of B on y's member, a constant over x's member
//!   ([`Hierarchy::cluster_link_kernel`]).
//!
//! Near surfaces make K² a long-tailed function, and a link's (K − K̂)² is large where its
//! kernel is: half of p_l goes by A_R A_S K̄_l² (K̄_l the link's mean kernel, from the
//! block's first entry or the ends' centres), so that each link is sampled about as often as
//! it weighs in ∫∫K², and half by A_R A_S alone, so that no link weighs more than twice what
//! uniform sampling would give it. As in the integrated eq. (5), links between document
//! surfaces that touch are left out (∫∫K² diverges where two surfaces meet), a mesh with
//! itself among them when its triangles share edges; pairs that no link holds (hidden from
//! each other, or facing away) have K̂ = 0 and K = 0 up to what the rays missed. The estimate is a ratio of
//! two sample means; its standard error (the delta method: the root of
//! Σ (n_i − R d_i)² / (M (M − 1)) over the mean of d) goes with it into the result.

use super::clustered::ClusterLink;
use super::Hierarchy;
use crate::math::basis::legendre;
use crate::three_d::cluster::is_cluster;
use crate::three_d::geometry::{box_of, norm, quad_quad, sub, Piece, V3};
use crate::three_d::transfer;
use crate::three_d::visibility::{self, pair_seed, SplitMix};
use rayon::prelude::*;
use std::collections::BTreeSet;

/// The point pairs eq. (5) is sampled at.
pub(super) const PAIRS: usize = 1 << 16;

/// The most pairs of document surfaces over which eq. (5) is integrated rather than sampled.
///
/// Integrating costs about 50 µs a pair (a 4 × 4 grid of cells on each, every pair of cells
/// by quadrature): 33 ms for the Cornell box's 16 surfaces, 0.19 s for a room of 52 and
/// 3.0 s for one of 252, longer than its refinement. Sampling [`PAIRS`] point pairs takes
/// 8–15 ms on all three, with a standard error of 3–20 % of the value that the result
/// reports. Up to 32 surfaces the exact value costs about as much as the sample.
pub(super) const INTEGRATED_PAIRS: usize = 32 * 32;

/// Whether eq. (5) is sampled rather than integrated over every pair of surfaces: always
/// with triangles, and beyond [`INTEGRATED_PAIRS`].
pub(super) fn sampled_on(with_triangles: bool, surfaces: usize) -> bool {
    with_triangles || surfaces * surfaces > INTEGRATED_PAIRS
}

/// Eq. (5) sampled.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Sampled {
    pub(super) value: f64,
    pub(super) standard_error: f64,
    /// Pairs of document surfaces (by index, i ≤ j) that touch, left out.
    pub(super) left_out: Vec<(usize, usize)>,
}

/// A point of an end of a link: the member it lies on (the element itself, or the root
/// element of a cluster's patch), its (s, t) on its patch, and the point in space.
#[derive(Debug, Clone, Copy)]
struct At {
    member: u32,
    st: (f64, f64),
    x: V3,
}

/// A link of either kind.
#[derive(Debug, Clone, Copy)]
enum Any<'a> {
    Element(&'a super::refine::Link, &'a [f32]),
    Cluster(&'a ClusterLink),
}

impl Hierarchy<'_> {
    /// Eq. (5) over `pairs` point pairs; `groups` are the document's surfaces as patches.
    pub(super) fn sampled_kernel_error(&self, groups: &[Vec<u32>], pairs: usize) -> Sampled {
        let mut group_of = vec![0; self.geo.quads.len()];
        for (g, members) in groups.iter().enumerate() {
            members.iter().for_each(|&p| group_of[p as usize] = g);
        }
        let left_out = self.touching_surfaces(&group_of);
        let touch: rustc_hash::FxHashSet<(usize, usize)> = left_out.iter().copied().collect();
        let link = |i: usize| {
            if i < self.links.len() {
                Any::Element(&self.links.ends()[i], self.links.block(i))
            } else {
                Any::Cluster(&self.cluster_links[i - self.links.len()])
            }
        };
        let count = self.links.len() + self.cluster_links.len();
        // the group of a link's end
        let group = |end: u32| {
            let patch = if is_cluster(end) {
                self.clusters.members(end)[0] as usize
            } else {
                self.elements[end as usize].piece.surface
            };
            group_of[patch]
        };
        // A_R A_S and A_R A_S K̄² of a link, 0 for those left out; worked out twice (once for
        // their sums, in order so that they round alike on every run, once for the
        // probabilities) rather than held: a million links' pairs were 16 MB at the peak
        let weight = |i: usize| {
            let (r, s) = match link(i) {
                Any::Element(l, _) => (l.recv, l.src),
                Any::Cluster(l) => (l.recv, l.src),
            };
            let (gr, gs) = (group(r), group(s));
            if touch.contains(&(gr.min(gs), gr.max(gs))) {
                return (0.0, 0.0);
            }
            let area = self.end_area(r) * self.end_area(s);
            (area, area * self.mean_kernel(link(i)).powi(2))
        };
        let (area_sum, kernel_sum) = (0..count)
            .map(weight)
            .fold((0.0, 0.0), |(a, k), w| (a + w.0, k + w.1));
        let nothing = Sampled {
            value: 0.0,
            standard_error: 0.0,
            left_out: left_out.clone(),
        };
        if area_sum <= 0.0 {
            return nothing;
        }
        let probability = |w: (f64, f64)| {
            let by_kernel = if kernel_sum > 0.0 {
                w.1 / kernel_sum
            } else {
                w.0 / area_sum
            };
            0.5 * (w.0 / area_sum + by_kernel)
        };
        let mut cumulative: Vec<f64> = (0..count)
            .into_par_iter()
            .map(|i| probability(weight(i)))
            .collect();
        let mut acc = 0.0;
        for c in cumulative.iter_mut() {
            acc += *c;
            *c = acc;
        }
        let samples: Vec<(f64, f64)> = (0..pairs)
            .into_par_iter()
            .map(|i| {
                let mut rng = SplitMix(pair_seed(0x0e95, i as u64));
                let u = rng.next_f64() * acc;
                let pick = cumulative.partition_point(|&c| c <= u).min(count - 1);
                let w = weight(pick);
                let p = probability(w);
                if p <= 0.0 {
                    return (0.0, 0.0);
                }
                let l = link(pick);
                let (r, s) = match l {
                    Any::Element(l, _) => (l.recv, l.src),
                    Any::Cluster(l) => (l.recv, l.src),
                };
                let a = self.point_of(r, &mut rng);
                let b = self.point_of(s, &mut rng);
                let k = self.kernel(&a, &b);
                let approx = match l {
                    Any::Element(l, block) => self.block_kernel(l, block, &a, &b),
                    Any::Cluster(l) => self.cluster_link_kernel(l, a.member, b.member),
                };
                let scale = w.0 / p;
                (scale * (k - approx).powi(2), scale * k * k)
            })
            .collect();
        let m = pairs as f64;
        let (num, den) = samples
            .iter()
            .fold((0.0, 0.0), |(n, d), s| (n + s.0, d + s.1));
        if den <= 0.0 {
            return nothing;
        }
        let r = num / den;
        let spread: f64 = samples.iter().map(|(n, d)| (n - r * d).powi(2)).sum();
        Sampled {
            value: r,
            standard_error: (spread / (m * (m - 1.0))).sqrt() / (den / m),
            left_out,
        }
    }

    /// The area of a link's end.
    pub(super) fn end_area(&self, end: u32) -> f64 {
        if is_cluster(end) {
            self.clusters.get(end).area
        } else {
            self.elements[end as usize].area
        }
    }

    /// K̄, the mean kernel over a link's ends: T₀₀ / √(A_R A_S) for an element link (ψ₀ is
    /// 1 / √A), the point-to-point kernel between the ends' centres for a cluster link.
    fn mean_kernel(&self, l: Any) -> f64 {
        match l {
            Any::Element(l, block) => {
                let (r, s) = (
                    &self.elements[l.recv as usize],
                    &self.elements[l.src as usize],
                );
                f64::from(block[0].abs()) / (r.area * s.area).sqrt()
            }
            Any::Cluster(l) => {
                let d = norm(sub(self.centre_of(l.recv), self.centre_of(l.src)));
                if d > 0.0 {
                    l.visibility / (std::f64::consts::PI * d * d)
                } else {
                    0.0
                }
            }
        }
    }

    /// A point uniform by area on a link's end.
    fn point_of(&self, end: u32, rng: &mut SplitMix) -> At {
        let (u, v) = (rng.next_f64(), rng.next_f64());
        let (member, piece) = if is_cluster(end) {
            let member = self.clusters.pick(end, rng.next_f64());
            (member as u32, Piece::whole(member))
        } else {
            (end, self.elements[end as usize].piece)
        };
        let q = &self.geo.quads[piece.surface];
        let (s, t) = visibility::at(q, &piece, u, v);
        At {
            member,
            st: (s, t),
            x: q.at(s, t),
        }
    }

    /// K(x, y) with its visibility, by one ray.
    fn kernel(&self, a: &At, b: &At) -> f64 {
        let (pa, pb) = (
            self.elements[a.member as usize].piece.surface,
            self.elements[b.member as usize].piece.surface,
        );
        let k = transfer::kernel(a.x, self.geo.quads[pa].n, b.x, self.geo.quads[pb].n);
        // (NaN when the two points coincide, 0 / 0)
        if k.is_nan() || k <= 0.0 || self.geo.bvh.occluded(a.x, b.x, [pa, pb]) {
            return 0.0;
        }
        k
    }

    /// An element link's kernel at (x, y): Σ_ab T_ab ψ_a(x) ψ_b(y).
    fn block_kernel(&self, l: &super::refine::Link, block: &[f32], a: &At, b: &At) -> f64 {
        let kk = self.k * self.k;
        let (mut psi_a, mut psi_b) = ([0.0; 16], [0.0; 16]);
        self.functions(l.recv, a.st, &mut psi_a[..kk]);
        self.functions(l.src, b.st, &mut psi_b[..kk]);
        block
            .chunks_exact(kk)
            .zip(&psi_a[..kk])
            .map(|(row, fa)| {
                fa * row
                    .iter()
                    .zip(&psi_b[..kk])
                    .map(|(&t, f)| f64::from(t) * f)
                    .sum::<f64>()
            })
            .sum()
    }

    /// The orthonormal functions ψ of element `e` at (s, t) of its patch (k² of them, a
    /// triangle's beyond its (m + 1)(m + 2)/2 zero).
    fn functions(&self, e: u32, (s, t): (f64, f64), out: &mut [f64]) {
        let el = &self.elements[e as usize];
        let f = 1.0 / el.area.sqrt();
        out.fill(0.0);
        if self.geo.quads[el.piece.surface].tri {
            let (u, v) = el.piece.local(s, t);
            let n = crate::math::triangle::dimension(self.k - 1);
            self.tri_basis.eval(u, v, &mut out[..n]);
        } else {
            let k = self.k;
            let (mut ps, mut pt) = ([0.0; 4], [0.0; 4]);
            let p = el.piece;
            legendre((s - p.s[0]) / (p.s[1] - p.s[0]), &mut ps[..k]);
            legendre((t - p.t[0]) / (p.t[1] - p.t[0]), &mut pt[..k]);
            for q in 0..k {
                for p in 0..k {
                    out[q * k + p] = ps[p] * pt[q];
                }
            }
        }
        out.iter_mut().for_each(|x| *x *= f);
    }

    /// Pairs of document surfaces (i ≤ j, by index) whose patches meet, from box queries in a
    /// hierarchy over every patch.
    fn touching_surfaces(&self, group_of: &[usize]) -> Vec<(usize, usize)> {
        let quads = &self.geo.quads;
        let largest = quads.iter().map(|q| q.diameter()).fold(0.0, f64::max);
        let found: Vec<Vec<(usize, usize)>> = (0..quads.len())
            .into_par_iter()
            .map(|i| {
                let a = &quads[i];
                let ca = a.outline();
                let (lo, hi) = box_of(ca);
                let pad = 1e-9 * largest;
                let (lo, hi) = (lo.map(|v| v - pad), hi.map(|v| v + pad));
                let mut out = Vec::new();
                self.geo.bvh.any_in_scene_box(lo, hi, |j| {
                    if j > i {
                        let b = &quads[j];
                        let tol = 1e-9 * a.diameter().max(b.diameter());
                        if quad_quad(&ca, a.n, &b.outline(), b.n) <= tol {
                            let (g, h) = (group_of[i], group_of[j]);
                            out.push((g.min(h), g.max(h)));
                        }
                    }
                    false
                });
                out
            })
            .collect();
        let set: BTreeSet<(usize, usize)> = found.into_iter().flatten().collect();
        set.into_iter().collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::progress::Silent;
    use crate::scene::{Quad, SceneKind};
    use crate::three_d::hierarchy::sizing::Sizing;
    use crate::three_d::hierarchy::surface_groups;
    use crate::three_d::projection::{kernel_squares, Geometry};
    use crate::three_d::rules::Rules;
    use serde_json::json;

    /// A square light 1 above a square floor and a wall beside them, nothing between any
    /// two and no two touching: every square as one parallelogram, or as two triangles.
    fn squares(triangles: bool) -> serde_json::Value {
        let squares = [
            (
                "light",
                [
                    [0.0, 1.0, 0.0],
                    [1.0, 1.0, 0.0],
                    [1.0, 1.0, 1.0],
                    [0.0, 1.0, 1.0],
                ],
                0.0,
                1.0,
            ),
            (
                "floor",
                [
                    [0.0, 0.0, 0.0],
                    [0.0, 0.0, 1.0],
                    [1.0, 0.0, 1.0],
                    [1.0, 0.0, 0.0],
                ],
                0.6,
                0.0,
            ),
            (
                "wall",
                [
                    [1.5, 0.1, 0.0],
                    [1.5, 0.1, 1.0],
                    [1.5, 0.9, 1.0],
                    [1.5, 0.9, 0.0],
                ],
                0.5,
                0.0,
            ),
        ];
        let mut surfaces = Vec::new();
        for (name, c, rho, e) in squares {
            if triangles {
                for (half, tri) in [[c[0], c[1], c[2]], [c[0], c[2], c[3]]].iter().enumerate() {
                    surfaces.push(json!({"name": format!("{name}-{half}"), "triangle": tri,
                        "reflectance": rho, "emission": e}));
                }
            } else {
                surfaces.push(json!({"name": name, "corners": c, "reflectance": rho,
                    "emission": e}));
            }
        }
        json!({"scene": {"kind": "3d", "surfaces": surfaces},
               "solver": {"method": "hierarchical"}})
    }

    fn patches(doc: &serde_json::Value) -> Vec<Quad> {
        let job = crate::scene::parse_value(doc, &crate::scene::Limits::default()).unwrap();
        match job.scene.kind {
            SceneKind::ThreeD(scene) => scene.patches,
            _ => unreachable!(),
        }
    }

    /// The links of the scene after one solve and one re-refinement, and Σ‖T‖² over them.
    fn linked<'g>(geo: &'g Geometry, quads: &'g [Quad]) -> (Hierarchy<'g>, f64) {
        let sizing = Sizing::new(&geo.quads, Some(0.05), None);
        let mut h = Hierarchy::new(geo, quads, 1, sizing, 1e-3, &Rules::default());
        h.link_all(&Silent).unwrap();
        while h.sweep() > 1e-6 {}
        h.rerefine(&Silent).unwrap();
        let kept = h
            .links
            .coefficients()
            .iter()
            .map(|&v| f64::from(v).powi(2))
            .sum();
        (h, kept)
    }

    fn agree(sampled: &Sampled, exact: f64) {
        eprintln!(
            "sampled {:.5} ± {:.5}, integrated {exact:.5}",
            sampled.value, sampled.standard_error
        );
        assert!(exact > 1e-3, "{exact}: a test of nothing");
        assert!(
            sampled.standard_error < 0.1 * exact,
            "{sampled:?}: too few pairs to tell"
        );
        assert!(
            (sampled.value - exact).abs() <= 4.0 * sampled.standard_error,
            "{sampled:?} against {exact}"
        );
    }

    #[test]
    fn eq_5_is_integrated_over_a_few_parallelograms_and_sampled_over_many_or_triangles() {
        // the Cornell box's 16 surfaces are integrated, a room of 52 is sampled
        assert!(!sampled_on(false, 16) && !sampled_on(false, 32));
        assert!(sampled_on(false, 33) && sampled_on(false, 52));
        assert!(sampled_on(true, 1));
    }

    /// On parallelograms, where eq. (5) is also integrated (∫∫K² by quadrature over every
    /// pair of surfaces, Σ‖T‖² over the links by Parseval), the sampled value agrees with it
    /// within four of its standard errors.
    #[test]
    fn sampled_eq_5_agrees_with_the_integrated_one_on_parallelograms() {
        let quads = patches(&squares(false));
        let geo = Geometry::new(&quads);
        let (h, kept) = linked(&geo, &quads);
        let total: f64 = kernel_squares(&geo, 8, 6, |_, _| false, &Silent)
            .unwrap()
            .iter()
            .sum();
        let sampled = h.sampled_kernel_error(&surface_groups(&quads), PAIRS);
        assert!(sampled.left_out.is_empty(), "{:?}", sampled.left_out);
        agree(&sampled, (total - kept) / total);
    }

    /// The same on the squares as triangles: ∫∫K² by a degree-8 rule on sixteen parts of
    /// every triangle, over the pairs that do not touch (the two halves of a square share
    /// an edge: they are left out, and face nothing of each other anyway).
    #[test]
    fn sampled_eq_5_agrees_with_the_integrated_one_on_triangles() {
        let quads = patches(&squares(true));
        let geo = Geometry::new(&quads);
        let (h, kept) = linked(&geo, &quads);
        let rule = crate::math::triangle::TriangleRule::for_degree(8);
        let parts = |q: &crate::three_d::geometry::Parallelogram| {
            let mut parts = vec![[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]];
            for _ in 0..2 {
                parts = parts
                    .iter()
                    .flat_map(crate::math::triangle::split)
                    .collect();
            }
            let area = q.area / parts.len() as f64;
            let mut points = Vec::new();
            for [a, b, c] in parts {
                for (p, w) in rule.points.iter().zip(&rule.weights) {
                    let s = a[0] + p[0] * (b[0] - a[0]) + p[1] * (c[0] - a[0]);
                    let t = a[1] + p[0] * (b[1] - a[1]) + p[1] * (c[1] - a[1]);
                    points.push((q.at(s, t), w * area));
                }
            }
            points
        };
        let mut total = 0.0;
        for (i, a) in geo.quads.iter().enumerate() {
            for (j, b) in geo.quads.iter().enumerate() {
                // the halves of one square: names "light-0" and "light-1"
                if quads[i].name[..quads[i].name.len() - 2]
                    == quads[j].name[..quads[j].name.len() - 2]
                {
                    continue;
                }
                for (x, wx) in parts(a) {
                    for (y, wy) in parts(b) {
                        total += wx * wy * transfer::kernel(x, a.n, y, b.n).powi(2);
                    }
                }
            }
        }
        let sampled = h.sampled_kernel_error(&surface_groups(&quads), PAIRS);
        assert_eq!(sampled.left_out, vec![(0, 1), (2, 3), (4, 5)]);
        agree(&sampled, (total - kept) / total);
    }
}
