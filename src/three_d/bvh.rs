//! A bounding volume hierarchy over the parallelograms of a 3D scene, for the visibility term
//! V(x, y) of the slides' eq. (3) and for the camera's primary rays.
//!
//! - Built top-down by the surface area heuristic over centroid-ordered splits (MacDonald and
//!   Booth 1990) into a binary tree whose leaves hold up to eight surfaces, where testing them
//!   all costs less than another box.
//! - Then collapsed into a 4-wide tree (Wald, Benthin and Boulos 2008; Dammertz et al. 2008):
//!   each node holds the boxes of up to four children side by side, and each leaf one or two
//!   packets of four parallelograms side by side, so that a ray meets four boxes with the slab
//!   method (Kay and Kajiya 1986), or four parallelograms through their dual bases, in one
//!   pass of vector arithmetic.
//!
//! Written here rather than taken from a crate: the crates build over `f32` triangles, where
//! the form factors of surfaces that share an edge need `f64` parallelograms, and visibility
//! rays need only "any hit" with two surfaces skipped. The lanes are AVX2 registers where the
//! processor has them (`pulp` checks at run time), two SSE2 halves (`wide`) elsewhere.
//! Measured in `benches/three_d.rs` (rays per second, `benches/README.md`).

use crate::three_d::geometry::{box_of, dot, sub, Parallelogram, V3};
use rayon::prelude::*;
use smallvec::SmallVec;

/// Children per node and surfaces per leaf.
const W: usize = 4;
/// A child reference with this bit set is a leaf: `packets` consecutive entries of `leaves`
/// from `first`, encoded as `LEAF | first << 1 | (packets − 1)`.
const LEAF: u32 = 1 << 31;
/// Packets of four surfaces a leaf may hold.
const PACKETS: usize = 2;

/// Up to four children: their boxes by axis and lane, and references. Lanes past `count` are
/// never read.
#[derive(Debug, Clone, Copy)]
struct Node {
    lo: [Lanes4; 3],
    hi: [Lanes4; 3],
    child: [u32; W],
    count: u32,
}

/// Up to four parallelograms by component and lane. Empty lanes have a zero normal, so that a
/// ray never crosses them, and the surface index `u32::MAX`.
#[derive(Debug, Clone, Copy)]
struct Leaf {
    p0: [Lanes4; 3],
    n: [Lanes4; 3],
    u: [Lanes4; 3],
    v: [Lanes4; 3],
    /// 1 for a triangle (s + u ≤ 1 too), 0 for a parallelogram.
    tri: Lanes4,
    id: [u32; W],
}

impl Leaf {
    /// The packet of up to four surfaces `ids` of `quads`.
    fn pack(quads: &[Parallelogram], ids: &[u32]) -> Leaf {
        let mut lanes = [[[0.0; W]; 3]; 4];
        let mut id = [u32::MAX; W];
        let mut tri = [0.0; W];
        for (k, &i) in ids.iter().enumerate() {
            let q = &quads[i as usize];
            tri[k] = if q.tri { 1.0 } else { 0.0 };
            for (lane, vector) in lanes.iter_mut().zip([q.p0, q.n, q.u, q.v]) {
                for a in 0..3 {
                    lane[a][k] = vector[a];
                }
            }
            id[k] = i;
        }
        let [p0, n, u, v] = lanes.map(|l| l.map(Lanes4));
        Leaf {
            p0,
            n,
            u,
            v,
            tri: Lanes4(tri),
            id,
        }
    }
}

/// Four values side by side, aligned for one vector load.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(32))]
struct Lanes4([f64; W]);

/// The closest hit of a ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    pub(crate) surface: usize,
    pub(crate) dist: f64,
    pub(crate) s: f64,
    pub(crate) t: f64,
}

#[derive(Debug, Clone)]
pub struct Bvh {
    quads: Vec<Parallelogram>,
    /// Surfaces in the tree.
    members: usize,
    /// A second tree, in the same arrays, over the surfaces left out of the first
    /// ([`Bvh::occluders`]), for the box queries over every surface; none for [`Bvh::new`].
    left_out: Option<u32>,
    nodes: Vec<Node>,
    leaves: Vec<Leaf>,
    /// The reference to start from: a node, a leaf (`LEAF` set), or none when empty.
    root: Option<u32>,
    /// AVX2 and FMA, when the processor has them.
    #[cfg(target_arch = "x86_64")]
    avx2: Option<pulp::x86::V3>,
}

/// Whether two boxes, each (lo, hi), meet (touching counts).
pub(super) fn boxes_meet(a: (V3, V3), b: (V3, V3)) -> bool {
    (0..3).all(|k| a.0[k] <= b.1[k] && b.0[k] <= a.1[k])
}

/// The binary tree of the build, before it is collapsed.
struct Binary {
    lo: V3,
    hi: V3,
    /// Surfaces of a leaf; empty for an inner node.
    surfaces: Vec<u32>,
    kids: Option<Box<[Binary; 2]>>,
}

impl Binary {
    fn area(&self) -> f64 {
        let d = sub(self.hi, self.lo);
        d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
    }
}

/// The surfaces above which a node's two halves are built on two threads.
const PARALLEL_SPLIT: usize = 4096;

impl Bvh {
    pub fn new(quads: &[Parallelogram]) -> Bvh {
        Bvh::over(quads, (0..quads.len() as u32).collect())
    }

