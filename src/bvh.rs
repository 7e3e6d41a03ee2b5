//! A bounding volume hierarchy over the parallelograms of a 3D scene, for the visibility term
//! V(x, y) of the slides' eq. (3) and for the camera's primary rays.
//!
//! Built top-down by the surface area heuristic over centroid-ordered splits; nodes are
//! axis-aligned boxes tested with the slab method (Kay and Kajiya 1986); leaves hold up to two
//! parallelograms, intersected through their dual basis.

use crate::space::{dot, sub, Parallelogram, V3};

#[derive(Debug, Clone, Copy)]
struct Node {
    lo: V3,
    hi: V3,
    /// Leaf: first index into `order` and count; inner: left child index (right = left + 1 is
    /// not assumed: `right` holds it) and count 0.
    first: u32,
    count: u32,
    right: u32,
}

/// The closest hit of a ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    pub surface: usize,
    pub dist: f64,
    pub s: f64,
    pub t: f64,
}

#[derive(Debug, Clone)]
pub struct Bvh {
    quads: Vec<Parallelogram>,
    nodes: Vec<Node>,
    order: Vec<u32>,
}

impl Bvh {
    pub fn new(quads: &[Parallelogram]) -> Bvh {
        let mut bvh = Bvh {
            quads: quads.to_vec(),
            nodes: Vec::new(),
            order: (0..quads.len() as u32).collect(),
        };
        if !quads.is_empty() {
            bvh.build(0, quads.len());
        }
        bvh
    }

    /// A hierarchy for occlusion queries: it keeps every surface's index but leaves out of the
    /// tree each surface that has the whole scene on its front side (the walls of a room).
    /// A segment between two points of the scene stays in that closed half-space, so it can
    /// meet such a plane only at an end point or by lying in it, neither of which occludes.
    pub fn occluders(quads: &[Parallelogram]) -> Bvh {
        let size = quads.iter().map(|q| q.diameter()).fold(0.0, f64::max);
        let tol = 1e-9 * size;
        let bounding = |q: &Parallelogram| {
            quads.iter().all(|o| {
                o.piece([0.0, 1.0], [0.0, 1.0])
                    .iter()
                    .all(|&c| q.side(c) >= -tol)
            })
        };
        let mut bvh = Bvh {
            quads: quads.to_vec(),
            nodes: Vec::new(),
            order: (0..quads.len() as u32)
                .filter(|&i| !bounding(&quads[i as usize]))
                .collect(),
        };
        if !bvh.order.is_empty() {
            bvh.build(0, bvh.order.len());
        }
        bvh
    }

    /// How many surfaces the tree holds.
    pub fn len(&self) -> usize {
        self.order.len()
    }

    pub fn is_empty(&self) -> bool {
        self.order.is_empty()
    }

    pub fn quads(&self) -> &[Parallelogram] {
        &self.quads
    }

    fn bounds(&self, i: u32) -> (V3, V3) {
        let q = &self.quads[i as usize];
        let mut lo = q.p0;
        let mut hi = q.p0;
        for c in [q.at(1.0, 0.0), q.at(1.0, 1.0), q.at(0.0, 1.0)] {
            for a in 0..3 {
                lo[a] = lo[a].min(c[a]);
                hi[a] = hi[a].max(c[a]);
            }
        }
        (lo, hi)
    }