    /// A hierarchy for occlusion queries: it keeps every surface's index but leaves out of the
    /// tree each surface that has the whole scene on its front side (the walls of a room).
    /// A segment between two points of the scene stays in that closed half-space, so it can
    /// meet such a plane only at an end point or by lying in it, neither of which occludes.
    pub fn occluders(quads: &[Parallelogram]) -> Bvh {
        let size = quads.iter().map(|q| q.diameter()).fold(0.0, f64::max);
        let tol = 1e-9 * size;
        let corners: Vec<V3> = quads.iter().flat_map(|q| q.outline()).collect();
        // the corners farthest out in 26 directions first: they settle almost every surface
        // that is not bounding at once, where the scan of every corner would make this
        // quadratic in the surfaces
        let mut extremes: Vec<V3> = Vec::new();
        for d in 0..27 {
            let dir = [
                (d % 3) as f64 - 1.0,
                (d / 3 % 3) as f64 - 1.0,
                (d / 9) as f64 - 1.0,
            ];
            if let Some(&c) = corners
                .iter()
                .min_by(|a, b| dot(**a, dir).total_cmp(&dot(**b, dir)))
            {
                extremes.push(c);
            }
        }
        // then, for a surface that passes them, the least n · c over every corner c, once
        // per distinct normal: a mesh of many triangles on one plane (a floor, a wall) would
        // otherwise scan every corner once per triangle, quadratic in them (10⁵ coplanar
        // triangles: 56 s)
        let candidates: Vec<u32> = (0..quads.len() as u32)
            .filter(|&i| {
                let q = &quads[i as usize];
                extremes.iter().all(|&c| q.side(c) >= -tol)
            })
            .collect();
        let key = |n: V3| n.map(f64::to_bits);
        let mut normals: Vec<[u64; 3]> = candidates
            .iter()
            .map(|&i| key(quads[i as usize].n))
            .collect();
        normals.sort_unstable();
        normals.dedup();
        let least: std::collections::HashMap<[u64; 3], f64> = normals
            .into_par_iter()
            .map(|k| {
                let n = k.map(f64::from_bits);
                let least = corners
                    .iter()
                    .map(|&c| dot(n, c))
                    .fold(f64::INFINITY, f64::min);
                (k, least)
            })
            .collect();
        let mut bounding = vec![false; quads.len()];
        for i in candidates {
            let q = &quads[i as usize];
            bounding[i as usize] = least[&key(q.n)] - dot(q.n, q.p0) >= -tol;
        }
        let members = (0..quads.len() as u32)
            .filter(|&i| !bounding[i as usize])
            .collect();
        Bvh::over(quads, members)
    }

    fn over(quads: &[Parallelogram], members: Vec<u32>) -> Bvh {
        let mut inside = vec![false; quads.len()];
        members.iter().for_each(|&i| inside[i as usize] = true);
        let left_out: Vec<u32> = (0..quads.len() as u32)
            .filter(|&i| !inside[i as usize])
            .collect();
        let mut bvh = Bvh {
            quads: quads.to_vec(),
            members: members.len(),
            left_out: None,
            nodes: Vec::new(),
            leaves: Vec::new(),
            root: None,
            #[cfg(target_arch = "x86_64")]
            avx2: pulp::x86::V3::try_new(),
        };
        // each surface's box once: the sorts compare them n log n times a level
        let boxes: Vec<(V3, V3)> = (0..quads.len() as u32).map(|i| bvh.bounds(i)).collect();
        if !members.is_empty() {
            let tree = bvh.split(&boxes, members);
            bvh.root = Some(bvh.collapse(&tree));
        }
        // the walls of a meshed room are all left out, thousands of triangles: a tree of their
        // own, where a scan for each surface's query would be quadratic
        if !left_out.is_empty() {
            let tree = bvh.split(&boxes, left_out);
            bvh.left_out = Some(bvh.collapse(&tree));
        }
        bvh
    }

    /// How many surfaces the tree holds.
    #[cfg(test)]
    pub(crate) fn len(&self) -> usize {
        self.members
    }

    pub fn is_empty(&self) -> bool {
        self.members == 0
    }

    pub(super) fn quads(&self) -> &[Parallelogram] {
        &self.quads
    }

    /// The bounding box of surface `i`.
    pub(super) fn bounds(&self, i: u32) -> (V3, V3) {
        box_of(self.quads[i as usize].outline())
    }

    /// The binary SAH tree over `surfaces`, whose boxes are `boxes` (by surface); its two
    /// halves are built in parallel.
    fn split(&self, boxes: &[(V3, V3)], mut surfaces: Vec<u32>) -> Binary {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for &i in &surfaces {
            let (l, h) = boxes[i as usize];
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
        let count = surfaces.len();
        let leaf = Binary {
            lo,
            hi,
            surfaces: Vec::new(),
            kids: None,
        };
        if count <= W {
            return Binary { surfaces, ..leaf };
        }
        // of the splits of the centroid order along each axis, the one of least expected cost
        // by the surface area heuristic (MacDonald and Booth 1990): one box test plus, for
        // each side, the chance that a ray through this box meets that side's box times the
        // packets there. That keeps each box of a room in its own node.
        let packets = |n: usize| n.div_ceil(W) as f64;
        let total = leaf.area();
        // (cost, axis, split): the order is sorted again for the best axis only, since
        // keeping a copy of it at every improvement would be quadratic in the surfaces
        let mut best: Option<(f64, usize, usize)> = None;
        let key = |axis: usize, i: &u32| {
            let (l, h) = boxes[*i as usize];
            l[axis] + h[axis]
        };
        for axis in 0..3 {
            let mut slice = surfaces.clone();
            slice.sort_by(|a, b| key(axis, a).total_cmp(&key(axis, b)).then(a.cmp(b)));
            let areas = |it: &mut dyn Iterator<Item = &u32>| -> Vec<f64> {
                let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
                it.map(|&i| {
                    let (l, h) = boxes[i as usize];
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
                let cost = 1.0 + (left[k - 1] * packets(k) + right[k] * packets(count - k)) / total;
                if best.as_ref().is_none_or(|b| cost < b.0) {
                    best = Some((cost, axis, k));
                }
            }
        }
        // a leaf of a few packets, tested without a box in between, when that is cheaper
        if count <= PACKETS * W && best.as_ref().is_none_or(|b| packets(count) <= b.0) {
            return Binary { surfaces, ..leaf };
        }
        let (_, axis, half) = best.expect("more than four surfaces");
        surfaces.sort_by(|a, b| key(axis, a).total_cmp(&key(axis, b)).then(a.cmp(b)));
        let right = surfaces.split_off(half);
        Binary {
            lo,
            hi,
            surfaces: Vec::new(),
            kids: Some(Box::new(if count > PARALLEL_SPLIT {
                let (a, b) =
                    rayon::join(|| self.split(boxes, surfaces), || self.split(boxes, right));
                [a, b]
            } else {
                [self.split(boxes, surfaces), self.split(boxes, right)]
            })),
        }
    }

    /// The 4-wide tree of a binary one: each node takes up to four descendants, opening the
    /// inner one of largest area first; returns the reference to `tree`.
    fn collapse(&mut self, tree: &Binary) -> u32 {
        let Some(kids) = &tree.kids else {
            let first = self.leaves.len() as u32;
            for chunk in tree.surfaces.chunks(W) {
                let leaf = Leaf::pack(&self.quads, chunk);
                self.leaves.push(leaf);
            }
            let packets = self.leaves.len() as u32 - first;
            return LEAF | first << 1 | (packets - 1);
        };
        let mut open: Vec<&Binary> = vec![&kids[0], &kids[1]];
        while open.len() < W {
            let widest = (0..open.len())
                .filter(|&k| open[k].kids.is_some())
                .max_by(|&a, &b| open[a].area().total_cmp(&open[b].area()));
            let Some(k) = widest else { break };
            let pair = open[k].kids.as_ref().expect("inner");
            open[k] = &pair[0];
            open.insert(k + 1, &pair[1]);
        }
        // lanes past `count` keep a zero box; the walks mask them out
        let mut lo = [[0.0; W]; 3];
        let mut hi = [[0.0; W]; 3];
        for (k, b) in open.iter().enumerate() {
            for a in 0..3 {
                lo[a][k] = b.lo[a];
                hi[a][k] = b.hi[a];
            }
        }
        let me = self.nodes.len();
        self.nodes.push(Node {
            lo: lo.map(Lanes4),
            hi: hi.map(Lanes4),
            child: [0; W],
            count: open.len() as u32,
        });
        for (k, b) in open.into_iter().enumerate() {
            let child = self.collapse(b);
            self.nodes[me].child[k] = child;
        }
        me as u32
    }

    /// Whether `test` holds for some surface whose bounding box meets the box [lo, hi], over
    /// every surface of the scene, the tree's and those it leaves out
    /// ([`Bvh::occluders`], in a second tree over the same surfaces' copy), so that the
    /// occluders' tree also answers the box queries that need them all (what stands or lies
    /// on what, [`crate::three_d::cover`]; which surfaces touch) without a second hierarchy
    /// and a second copy of the surfaces: 0.56 s of 10⁵ triangles.
    pub(super) fn any_in_scene_box(
        &self,
        lo: V3,
        hi: V3,
        mut test: impl FnMut(usize) -> bool,
    ) -> bool {
        let meets = |l: V3, h: V3| boxes_meet((l, h), (lo, hi));
        self.any_below(self.root, &meets, &mut test)
            || self.any_below(self.left_out, &meets, &mut test)
    }

    /// Whether `test` holds for some surface of the tree whose bounding box meets the box
    /// [lo, hi]; the walk stops at the first.
    pub(super) fn any_in_box(&self, lo: V3, hi: V3, test: impl FnMut(usize) -> bool) -> bool {
        self.any_below(self.root, &|l, h| boxes_meet((l, h), (lo, hi)), test)
    }

    /// Whether `test` holds for some surface of the tree whose bounding box `region` may
    /// meet; the walk stops at the first. `region` answers for a box [lo, hi] (a node's, then
    /// its children's, and a surface's) and must answer yes for every box that holds a
    /// point of the region; it may keep state between calls (tighten as the walk goes on).
    pub(super) fn any_in_region(
        &self,
        region: &impl Fn(V3, V3) -> bool,
        test: impl FnMut(usize) -> bool,
    ) -> bool {
        self.any_below(self.root, region, test)
    }

    /// [`Bvh::any_in_region`] from `root`.
    fn any_below(
        &self,
        root: Option<u32>,
        region: &impl Fn(V3, V3) -> bool,
        mut test: impl FnMut(usize) -> bool,
    ) -> bool {
        let Some(root) = root else {
            return false;
        };
        let mut stack: SmallVec<[u32; 48]> = SmallVec::new();
        stack.push(root);
        while let Some(r) = stack.pop() {
            if r & LEAF != 0 {
                for leaf in packets(self, r) {
                    for &id in leaf.id.iter().filter(|&&id| id != u32::MAX) {
                        let (l, h) = self.bounds(id);
                        if region(l, h) && test(id as usize) {
                            return true;
                        }
                    }
                }
                continue;
            }
            let node = &self.nodes[r as usize];
            for k in 0..node.count as usize {
                let l = [node.lo[0].0[k], node.lo[1].0[k], node.lo[2].0[k]];
                let h = [node.hi[0].0[k], node.hi[1].0[k], node.hi[2].0[k]];
                if region(l, h) {
                    stack.push(node.child[k]);
                }
            }
        }
        false
    }

    /// The nearest hit with distance in (t_min, t_max) along `o + t d`, skipping `skip`.
    pub fn first_hit(&self, o: V3, d: V3, t_min: f64, t_max: f64, skip: [usize; 2]) -> Option<Hit> {
        #[cfg(target_arch = "x86_64")]
        if let Some(simd) = self.avx2 {
            // SAFETY: `avx2` is set only when the processor has the features the walk is
            // compiled for
            return unsafe { nearest_avx2(simd, self, Query::new(o, d, t_min, t_max, skip)) };
        }
        nearest(Portable, self, Query::new(o, d, t_min, t_max, skip))
    }

    /// Whether some surface other than `skip` crosses the open segment (a, b): any hit ends
    /// the walk.
    pub fn occluded(&self, a: V3, b: V3, skip: [usize; 2]) -> bool {
        let q = Query::segment(a, b, skip);
        #[cfg(target_arch = "x86_64")]
        if let Some(simd) = self.avx2 {
            // SAFETY: as for `first_hit`
            return unsafe { any_hit_avx2(simd, self, q) };
        }
        any_hit(Portable, self, q)
    }

    /// Surfaces `ids` of the scene in packets of four, for [`Bvh::occluded_among`].
    pub(crate) fn shaft(&self, ids: &[u32]) -> Shaft {
        Shaft(ids.chunks(W).map(|c| Leaf::pack(&self.quads, c)).collect())
    }

    /// [`Bvh::occluded`] with only the surfaces of `shaft` tested, each packet by the same
    /// arithmetic as the tree's leaves: the same answer when they are every surface of the
    /// tree that may cross the segment.
    pub(crate) fn occluded_among(&self, shaft: &Shaft, a: V3, b: V3, skip: [usize; 2]) -> bool {
        let q = Query::segment(a, b, skip);
        #[cfg(target_arch = "x86_64")]
        if let Some(simd) = self.avx2 {
            // SAFETY: as for `first_hit`
            return unsafe { any_crossing_avx2(simd, &shaft.0, q) };
        }
        any_crossing(Portable, &shaft.0, q)
    }
}

/// A few surfaces taken out of the tree in packets of four: those that may come between two
/// pieces (the candidate list of shaft culling, Haines and Wallace 1991, here the surfaces
/// whose boxes may meet the pieces' hull). A ray between the pieces then tests each packet
/// instead of walking the tree from its root. The packets are on the heap: each pair's list is
/// moved by value, and eight packets held inline (3.5 KB) were copied for every pair judged,
/// the clear ones too (the Cornell box refined about 5 % faster without the copies).
#[derive(Debug, Clone)]
pub(crate) struct Shaft(Vec<Leaf>);

impl Shaft {
    /// Whether the shaft holds no surface.
    pub(crate) fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

/// The vector operations of the walks, on four `f64` lanes: AVX2 registers where the processor
/// has them (chosen at run time through `pulp`), two SSE2 halves (`wide`) elsewhere.
trait Lanes: Copy {
    type F: Copy;
    /// Lane masks, all ones where a comparison holds.
    type M: Copy;
    fn load(self, x: &Lanes4) -> Self::F;
    fn splat(self, x: f64) -> Self::F;
    fn store(self, x: Self::F) -> [f64; W];
    fn add(self, a: Self::F, b: Self::F) -> Self::F;
    fn sub(self, a: Self::F, b: Self::F) -> Self::F;
    fn mul(self, a: Self::F, b: Self::F) -> Self::F;
    fn lt(self, a: Self::F, b: Self::F) -> Self::M;
    fn le(self, a: Self::F, b: Self::F) -> Self::M;
    fn and(self, a: Self::M, b: Self::M) -> Self::M;
    /// `a` where `m` is set, else `b`.
    fn select(self, m: Self::M, a: Self::F, b: Self::F) -> Self::F;
    /// Lane k's mask as bit k.
    fn bits(self, m: Self::M) -> u32;
}

#[derive(Clone, Copy)]
struct Portable;

impl Lanes for Portable {
    type F = wide::f64x4;
    type M = wide::f64x4;
    #[inline(always)]
    fn load(self, x: &Lanes4) -> Self::F {
        wide::f64x4::new(x.0)
    }
    #[inline(always)]
    fn splat(self, x: f64) -> Self::F {
        wide::f64x4::splat(x)
    }
    #[inline(always)]
    fn store(self, x: Self::F) -> [f64; W] {
        x.to_array()
    }
    #[inline(always)]
    fn add(self, a: Self::F, b: Self::F) -> Self::F {
        a + b
    }
    #[inline(always)]
    fn sub(self, a: Self::F, b: Self::F) -> Self::F {
        a - b
    }
    #[inline(always)]
    fn mul(self, a: Self::F, b: Self::F) -> Self::F {
        a * b
    }
    #[inline(always)]
    fn lt(self, a: Self::F, b: Self::F) -> Self::M {
        a.simd_lt(b)
    }
    #[inline(always)]
    fn le(self, a: Self::F, b: Self::F) -> Self::M {
        a.simd_le(b)
    }
    #[inline(always)]
    fn and(self, a: Self::M, b: Self::M) -> Self::M {
        a & b
    }
    #[inline(always)]
    fn select(self, m: Self::M, a: Self::F, b: Self::F) -> Self::F {
        m.select(a, b)
    }
    #[inline(always)]
    fn bits(self, m: Self::M) -> u32 {
        m.to_bitmask()
    }
}

#[cfg(target_arch = "x86_64")]
impl Lanes for pulp::x86::V3 {
    type F = pulp::f64x4;
    type M = pulp::m64x4;
    #[inline(always)]
    fn load(self, x: &Lanes4) -> Self::F {
        pulp::cast(x.0)
    }
    #[inline(always)]
    fn splat(self, x: f64) -> Self::F {
        self.splat_f64x4(x)
    }
    #[inline(always)]
    fn store(self, x: Self::F) -> [f64; W] {
        pulp::cast(x)
    }
    #[inline(always)]
    fn add(self, a: Self::F, b: Self::F) -> Self::F {
        self.add_f64x4(a, b)
    }
    #[inline(always)]
    fn sub(self, a: Self::F, b: Self::F) -> Self::F {
        self.sub_f64x4(a, b)
    }
    #[inline(always)]
    fn mul(self, a: Self::F, b: Self::F) -> Self::F {
        self.mul_f64x4(a, b)
    }
    #[inline(always)]
    fn lt(self, a: Self::F, b: Self::F) -> Self::M {
        self.cmp_lt_f64x4(a, b)
    }
    #[inline(always)]
    fn le(self, a: Self::F, b: Self::F) -> Self::M {
        self.cmp_le_f64x4(a, b)
    }
    #[inline(always)]
    fn and(self, a: Self::M, b: Self::M) -> Self::M {
        self.and_m64x4(a, b)
    }
    #[inline(always)]
    fn select(self, m: Self::M, a: Self::F, b: Self::F) -> Self::F {
        self.select_f64x4(m, a, b)
    }
    #[inline(always)]
    fn bits(self, m: Self::M) -> u32 {
        self.avx._mm256_movemask_pd(pulp::cast(m)) as u32
    }
}

/// [`nearest`] compiled for AVX2 and FMA. The walks are generic over their lanes and inlined
/// here, so that every vector operation inlines into one function built for those features:
/// through `pulp`'s `vectorize` the nearest-hit walk stayed a separate function built without
/// them, each operation a call, and ran ten times slower than the portable lanes.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2,fma")]
unsafe fn nearest_avx2(simd: pulp::x86::V3, bvh: &Bvh, q: Query) -> Option<Hit> {
    nearest(simd, bvh, q)
}

/// [`any_hit`] compiled for AVX2 and FMA, as [`nearest_avx2`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2,fma")]
unsafe fn any_hit_avx2(simd: pulp::x86::V3, bvh: &Bvh, q: Query) -> bool {
    any_hit(simd, bvh, q)
}

/// [`any_crossing`] compiled for AVX2 and FMA, as [`nearest_avx2`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2,fma")]
unsafe fn any_crossing_avx2(simd: pulp::x86::V3, packets: &[Leaf], q: Query) -> bool {
    any_crossing(simd, packets, q)
}

/// The test of [`Bvh::occluded_among`]: the packets one after another, up to the first that
/// the ray crosses.
#[inline(always)]
fn any_crossing<L: Lanes>(simd: L, packets: &[Leaf], q: Query) -> bool {
    let ray = Ray::new(simd, q);
    let t_max = simd.splat(q.t_max);
    packets.iter().any(|leaf| ray.crossings(leaf, t_max).1 != 0)
}

/// The walk for [`Bvh::occluded`]; children are visited in any order.
#[inline(always)]
fn any_hit<L: Lanes>(simd: L, bvh: &Bvh, q: Query) -> bool {
    let Some(root) = bvh.root else {
        return false;
    };
    let ray = Ray::new(simd, q);
    let t_max = simd.splat(q.t_max);
    let mut stack: SmallVec<[u32; 48]> = SmallVec::new();
    stack.push(root);
    while let Some(r) = stack.pop() {
        if r & LEAF != 0 {
            for leaf in packets(bvh, r) {
                if ray.crossings(leaf, t_max).1 != 0 {
                    return true;
                }
            }
            continue;
        }
        let node = &bvh.nodes[r as usize];
        let (_, mut hits) = ray.slabs(node, t_max);
        while hits != 0 {
            stack.push(node.child[hits.trailing_zeros() as usize]);
            hits &= hits - 1;
        }
    }
    false
}

/// The walk for [`Bvh::first_hit`]: nearer children first, and a child whose box starts
/// beyond the nearest hit so far is dropped when it comes off the stack.
#[inline(always)]
fn nearest<L: Lanes>(simd: L, bvh: &Bvh, q: Query) -> Option<Hit> {
    let root = bvh.root?;
    let ray = Ray::new(simd, q);
    let mut best: Option<Hit> = None;
    let mut t_max = q.t_max;
    let mut stack: SmallVec<[(u32, f64); 48]> = SmallVec::new();
    stack.push((root, q.t_min));
    while let Some((r, enter)) = stack.pop() {
        if enter > t_max {
            continue;
        }
        if r & LEAF != 0 {
            for leaf in packets(bvh, r) {
                let (at, mut hits) = ray.crossings(leaf, simd.splat(t_max));
                while hits != 0 {
                    let k = hits.trailing_zeros() as usize;
                    hits &= hits - 1;
                    let (t, s, u) = at.at(k);
                    if t < t_max {
                        t_max = t;
                        best = Some(Hit {
                            surface: leaf.id[k] as usize,
                            dist: t,
                            s,
                            t: u,
                        });
                    }
                }
            }
            continue;
        }
        let node = &bvh.nodes[r as usize];
        let (near, mut hits) = ray.slabs(node, simd.splat(t_max));
        // push the farthest first so that the nearest comes off the stack first
        let mut order: SmallVec<[(f64, u32); W]> = SmallVec::new();
        while hits != 0 {
            let k = hits.trailing_zeros() as usize;
            hits &= hits - 1;
            order.push((near[k], node.child[k]));
        }
        order.sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
        stack.extend(order.into_iter().map(|(t, c)| (c, t)));
    }
    best
}

/// The packets of the leaf reference `r`.
#[inline(always)]
fn packets(bvh: &Bvh, r: u32) -> &[Leaf] {
    let first = ((r & !LEAF) >> 1) as usize;
    &bvh.leaves[first..=first + (r & 1) as usize]
}

/// What a walk is asked about: the ray `o + t d` for t in (t_min, t_max), the surfaces
/// `skip` left out.
#[derive(Debug, Clone, Copy)]
struct Query {
    o: V3,
    d: V3,
    t_min: f64,
    t_max: f64,
    skip: [usize; 2],
}

impl Query {
    fn new(o: V3, d: V3, t_min: f64, t_max: f64, skip: [usize; 2]) -> Query {
        Query {
            o,
            d,
            t_min,
            t_max,
            skip,
        }
    }

    /// The open segment (a, b), its ends left out by a margin of 1e-9 of its length.
    fn segment(a: V3, b: V3, skip: [usize; 2]) -> Query {
        Query::new(a, sub(b, a), 1e-9, 1.0 - 1e-9, skip)
    }
}

/// A ray `o + t d`, t > t_min, set up for four lanes at a time.
struct Ray<L: Lanes> {
    simd: L,
    o: [L::F; 3],
    d: [L::F; 3],
    inv: [L::F; 3],
    t_min: L::F,
    skip: [u32; 2],
}

impl<L: Lanes> Ray<L> {
    #[inline(always)]
    fn new(simd: L, q: Query) -> Ray<L> {
        Ray {
            simd,
            o: q.o.map(|c| simd.splat(c)),
            d: q.d.map(|c| simd.splat(c)),
            inv: q.d.map(|c| simd.splat(1.0 / c)),
            t_min: simd.splat(q.t_min),
            // u32::MAX marks empty lanes, which never cross anyway
            skip: q.skip.map(|s| u32::try_from(s).unwrap_or(u32::MAX)),
        }
    }

    /// The slab test against a node's four boxes: the entry distances, and the lanes (bits)
    /// whose box the ray meets within (t_min, t_max).
    #[inline(always)]
    fn slabs(&self, n: &Node, t_max: L::F) -> ([f64; W], u32) {
        let v = self.simd;
        let mut near = self.t_min;
        let mut far = t_max;
        for a in 0..3 {
            let t0 = v.mul(v.sub(v.load(&n.lo[a]), self.o[a]), self.inv[a]);
            let t1 = v.mul(v.sub(v.load(&n.hi[a]), self.o[a]), self.inv[a]);
            let swap = v.lt(t1, t0);
            let (lo, hi) = (v.select(swap, t1, t0), v.select(swap, t0, t1));
            // NaN (0 · ∞ on a box face) compares false and leaves the interval unchanged
            near = v.select(v.lt(near, lo), lo, near);
            far = v.select(v.lt(hi, far), hi, far);
        }
        let lanes = (1u32 << n.count) - 1;
        (v.store(near), v.bits(v.le(near, far)) & lanes)
    }

    /// Where the ray meets the planes of a leaf's four parallelograms, and the lanes (bits)
    /// whose parallelogram it crosses within (t_min, t_max), other than the skipped surfaces.
    /// The tests multiply through by |d·n| instead of dividing by it; a ray parallel to a
    /// plane (or an empty lane, of zero normal) has d·n = 0 and fails them.
    #[inline(always)]
    fn crossings(&self, l: &Leaf, t_max: L::F) -> (Crossings, u32) {
        let v = self.simd;
        let dot = |a: &[L::F; 3], b: &[Lanes4; 3]| {
            let p = |k: usize| v.mul(a[k], v.load(&b[k]));
            v.add(v.add(p(0), p(1)), p(2))
        };
        let w = [0, 1, 2].map(|k| v.sub(v.load(&l.p0[k]), self.o[k]));
        let num = dot(&w, &l.n);
        let den = dot(&self.d, &l.n);
        // (s, u) × den of the point t d − w relative to p0, by the dual basis
        let s = v.sub(v.mul(num, dot(&self.d, &l.u)), v.mul(den, dot(&w, &l.u)));
        let u = v.sub(v.mul(num, dot(&self.d, &l.v)), v.mul(den, dot(&w, &l.v)));
        let zero = v.splat(0.0);
        let neg = v.lt(den, zero);
        let flip = |x: L::F| v.select(neg, v.sub(zero, x), x);
        let (a, tn, sn, un) = (flip(den), flip(num), flip(s), flip(u));
        let on = v.and(
            v.and(v.lt(v.mul(self.t_min, a), tn), v.lt(tn, v.mul(t_max, a))),
            v.and(
                v.and(v.le(zero, sn), v.le(sn, a)),
                v.and(
                    v.and(v.le(zero, un), v.le(un, a)),
                    // a triangle's diagonal: s + u ≤ 1 (tri = 0 makes it s ≤ 1 again)
                    v.le(v.add(sn, v.mul(v.load(&l.tri), un)), a),
                ),
            ),
        );
        let mut skipped = 0;
        for k in 0..W {
            skipped |= ((l.id[k] == self.skip[0]) | (l.id[k] == self.skip[1])) as u32 * (1 << k);
        }
        let fractions = Crossings {
            num: v.store(num),
            den: v.store(den),
            s: v.store(s),
            u: v.store(u),
        };
        (fractions, v.bits(on) & !skipped)
    }
}

/// A leaf's crossings as fractions over den = d·n: t = num / den, and (s, u) likewise.
struct Crossings {
    num: [f64; W],
    den: [f64; W],
    s: [f64; W],
    u: [f64; W],
}

impl Crossings {
    /// (t, s, u) of lane k.
    #[inline(always)]
    fn at(&self, k: usize) -> (f64, f64, f64) {
        let d = self.den[k];
        (self.num[k] / d, self.s[k] / d, self.u[k] / d)
    }
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

    /// The reference: one parallelogram at a time, solving o + t d = p0 + s e1 + u e3 by
    /// Cramer's rule (independent of the dual basis the tree uses).
    fn brute(quads: &[Parallelogram], o: V3, d: V3, t_max: f64, skip: [usize; 2]) -> Option<Hit> {
        let det = |a: V3, b: V3, c: V3| {
            a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                + a[2] * (b[0] * c[1] - b[1] * c[0])
        };
        (0..quads.len())
            .filter(|i| !skip.contains(i))
            .filter_map(|i| {
                let q = &quads[i];
                // t d − s e1 − u e3 = p0 − o
                let m = [
                    d,
                    [-q.e1[0], -q.e1[1], -q.e1[2]],
                    [-q.e3[0], -q.e3[1], -q.e3[2]],
                ];
                let r = sub(q.p0, o);
                let den = det(m[0], m[1], m[2]);
                if den == 0.0 {
                    return None;
                }
                let t = det(r, m[1], m[2]) / den;
                let s = det(m[0], r, m[2]) / den;
                let u = det(m[0], m[1], r) / den;
                let on = (0.0..=1.0).contains(&s)
                    && (0.0..=1.0).contains(&u)
                    && (!q.tri || s + u <= 1.0);
                (on && t > 1e-9 && t < t_max).then_some(Hit {
                    surface: i,
                    dist: t,
                    s,
                    t: u,
                })
            })
            .min_by(|a, b| a.dist.total_cmp(&b.dist))
    }

    fn agree(quads: &[Parallelogram], rays: usize, box_size: [f64; 3], seed: u64) -> usize {
        let bvh = Bvh::new(quads);
        let mut rnd = uniform(seed);
        let mut hits = 0;
        for n in 0..rays {
            let mut point = || box_size.map(|l| rnd() * (l + 1.0) - 0.5);
            let (o, e) = (point(), point());
            let d = sub(e, o);
            let skip = if n % 3 == 0 {
                [n % quads.len(), (n / 7) % quads.len()]
            } else {
                [usize::MAX; 2]
            };
            let want = brute(quads, o, d, 1.0 - 1e-9, skip);
            let got = bvh.first_hit(o, d, 1e-9, 1.0 - 1e-9, skip);
            assert_eq!(got.map(|h| h.surface), want.map(|h| h.surface));
            if let (Some(g), Some(w)) = (got, want) {
                assert!((g.dist - w.dist).abs() < 1e-12, "{g:?} {w:?}");
                assert!((g.s - w.s).abs() < 1e-9 && (g.t - w.t).abs() < 1e-9);
            }
            assert_eq!(bvh.occluded(o, e, skip), want.is_some());
            // the portable lanes give the same answers as the vector unit's
            let portable = nearest(Portable, &bvh, Query::new(o, d, 1e-9, 1.0 - 1e-9, skip));
            assert_eq!(portable, got);
            let blocked = any_hit(Portable, &bvh, Query::new(o, d, 1e-9, 1.0 - 1e-9, skip));
            assert_eq!(blocked, want.is_some());
            // an unbounded ray finds the nearest hit of the whole line's forward half
            let far = bvh.first_hit(o, d, 1e-9, f64::INFINITY, skip);
            let want = brute(quads, o, d, f64::INFINITY, skip);
            assert_eq!(far.map(|h| h.surface), want.map(|h| h.surface));
            hits += want.is_some() as usize;
        }
        hits
    }

    #[test]
    fn nearest_hit_and_occlusion_agree_with_brute_force() {
        let quads: Vec<_> = (0..9)
            .map(|i| square(i as f64 * 0.5, (i % 3) as f64 * 0.7))
            .collect();
        let hits = agree(&quads, 2000, [2.0, 1.0, 4.0], 12345);
        assert!(hits > 500, "{hits}");
    }

    #[test]
    fn a_deep_tree_of_tilted_plates_agrees_with_brute_force() {
        // 300 small plates of random size and orientation in a 4 × 4 × 4 box: a tree of
        // several levels, with leaves of one to four plates
        let mut rnd = uniform(777);
        let quads: Vec<_> = (0..300)
            .map(|_| {
                let c = [rnd() * 4.0, rnd() * 4.0, rnd() * 4.0];
                let mut e = || [rnd() - 0.5, rnd() - 0.5, rnd() - 0.5];
                let (e1, e3) = (e(), e());
                Parallelogram::new(&[
                    c,
                    [c[0] + e1[0], c[1] + e1[1], c[2] + e1[2]],
                    [
                        c[0] + e1[0] + e3[0],
                        c[1] + e1[1] + e3[1],
                        c[2] + e1[2] + e3[2],
                    ],
                    [c[0] + e3[0], c[1] + e3[1], c[2] + e3[2]],
                ])
            })
            .collect();
        let bvh = Bvh::new(&quads);
        assert!(bvh.nodes.len() > 10, "{}", bvh.nodes.len());
        let hits = agree(&quads, 3000, [4.0; 3], 4242);
        assert!(hits > 1000 && hits < 2900, "{hits}");
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

    /// The box queries over every surface ([`Bvh::any_in_scene_box`]) of the occluders' tree
    /// find what the full tree finds: the walls of a room, each of 4 × 4 parallelograms (96
    /// left out of the occluders, a tree of their own), and 40 plates inside it.
    #[test]
    fn the_occluders_box_queries_over_the_scene_find_what_the_full_tree_finds() {
        let mut rnd = uniform(7);
        let walls = [
            ([0., 0., 0.], [1., 0., 0.], [0., 1., 0.]),
            ([0., 0., 1.], [0., 1., 0.], [1., 0., 0.]),
            ([0., 0., 0.], [0., 1., 0.], [0., 0., 1.]),
            ([1., 0., 0.], [0., 0., 1.], [0., 1., 0.]),
            ([0., 0., 0.], [0., 0., 1.], [1., 0., 0.]),
            ([0., 1., 0.], [1., 0., 0.], [0., 0., 1.]),
        ];
        let mut quads = Vec::new();
        for (o, u, v) in walls {
            for (i, j) in (0..16).map(|k| (k % 4, k / 4)) {
                let at = |a: f64, b: f64| -> V3 {
                    std::array::from_fn(|k| o[k] + 0.25 * (a * u[k] + b * v[k]))
                };
                let (a, b) = (i as f64, j as f64);
                quads.push(Parallelogram::new(&[
                    at(a, b),
                    at(a + 1.0, b),
                    at(a + 1.0, b + 1.0),
                    at(a, b + 1.0),
                ]));
            }
        }
        for _ in 0..40 {
            let c: V3 = std::array::from_fn(|_| 0.1 + 0.8 * rnd());
            let h = 0.02 + 0.05 * rnd();
            quads.push(Parallelogram::new(&[
                [c[0] - h, c[1] - h, c[2]],
                [c[0] + h, c[1] - h, c[2] + h],
                [c[0] + h, c[1] + h, c[2] + h],
                [c[0] - h, c[1] + h, c[2]],
            ]));
        }
        let (all, occ) = (Bvh::new(&quads), Bvh::occluders(&quads));
        assert_eq!(occ.len(), 40);
        let mut found = 0;
        for _ in 0..500 {
            let c: V3 = std::array::from_fn(|_| 1.2 * rnd() - 0.1);
            let h: V3 = std::array::from_fn(|_| 0.2 * rnd());
            let (lo, hi): (V3, V3) = (sub(c, h), std::array::from_fn(|k| c[k] + h[k]));
            let mut sets = [Vec::new(), Vec::new()];
            let [a, b] = &mut sets;
            all.any_in_box(lo, hi, |i| {
                a.push(i);
                false
            });
            occ.any_in_scene_box(lo, hi, |i| {
                b.push(i);
                false
            });
            sets.iter_mut().for_each(|s| s.sort_unstable());
            assert_eq!(sets[0], sets[1], "{lo:?} {hi:?}");
            found += sets[0].len();
        }
        assert!(found > 1000, "{found}");
    }
}