    fn build(&mut self, first: usize, count: usize) -> u32 {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for &i in &self.order[first..first + count] {
            let (l, h) = self.bounds(i);
            for a in 0..3 {
                lo[a] = lo[a].min(l[a]);
                hi[a] = hi[a].max(h[a]);
            }
        }
        // pad degenerate (planar) boxes so that the slab test never divides 0 by 0 into NaN
        for a in 0..3 {
            let pad = 1e-9 * (hi[a] - lo[a]).abs().max(1e-12);
            lo[a] -= pad;
            hi[a] += pad;
        }
        let me = self.nodes.len() as u32;
        self.nodes.push(Node {
            lo,
            hi,
            first: first as u32,
            count: count as u32,
            right: 0,
        });
        if count <= 2 {
            return me;
        }
        // the surface area heuristic: of the splits of the centroid order along each axis,
        // the one that minimises Σ area(child box) × surfaces in it (MacDonald and Booth
        // 1990), which keeps each box of a room in its own node
        let mut best: Option<(f64, Vec<u32>, usize)> = None;
        for axis in 0..3 {
            let key = |i: &u32| {
                let (l, h) = self.bounds(*i);
                l[axis] + h[axis]
            };
            let mut slice: Vec<u32> = self.order[first..first + count].to_vec();
            slice.sort_by(|a, b| key(a).total_cmp(&key(b)).then(a.cmp(b)));
            let areas = |it: &mut dyn Iterator<Item = &u32>| -> Vec<f64> {
                let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
                it.map(|&i| {
                    let (l, h) = self.bounds(i);
                    for a in 0..3 {
                        lo[a] = lo[a].min(l[a]);
                        hi[a] = hi[a].max(h[a]);
                    }
                    let d = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
                    d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
                })
                .collect()
            };
            let left = areas(&mut slice.iter());
            let mut right = areas(&mut slice.iter().rev());
            right.reverse();
            for k in 1..count {
                let cost = left[k - 1] * k as f64 + right[k] * (count - k) as f64;
                if best.as_ref().is_none_or(|b| cost < b.0) {
                    best = Some((cost, slice.clone(), k));
                }
            }
        }
        let (_, slice, half) = best.expect("at least three surfaces");
        self.order[first..first + count].copy_from_slice(&slice);
        let left = self.build(first, half);
        let right = self.build(first + half, count - half);
        let node = &mut self.nodes[me as usize];
        node.first = left;
        node.count = 0;
        node.right = right;
        me
    }

    /// The nearest hit with distance in (t_min, t_max) along `o + t d`, skipping `skip`.
    pub fn first_hit(&self, o: V3, d: V3, t_min: f64, t_max: f64, skip: [usize; 2]) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let mut t_max = t_max;
        self.traverse(o, d, t_min, &mut t_max, |i, t_max| {
            if i != skip[0] && i != skip[1] {
                if let Some(hit) = intersect(&self.quads[i], i, o, d, t_min, *t_max) {
                    *t_max = hit.dist;
                    best = Some(hit);
                }
            }
            false
        });
        best
    }

    /// Whether some surface other than `skip` crosses the open segment (a, b): any hit ends
    /// the walk.
    pub fn occluded(&self, a: V3, b: V3, skip: [usize; 2]) -> bool {
        let d = sub(b, a);
        let (t_min, mut t_max) = (1e-9, 1.0 - 1e-9);
        let mut hit = false;
        self.traverse(a, d, t_min, &mut t_max, |i, t_max| {
            hit = i != skip[0] && i != skip[1] && crosses(&self.quads[i], a, d, t_min, *t_max);
            hit
        });
        hit
    }

    /// Visits the surfaces in the leaves whose boxes the ray o + t d meets for t in
    /// (t_min, t_max); `leaf` may shorten t_max and returns whether to stop. Generic, so that
    /// each query's test is inlined into the loop.
    fn traverse(
        &self,
        o: V3,
        d: V3,
        t_min: f64,
        t_max: &mut f64,
        mut leaf: impl FnMut(usize, &mut f64) -> bool,
    ) {
        if self.nodes.is_empty() {
            return;
        }
        let inv = [1.0 / d[0], 1.0 / d[1], 1.0 / d[2]];
        let mut stack = [0u32; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            if !slab(node, o, inv, t_min, *t_max) {
                continue;
            }
            if node.count == 0 {
                stack[top] = node.first;
                stack[top + 1] = node.right;
                top += 2;
                continue;
            }
            for &i in &self.order[node.first as usize..(node.first + node.count) as usize] {
                if leaf(i as usize, t_max) {
                    return;
                }
            }
        }
    }
}

#[inline(always)]
fn slab(n: &Node, o: V3, inv: V3, t_min: f64, t_max: f64) -> bool {
    let mut lo = t_min;
    let mut hi = t_max;
    for a in 0..3 {
        let t0 = (n.lo[a] - o[a]) * inv[a];
        let t1 = (n.hi[a] - o[a]) * inv[a];
        let (near, far) = if t0 < t1 { (t0, t1) } else { (t1, t0) };
        // NaN (0 · ∞ on a box face) compares false and leaves the interval unchanged
        if near > lo {
            lo = near;
        }
        if far < hi {
            hi = far;
        }
    }
    lo <= hi
}

/// Whether the ray o + t d meets the parallelogram for some t in (t_min, t_max).
#[inline(always)]
fn crosses(q: &Parallelogram, o: V3, d: V3, t_min: f64, t_max: f64) -> bool {
    let den = dot(d, q.n);
    let w = sub(q.p0, o);
    let num = dot(w, q.n);
    // t = num / den in (t_min, t_max), without the division
    let inside = if den > 0.0 {
        num > t_min * den && num < t_max * den
    } else if den < 0.0 {
        num < t_min * den && num > t_max * den
    } else {
        false
    };
    if !inside {
        return false;
    }
    let t = num / den;
    let p = [
        o[0] + t * d[0] - q.p0[0],
        o[1] + t * d[1] - q.p0[1],
        o[2] + t * d[2] - q.p0[2],
    ];
    let s = dot(p, q.u);
    let u = dot(p, q.v);
    (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&u)
}

/// Ray o + t d against a parallelogram (either side), t in (t_min, t_max).
#[inline(always)]
fn intersect(q: &Parallelogram, i: usize, o: V3, d: V3, t_min: f64, t_max: f64) -> Option<Hit> {
    let den = dot(d, q.n);
    if den == 0.0 {
        return None;
    }
    let t = dot(sub(q.p0, o), q.n) / den;
    if !(t > t_min && t < t_max) {
        return None;
    }
    let p = [o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]];
    let (s, u) = q.params(p);
    ((0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&u)).then_some(Hit {
        surface: i,
        dist: t,
        s,
        t: u,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(z: f64, x0: f64) -> Parallelogram {
        Parallelogram::new(&[
            [x0, 0.0, z],
            [x0 + 1.0, 0.0, z],
            [x0 + 1.0, 1.0, z],
            [x0, 1.0, z],
        ])
    }

    /// Deterministic uniform numbers in [0, 1) from a 64-bit linear congruential generator.
    fn uniform(mut seed: u64) -> impl FnMut() -> f64 {
        move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    #[test]
    fn nearest_hit_and_occlusion_agree_with_brute_force() {
        let quads: Vec<_> = (0..9)
            .map(|i| square(i as f64 * 0.5, (i % 3) as f64 * 0.7))
            .collect();
        let bvh = Bvh::new(&quads);
        let mut rnd = uniform(12345);
        for _ in 0..2000 {
            let o = [rnd() * 3.0 - 0.5, rnd() * 2.0 - 0.5, rnd() * 5.0 - 0.5];
            let e = [rnd() * 3.0 - 0.5, rnd() * 2.0 - 0.5, rnd() * 5.0 - 0.5];
            let d = sub(e, o);
            let brute = (0..quads.len())
                .filter_map(|i| intersect(&quads[i], i, o, d, 1e-9, 1.0 - 1e-9))
                .min_by(|a, b| a.dist.total_cmp(&b.dist));
            let got = bvh.first_hit(o, d, 1e-9, 1.0 - 1e-9, [usize::MAX; 2]);
            assert_eq!(got.map(|h| h.surface), brute.map(|h| h.surface));
            assert_eq!(bvh.occluded(o, e, [usize::MAX; 2]), brute.is_some());
        }
    }

    #[test]
    fn occluders_leave_out_the_walls_of_a_room_and_nothing_else() {
        // the inside of a unit cube (normals inward) and a small plate floating in it
        let faces = [
            [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]],
            [[0., 0., 1.], [0., 1., 1.], [1., 1., 1.], [1., 0., 1.]],
            [[0., 0., 0.], [0., 1., 0.], [0., 1., 1.], [0., 0., 1.]],
            [[1., 0., 0.], [1., 0., 1.], [1., 1., 1.], [1., 1., 0.]],
            [[0., 0., 0.], [0., 0., 1.], [1., 0., 1.], [1., 0., 0.]],
            [[0., 1., 0.], [1., 1., 0.], [1., 1., 1.], [0., 1., 1.]],
            [
                [0.4, 0.4, 0.5],
                [0.6, 0.4, 0.5],
                [0.6, 0.6, 0.5],
                [0.4, 0.6, 0.5],
            ],
        ];
        let quads: Vec<_> = faces.iter().map(Parallelogram::new).collect();
        let all = Bvh::new(&quads);
        let occ = Bvh::occluders(&quads);
        assert_eq!(occ.len(), 1);
        // the same answers as the full tree for segments between points of the surfaces
        let mut rnd = uniform(99);
        let mut blocked = 0;
        for _ in 0..4000 {
            let (i, k) = ((rnd() * 7.0) as usize, (rnd() * 7.0) as usize);
            let a = quads[i].at(rnd(), rnd());
            let b = quads[k].at(rnd(), rnd());
            let want = all.occluded(a, b, [i, k]);
            assert_eq!(occ.occluded(a, b, [i, k]), want, "{a:?} {b:?}");
            blocked += want as usize;
        }
        assert!(blocked > 20, "{blocked}");
    }
}
