//! The visibility term V(x, y) of the slides' eq. (3) between two pieces of patches
//! (parallelograms and triangles).
//!
//! - A conservative test first: a surface can occlude a pair of pieces only if it meets the
//!   convex hull of their corners. The separating-axis theorem decides it on a set of candidate
//!   axes (face normals and edge cross products); a missing axis only makes the test more
//!   conservative, so pairs it clears need no rays at all.
//! - Partially occluded pairs get a stratified estimate (Hanrahan, Salzman and Aupperle 1991,
//!   §4.2): a jittered n × n grid of points on each piece, the target's strata shuffled, one ray
//!   per pair of points that face each other through the [`Bvh`], each weighted by the kernel.
//!   The jitter is seeded from the indices of the two pieces, so the same document gives the
//!   same fractions.
//! - The same rays, grouped by the quarter (or, with enough of them, by the step cell: of a
//!   4 × 4 grid on a parallelogram, the sixteen grandchildren of a triangle) of the receiver
//!   they start from, give the visible fraction as a step over the receiver ([`Seen`]); a
//!   Galerkin block is weighted by it on the receiver's side, so a shadow edge through a
//!   receiver shows in its polynomial.

use crate::three_d::bvh::{Bvh, Shaft};
use crate::three_d::cover::{Mask, Partial};
use crate::three_d::geometry::Piece;
use crate::three_d::geometry::{
    box_of, cross, dot, norm, quad_quad, scale, sub, Parallelogram, V3,
};
use crate::three_d::steps::{quarter_of, tri_cell, Steps, CELLS, STEP};

/// Whether the parallelogram `q` may meet the convex hull of `points` (conservative). With
/// `thorough`, every candidate axis of the hull is tried (its edges and faces through any of
/// the points); without, only the axes that are cheap and decide most pairs of a room: `q`'s
/// normal, the coordinate axes, the normals of the two pieces and the cross products of their
/// edges with `q`'s. The per-element test runs for every link, where a dozen rays cost less
/// than the ~100 axes of the thorough test; the per-surface test runs once.
fn may_occlude(points: &[V3; 8], thorough: bool, q: &Parallelogram) -> bool {
    let qc = q.outline();
    // the tolerance's scale: q's size plus the points' bounding box
    let (lo, hi) = box_of(*points);
    let scale = q.diameter() + norm(sub(hi, lo));
    let tol = 1e-9 * scale;
    // projections on the unnormalised axis, the tolerance scaled to match: no division
    let separated = |axis: V3| {
        let l2 = dot(axis, axis);
        if l2 <= 1e-24 * scale * scale * scale * scale {
            return false;
        }
        let (mut plo, mut phi) = (f64::INFINITY, f64::NEG_INFINITY);
        for p in points {
            let v = dot(*p, axis);
            plo = plo.min(v);
            phi = phi.max(v);
        }
        let (mut qlo, mut qhi) = (f64::INFINITY, f64::NEG_INFINITY);
        for p in &qc {
            let v = dot(*p, axis);
            qlo = qlo.min(v);
            qhi = qhi.max(v);
        }
        let tol = tol * l2.sqrt();
        phi <= qlo + tol || qhi <= plo + tol
    };
    if separated(q.n) || (0..3).any(|a| separated(unit(a))) {
        return false;
    }
    // the two pieces (points 0..4 and 4..8): their planes and edges
    for c in [&points[0..4], &points[4..8]] {
        let (e1, e3) = (sub(c[1], c[0]), sub(c[3], c[0]));
        if separated(cross(e1, e3)) {
            return false;
        }
        for e in [e1, e3] {
            if separated(cross(e, q.e1)) || separated(cross(e, q.e3)) {
                return false;
            }
        }
    }
    if !thorough {
        return true;
    }
    for (i, a) in points.iter().enumerate() {
        for b in &points[i + 1..] {
            let d = sub(*b, *a);
            if separated(cross(d, q.e1)) || separated(cross(d, q.e3)) {
                return false;
            }
        }
    }
    // face normals of the hull spanned by three of the points
    for i in 0..points.len() {
        for j in i + 1..points.len() {
            for k in j + 1..points.len() {
                if separated(cross(sub(points[j], points[i]), sub(points[k], points[i]))) {
                    return false;
                }
            }
        }
    }
    true
}

fn unit(a: usize) -> V3 {
    let mut v = [0.0; 3];
    v[a] = 1.0;
    v
}

/// The eight corners of pieces `a` and `b`: the hull every ray between them lies in.
fn corners_of_pair(quads: &[Parallelogram], a: Piece, b: Piece) -> [V3; 8] {
    let (ca, cb) = (a.corners(quads), b.corners(quads));
    [ca[0], ca[1], ca[2], ca[3], cb[0], cb[1], cb[2], cb[3]]
}

/// The most surfaces that [`occluders`] lists for a pair's rays (eight packets): a ray tests
/// each of them where it would walk the tree. On the Cornell box and the room with 7 × 7
/// boxes, lists of 16, 32 and 64 took the refinement 6, 9 and 9 % and 1, 3 and 2 % less
/// time than the tree alone (each the mean of two runs, the results the same to the bit).
const SHAFT_SURFACES: usize = 32;

/// What may come between two pieces, for the rays between them: the few surfaces that may
/// (none when the pair is clear), or the whole tree when they are too many to list.
pub(crate) struct Occluders<'b> {
    bvh: &'b Bvh,
    few: Option<Shaft>,
}

impl<'b> Occluders<'b> {
    /// Every surface of `bvh`: the rays walk the tree.
    #[cfg(test)]
    pub(crate) fn all(bvh: &'b Bvh) -> Occluders<'b> {
        Occluders { bvh, few: None }
    }

    /// Whether no surface can come between the pieces.
    pub(crate) fn clear(&self) -> bool {
        self.few.as_ref().is_some_and(Shaft::is_empty)
    }

    /// Whether some surface other than `skip` crosses the open segment (x, y) between the
    /// pieces: the listed surfaces alone when there is a list, which holds every surface
    /// whose box may meet the pieces' hull, and so every one that may cross the segment.
    fn occluded(&self, x: V3, y: V3, skip: [usize; 2]) -> bool {
        match &self.few {
            Some(shaft) => self.bvh.occluded_among(shaft, x, y, skip),
            None => self.bvh.occluded(x, y, skip),
        }
    }
}

/// The surfaces of `bvh` (other than the pieces' own) that may occlude some ray between
/// pieces `a` and `b`. An empty list when no surface that the walk of the pieces' [`Hull`]
/// reaches passes the quick test of [`may_occlude`] on the pieces' hull and the thorough one
/// on their whole surfaces' hull, or when the hull's faces leave none of those it reached:
/// the pair is clear. Else every surface the walk reaches that the faces keep, with no test
/// of its own (the tests cost more than the rays they would spare: testing each surface of
/// the box made the room with 7 × 7 boxes 23 % slower), or the whole tree when the walk
/// reaches more than [`SHAFT_SURFACES`]. One walk finds both (a second walk for the list,
/// once the first had found an occluder, repeated most of it; with the faces' quicker
/// rejection in [`Hull`] the Cornell box refined 5 % faster and the room with 7 × 7 boxes
/// 8 %, with the same links and results to the bit; a few pairs more are found clear, and
/// the Cornell box casts 4.50 M rays instead of 4.51 M).
pub(super) fn occluders<'b>(bvh: &'b Bvh, memo: &HullMemo, a: Piece, b: Piece) -> Occluders<'b> {
    let quads = bvh.quads();
    let pts = corners_of_pair(quads, a, b);
    let whole = corners_of_pair(quads, Piece::whole(a.surface), Piece::whole(b.surface));
    // the whole surfaces' test is the pieces' own when both are whole, and the same for
    // every pair of pieces of the two surfaces otherwise: then it is kept
    let pieces = a != Piece::whole(a.surface) || b != Piece::whole(b.surface);
    let thorough = |k: usize| {
        if pieces {
            memo.get_or([a.surface, b.surface, k], || {
                may_occlude(&whole, true, &quads[k])
            })
        } else {
            may_occlude(&whole, true, &quads[k])
        }
    };
    let hull = Hull::of(&pts);
    let region = |l: V3, h: V3| hull.may_meet(l, h);
    // one walk lists the surfaces, and tests them until one may occlude
    let mut few: smallvec::SmallVec<[u32; SHAFT_SURFACES]> = smallvec::SmallVec::new();
    let (mut many, mut occluding, mut looked) = (false, false, 0);
    bvh.any_in_region(&region, |k| {
        if k == a.surface || k == b.surface {
            return false;
        }
        if few.len() == SHAFT_SURFACES {
            many = true;
        } else {
            few.push(k as u32);
        }
        if !occluding {
            looked += 1;
            occluding =
                looked > HULL_TEST_BUDGET || (may_occlude(&pts, false, &quads[k]) && thorough(k));
        }
        occluding && many
    });
    // the surfaces listed before the faces were found, tested by them now (a list that
    // they empty leaves the pair clear)
    if occluding && !many && hull.faces.get().is_some() {
        few.retain(|k| {
            let (l, h) = bvh.bounds(*k);
            hull.within_faces(l, h)
        });
    }
    Occluders {
        bvh,
        few: if !occluding {
            Some(bvh.shaft(&[]))
        } else {
            (!many).then(|| bvh.shaft(&few))
        },
    }
}

/// Whether a surface that may come between pieces `a` and `b` (other than theirs; by the
/// quick test of [`may_occlude`] on their hull) lies within `reach` of piece `a`: an occluder
/// that close casts a shadow on `a` about as narrow as its distance, which the rays of a
/// coarse pair, drawn from inside `a`, can all miss (`three_d::hierarchy::refine`).
pub(super) fn occluder_near(bvh: &Bvh, a: Piece, b: Piece, reach: f64) -> bool {
    let quads = bvh.quads();
    let pts = corners_of_pair(quads, a, b);
    let ca = a.corners(quads);
    let na = quads[a.surface].n;
    let (lo, hi) = box_of(ca);
    bvh.any_in_box(lo.map(|x| x - reach), hi.map(|x| x + reach), |k| {
        k != a.surface
            && k != b.surface
            && may_occlude(&pts, false, &quads[k])
            && quad_quad(&ca, na, &quads[k].outline(), quads[k].n) < reach
    })
}

/// The convex hull of two pieces' corners, which holds every segment between them: its
/// bounding box and its faces, each as a half-space n · (x − p₀) ≤ c (n of unit length, p₀
/// the first corner, so that the offsets' rounding is the pair's size's, not that of its
/// distance from the scene's origin), all a little widened. A box wholly outside one of them
/// holds nothing that can stop a ray of the pair: the walk of [`occluders`] leaves it out,
/// and with it a whole subtree of the BVH (shaft culling, Haines and Wallace 1991, with the
/// hull's own faces for the shaft's planes). A pair's box alone held a third of a meshed
/// room's triangles when the pieces were far apart on a diagonal, and the hull test of each
/// of them was most of its job.
///
/// The faces cost about as much as the walk of a small scene, so they are found only once
/// [`Hull::BOXES_BEFORE_FACES`] boxes have met the bounding box: in the Cornell box the faces
/// of every pair made the refinement 20 % slower.
struct Hull<'p> {
    points: &'p [V3; 8],
    lo: V3,
    hi: V3,
    pad: f64,
    met: std::cell::Cell<usize>,
    faces: std::cell::OnceCell<smallvec::SmallVec<[(V3, f64); 24]>>,
}

impl<'p> Hull<'p> {
    const BOXES_BEFORE_FACES: usize = 8;

    fn of(points: &'p [V3; 8]) -> Hull<'p> {
        let (mut lo, mut hi) = box_of(*points);
        // the quick test's tolerance reaches this far outside
        let pad = 1e-8 * norm(sub(hi, lo)).max(1e-300);
        for i in 0..3 {
            lo[i] -= pad;
            hi[i] += pad;
        }
        Hull {
            points,
            lo,
            hi,
            pad,
            met: std::cell::Cell::new(0),
            faces: std::cell::OnceCell::new(),
        }
    }

    fn faces(&self) -> smallvec::SmallVec<[(V3, f64); 24]> {
        let (points, pad) = (self.points, self.pad);
        let d = sub(self.hi, self.lo);
        // a face of the hull of two flat convex pieces is the plane of one of them, or
        // holds an edge of one and a corner of the other, with every point on one side; a
        // plane through points nearly in one line, or whose normal overflowed, is left out
        // (the hull is then only less tight)
        let o = points[0];
        let mut faces: smallvec::SmallVec<[(V3, f64); 24]> = smallvec::SmallVec::new();
        let min_area = 1e-6 * dot(d, d);
        let mut consider = |p: V3, q: V3, r: V3| {
            let n = cross(sub(q, p), sub(r, p));
            let l2 = dot(n, n);
            if !l2.is_finite() || l2 <= min_area * min_area {
                return;
            }
            // the corners' heights over the plane, times |n|: most candidates have corners
            // more than `pad` out on both sides, which the first few show, with no root
            // taken (p is a corner, at height 0)
            let reach = pad * pad * l2;
            let (mut below, mut above) = (0.0f64, 0.0f64);
            for x in points {
                let h = dot(n, sub(*x, p));
                below = below.min(h);
                above = above.max(h);
                if below * below > reach && above * above > reach {
                    return;
                }
            }
            let len = l2.sqrt();
            let n = scale(n, 1.0 / len);
            let (c, below, above) = (dot(n, sub(p, o)), below / len, above / len);
            // a face with every corner at most `pad` outside it, moved out to `pad` beyond the
            // farthest corner
            for (n, c, out) in [(n, c, above), (scale(n, -1.0), -c, -below)] {
                let c = c + out.max(0.0) + pad;
                let known = faces
                    .iter()
                    .any(|(m, e)| dot(*m, n) > 1.0 - 1e-12 && (e - c).abs() <= pad);
                if out <= pad && !known {
                    faces.push((n, c));
                }
            }
        };
        let (a, b) = points.split_at(4);
        for (p, q) in [(a, b), (b, a)] {
            consider(p[0], p[1], p[2]);
            for i in 0..4 {
                for &c in q {
                    consider(p[i], p[(i + 1) % 4], c);
                }
            }
        }
        faces
    }

    /// Whether the box [l, h] may meet the hull: it meets its bounding box, and no face has
    /// all of it outside.
    fn may_meet(&self, l: V3, h: V3) -> bool {
        if !crate::three_d::bvh::boxes_meet((l, h), (self.lo, self.hi)) {
            return false;
        }
        if self.met.get() < Self::BOXES_BEFORE_FACES {
            self.met.set(self.met.get() + 1);
            return true;
        }
        self.within_faces(l, h)
    }

    /// Whether no face has all of the box [l, h] outside.
    fn within_faces(&self, l: V3, h: V3) -> bool {
        let o = self.points[0];
        self.faces
            .get_or_init(|| self.faces())
            .iter()
            .all(|(n, c)| {
                let nearest: f64 = (0..3)
                    .map(|a| n[a] * (if n[a] > 0.0 { l[a] } else { h[a] } - o[a]))
                    .sum();
                nearest <= *c || nearest.is_nan()
            })
    }
}

/// The thorough hull test of [`occluders`] on two whole surfaces and an occluder, kept
/// per triple: a refinement asks it again for every pair of pieces of the same two surfaces
/// (in a room with 3 × 3 boxes it was a quarter of the job). Sharded so that the judging
/// threads seldom wait on one another, and bounded: a shard stops keeping new answers at
/// [`HullMemo::SHARD_LIMIT`] (a scene of 10⁵ triangles asks about millions of triples, most
/// of them once).
#[derive(Debug)]
pub(crate) struct HullMemo {
    shards: Vec<std::sync::Mutex<rustc_hash::FxHashMap<[usize; 3], bool>>>,
}

impl HullMemo {
    const SHARDS: usize = 64;
    const SHARD_LIMIT: usize = 1 << 12;

    pub(crate) fn new() -> HullMemo {
        HullMemo {
            shards: (0..Self::SHARDS).map(|_| Default::default()).collect(),
        }
    }

    /// The kept answer for `key`, else `test()`, kept while its shard has room.
    fn get_or(&self, key: [usize; 3], test: impl FnOnce() -> bool) -> bool {
        let h = key[0]
            .wrapping_mul(0x9e37_79b9_7f4a_7c15)
            .wrapping_add(key[1].wrapping_mul(0xc2b2_ae3d_27d4_eb4f))
            .wrapping_add(key[2]);
        let shard = &self.shards[(h >> 7) % Self::SHARDS];
        let lock = || shard.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(&known) = lock().get(&key) {
            return known;
        }
        let answer = test();
        let mut kept = lock();
        if kept.len() < Self::SHARD_LIMIT {
            kept.insert(key, answer);
        }
        answer
    }
}

/// The most surfaces that [`occluders`] tests of those its walk of the pair's hull reaches;
/// beyond them it answers that something may occlude, and the rays walk the tree. In a scene
/// of many small surfaces a hull may reach thousands, and a ray through the tree costs less
/// than the tests of a few dozen.
const HULL_TEST_BUDGET: usize = 256;

/// SplitMix64: the seeded generator of the jitter.
#[derive(Debug, Clone)]
pub struct SplitMix(pub u64);

impl SplitMix {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// What the visible fraction of a pair may still be when none of its `rays` got through: 3/n,
/// the one-sided 95 % bound on a fraction of which none of n samples hit (the "rule of three":
/// (1 − V)ⁿ ≤ 0.05 for V ≥ 3/n). The oracles take it as the share of the pair's transfer that
/// a hidden pair may be missing (through a gap the rays did not find), not the whole of it.
pub(super) fn unseen_bound(rays: u64) -> f64 {
    if rays == 0 {
        1.0
    } else {
        (3.0 / rays as f64).min(1.0)
    }
}

/// A seed from two element identities (order matters: the pair is directed).
pub(super) fn pair_seed(a: u64, b: u64) -> u64 {
    let mut r = SplitMix(a.wrapping_mul(0x100_0000_01B3) ^ b.rotate_left(32));
    r.next_u64()
}

/// The quarter (the child: `ds + 2 dt` on a parallelogram, the midpoint split's on a
/// triangle) of the receiver that step cell `c` lies in.
fn quarter(tri: bool, c: usize) -> usize {
    if tri {
        c / 4
    } else {
        quarter_of(c)
    }
}

/// What the rays between two pieces saw: the visible fraction of the whole transfer, and of
/// the part of it that arrives on each of the [`CELLS`] step cells of the receiver `a`
/// ([`crate::three_d::steps`]: on a parallelogram index `i + STEP j` by its s and t
/// positions, on a triangle its grandchildren).
///
/// A shadow edge crosses a receiver as a step; one fraction for the whole link spreads it
/// evenly (the floor next to a box gets the same share of sky at the box's foot as a cell's
/// width away from it). The cells keep a step of it, from the same rays: with few rays one
/// value per quarter of the receiver, with enough (four per cell) one per cell.
///
/// The cells' fractions are kept in 2⁻¹⁵ths (an accepted pair holds its `Seen` until its link
/// is made, and millions of them were a job's peak): 3e-5, against the sampling error of the
/// few rays behind each cell (about 0.1 from four rays); halves, quarters and eighths stay
/// exact.
///
/// Beside the fractions, `detail` is the ratio of the light that the source's finest
/// elements send along the pair's rays to what the polynomial that a link carries sends
/// along them ([`visible_share_of_light`]; 1 where it was not sampled).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Seen {
    pub(super) whole: f64,
    cells: [u16; CELLS],
    /// Whether the receiver is a triangle: its cells are those of [`tri_cell`].
    tri: bool,
    pub(super) detail: f32,
}

/// A cell's fraction 1 in the units of [`Seen`]'s cells.
const WHOLE_CELL: f64 = 32768.0;

impl Seen {
    /// Nothing in between.
    pub(super) const CLEAR: Seen = Seen {
        whole: 1.0,
        cells: [WHOLE_CELL as u16; CELLS],
        tri: false,
        detail: 1.0,
    };

    /// The fractions `whole` of the whole transfer and `cells` of each step cell's part, on
    /// a triangle receiver (`tri`) or a parallelogram.
    pub(super) fn new(whole: f64, cells: [f64; CELLS], tri: bool) -> Seen {
        Seen {
            whole,
            cells: cells.map(|v| (v.clamp(0.0, 1.0) * WHOLE_CELL).round() as u16),
            tri,
            detail: 1.0,
        }
    }

    /// The visible fraction of the part of the transfer that arrives on step cell `c`.
    pub(super) fn cell(&self, c: usize) -> f64 {
        f64::from(self.cells[c]) / WHOLE_CELL
    }

    /// Whether every cell's fraction is the whole's.
    fn uniform(&self) -> bool {
        (0..CELLS).all(|c| self.cell(c) == self.whole)
    }

    /// The mean fraction over each quarter of the receiver (its children).
    #[cfg(test)]
    pub(crate) fn quarters(&self) -> [f64; 4] {
        let mut q = [0.0; 4];
        for c in 0..CELLS {
            q[quarter(self.tri, c)] += self.cell(c) / (CELLS / 4) as f64;
        }
        q
    }

    /// Weighs a Galerkin block (`k² × k²`, row = receiver coefficient) by the visible
    /// fraction as a function on the receiver, piecewise constant on its step cells: the
    /// block becomes W · block with W = Σ_cells V_cell M_cell ([`Steps`]), the receiver's
    /// basis multiplied by that step function and projected back.
    ///
    /// At order 0 (k = 1) a receiver holds one constant, which the step cannot change: W
    /// would be the plain mean of the cells, and the whole fraction, weighted by the
    /// kernel, is the better estimate of the same number.
    pub(super) fn weigh(&self, steps: &Steps, block: &mut [f64]) {
        if steps.k == 1 || self.uniform() {
            block.iter_mut().for_each(|x| *x *= self.whole);
            return;
        }
        let m = if self.tri { &steps.tri } else { &steps.m };
        self.apply_step(m, steps.k, block);
    }

    /// [`Seen::weigh`] for a partly covered receiver: W = Σ_cells V_cell G_cell with the
    /// masked Gram matrices of its step cells ([`Partial`]), which turns the block into the
    /// moments ∫ χ φ_a H of the exposed part. The fractions are those of the exposed part
    /// ([`visible_fraction_over`]); uniform ones make W = V G. A partly covered triangle has
    /// no masked Gram matrices of its cells ([`Partial`]): it takes the whole fraction.
    pub(super) fn weigh_masked(&self, partial: &Partial, k: usize, block: &mut [f64]) {
        if k == 1 || partial.steps.is_empty() || self.uniform() {
            let kk = k * k;
            let w: Vec<f64> = partial.gram.iter().map(|g| self.whole * g).collect();
            left_multiply(&w, kk, block);
            return;
        }
        self.apply_step(&partial.steps, k, block);
    }

    /// block ← (Σ_cells V_cell M_cell) · block.
    fn apply_step(&self, m: &[Vec<f64>], k: usize, block: &mut [f64]) {
        let kk = k * k;
        let mut w = vec![0.0; kk * kk];
        for (c, m) in m.iter().enumerate() {
            let v = self.cell(c);
            w.iter_mut().zip(m).for_each(|(w, m)| *w += v * m);
        }
        left_multiply(&w, kk, block);
    }
}

/// block ← W · block for `kk × kk` row-major matrices.
fn left_multiply(w: &[f64], kk: usize, block: &mut [f64]) {
    let old = block.to_vec();
    for a in 0..kk {
        for b in 0..kk {
            block[a * kk + b] = (0..kk).map(|c| w[a * kk + c] * old[c * kk + b]).sum();
        }
    }
}

/// The visible fraction of quarter `q` (index `ds + 2 dt`), which no ray sampled, from the
/// others: the plane through three of them, across from one or two in a row, the mean of a
/// diagonal pair, `whole` when there are none.
/// On a triangle, whose children do not lie in rows, the mean of the others.
fn extend(known: &[Option<f64>; 4], q: usize, whole: f64, tri: bool) -> f64 {
    if tri {
        let known: Vec<f64> = known.iter().flatten().copied().collect();
        return if known.is_empty() {
            whole
        } else {
            known.iter().sum::<f64>() / known.len() as f64
        };
    }
    // neighbours across s and across t, and the diagonal
    let (across_s, across_t, diagonal) = (known[q ^ 1], known[q ^ 2], known[q ^ 3]);
    match (across_s, across_t, diagonal) {
        (Some(a), Some(b), Some(c)) => (a + b - c).clamp(0.0, 1.0),
        (Some(a), Some(b), None) => 0.5 * (a + b),
        (Some(a), None, _) | (None, Some(a), _) => a,
        (None, None, Some(c)) => c,
        (None, None, None) => whole,
    }
}

/// The visible fraction of the transfer between `a` and `b`: over a stratified `n × n` set of
/// point pairs, Σ w V / Σ w with w the point-to-disc kernel cosθa cosθb / (π r² + A) (A the
/// smaller piece's area, which keeps the weight finite for touching pieces), and the same over
/// the pairs whose point on `a` lies in each quarter of `a` or, for `n` ≥ 2 `STEP`, in each
/// step cell of `a` ([`Seen`]; a quarter no pair reached is extended from the others, a
/// cell takes its quarter's). Pairs that do not face each other carry no weight and cast no ray:
/// counting them would make a block's back-facing part, which a ray through the block itself
/// always finds occluded, darken its front. Returns 0 when no pair faces; the number of rays
/// cast is added to `rays`.
#[cfg(test)]
pub(crate) fn visible_fraction(
    bvh: &Bvh,
    a: Piece,
    b: Piece,
    n: usize,
    seed: u64,
    rays: &mut u64,
) -> Seen {
    visible_fraction_over(&Occluders::all(bvh), a, None, b, n, seed, rays)
}

/// The point (s, t) of piece `p` at (u, v) of its unit square: on a triangle piece, the
/// square folded onto the triangle along its diagonal (uniform on the triangle).
#[inline(always)]
pub(super) fn at(q: &Parallelogram, p: &Piece, u: f64, v: f64) -> (f64, f64) {
    if q.tri {
        let (u, v) = fold(u, v);
        return p.at_local(u, v);
    }
    (
        p.s[0] + (p.s[1] - p.s[0]) * u,
        p.t[0] + (p.t[1] - p.t[0]) * v,
    )
}

/// The point (u, v) of the unit square folded along its diagonal onto the reference
/// triangle u + v ≤ 1.
#[inline(always)]
fn fold(u: f64, v: f64) -> (f64, f64) {
    if u + v > 1.0 {
        (1.0 - u, 1.0 - v)
    } else {
        (u, v)
    }
}

/// [`visible_fraction`] over the pairs whose point on `a` is not `covered`: the fraction of
/// the light that reaches the exposed part of `a` ([`crate::three_d::cover`]).
pub(super) fn visible_fraction_over(
    occluders: &Occluders,
    a: Piece,
    covered: Option<&Mask>,
    b: Piece,
    n: usize,
    seed: u64,
    rays: &mut u64,
) -> Seen {
    visible_share_of_light(occluders, a, covered, b, n, seed, rays, &|_, _| 1.0, None)
}

/// [`visible_fraction_over`] with each ray also weighted by `light`, the radiosity of `b` at
/// the ray's end ((s, t) of its surface): the share of the light from `b` that is not
/// stopped, rather than of the rays. A link multiplies the whole transfer by it, and where
/// an occluder hides part of a source from a receiver, that part is most often also in the
/// occluder's shadow (the floor behind a block, seen from the ceiling), so the share of the
/// rays errs low, always: the Cornell box's ceiling took 2.4 % too little from the floor.
///
/// With `sent`, the polynomial of `b` that a link between the two carries, at (s, t), it
/// also gives the ratio of the light to it over the same pairs, Σ w L / Σ w P with w the
/// kernel to a disc of one grid cell's area ([`Seen`]'s `detail`): a link reads its source's B as one
/// polynomial, and where the source's finer elements hold light that the polynomial spreads
/// (a box's shadow on the floor) the kernel, which peaks where the light is (the part of
/// the floor under a receiver near the lamp), gathers more of it than of the spread. The
/// error of one link is within the oracle's estimate (its D_S, `hierarchy::refine`), but those of
/// all the links into a receiver share its sign: the room with 3 × 3 boxes' ceiling
/// gathered 3.9 % too little through its partly visible links from the floor, 0.46 % of
/// its light, with no change from ε = 1e-3 to 5e-4. The link's transfer times the ratio is
/// the rays' estimate of what the finer elements send.
#[allow(clippy::too_many_arguments)]
pub(super) fn visible_share_of_light(
    occluders: &Occluders,
    a: Piece,
    covered: Option<&Mask>,
    b: Piece,
    n: usize,
    seed: u64,
    rays: &mut u64,
    light: &dyn Fn(f64, f64) -> f64,
    sent: Option<&dyn Fn(f64, f64) -> f64>,
) -> Seen {
    let quads = occluders.bvh.quads();
    let (qa, qb) = (&quads[a.surface], &quads[b.surface]);
    let area = |p: &Piece, q: &Parallelogram| q.area * (p.s[1] - p.s[0]) * (p.t[1] - p.t[0]);
    let disc = area(&a, qa).min(area(&b, qb)) / std::f64::consts::PI;
    let mut rng = SplitMix(seed);
    let m = n * n;
    // on the stack for the grids the solvers use (up to 16 × 16): one call per judged pair
    let mut perm: smallvec::SmallVec<[u32; 256]> = (0..m as u32).collect();
    for i in (1..m).rev() {
        let j = (rng.next_u64() % (i as u64 + 1)) as usize;
        perm.swap(i, j);
    }
    let (mut seen, mut total) = ([0.0; CELLS], [0.0; CELLS]);
    // Σ w L and Σ w P of the ratio to `sent`
    let (mut shown, mut carried) = (0.0, 0.0);
    let cell = 1.0 / n as f64;
    for (i, &j) in perm.iter().enumerate() {
        let j = j as usize;
        let (ia, ja) = (i % n, i / n);
        let (ib, jb) = (j % n, j / n);
        let (ua, va) = (
            (ia as f64 + rng.next_f64()) * cell,
            (ja as f64 + rng.next_f64()) * cell,
        );
        let (ub, vb) = (
            (ib as f64 + rng.next_f64()) * cell,
            (jb as f64 + rng.next_f64()) * cell,
        );
        let (sa, ta) = at(qa, &a, ua, va);
        let (sb, tb) = at(qb, &b, ub, vb);
        if covered.is_some_and(|m| m.covered(sa, ta)) {
            continue;
        }
        let (x, y) = (qa.at(sa, ta), qb.at(sb, tb));
        let d = sub(y, x);
        let (ca, cb) = (dot(d, qa.n), -dot(d, qb.n));
        if ca <= 0.0 || cb <= 0.0 {
            continue;
        }
        let r2 = dot(d, d);
        let l = light(sb, tb);
        let w = ca * cb / (r2 * (r2 + disc)) * l;
        if let Some(sent) = sent {
            // each pair stands for a pair of the grid's cells: the disc of a cell, not of
            // the piece, which would flatten the kernel's peak that the ratio is about (by a
            // quarter of it for pieces as far apart as they are wide)
            let kernel = ca * cb / (r2 * (r2 + disc / m as f64));
            shown += kernel * l;
            carried += kernel * sent(sb, tb);
        }
        let step = |u: f64| ((u * STEP as f64) as usize).min(STEP - 1);
        let cell = if qa.tri {
            let (u, v) = fold(ua, va);
            tri_cell(u, v)
        } else {
            step(ua) + STEP * step(va)
        };
        *rays += 1;
        if !occluders.occluded(x, y, [a.surface, b.surface]) {
            seen[cell] += w;
        }
        total[cell] += w;
    }
    let lit = total.iter().sum::<f64>();
    let whole = if lit > 0.0 {
        seen.iter().sum::<f64>() / lit
    } else {
        0.0
    };
    // a polynomial that sends nothing toward `a` along the rays has no ratio to the light
    let detail = if sent.is_some() && carried > 0.0 && shown > 0.0 {
        (shown / carried) as f32
    } else {
        1.0
    };
    let (mut qs, mut qt) = ([0.0; 4], [0.0; 4]);
    for c in 0..CELLS {
        qs[quarter(qa.tri, c)] += seen[c];
        qt[quarter(qa.tri, c)] += total[c];
    }
    let fraction = |q: usize| (qt[q] > 0.0).then(|| qs[q] / qt[q]);
    let known: [Option<f64>; 4] = std::array::from_fn(fraction);
    let quarters: [f64; 4] =
        std::array::from_fn(|q| known[q].unwrap_or_else(|| extend(&known, q, whole, qa.tri)));
    // one value per cell once the stratified points put four in each; a cell no facing
    // pair reached keeps its quarter's
    let fine = n >= 2 * STEP;
    let cells = std::array::from_fn(|c| {
        if fine && total[c] > 0.0 {
            seen[c] / total[c]
        } else {
            quarters[quarter(qa.tri, c)]
        }
    });
    Seen {
        detail,
        ..Seen::new(whole, cells, qa.tri)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(z: f64, lo: f64, hi: f64, up: bool) -> Parallelogram {
        let c = [[lo, lo, z], [hi, lo, z], [hi, hi, z], [lo, hi, z]];
        if up {
            Parallelogram::new(&c)
        } else {
            Parallelogram::new(&[c[0], c[3], c[2], c[1]])
        }
    }

    /// An occluder near the receiver: a board 10 cm above a floor square, between it and a
    /// ceiling square 4 above, lies within the floor square's diameter; the same board 10 cm
    /// below the ceiling does not (it is near the source), nor a board 10 cm above the floor
    /// just beside the square, outside every segment between the two.
    #[test]
    fn an_occluder_near_the_receiver_is_found_within_its_reach() {
        let floor = square(0.0, 0.0, 1.0, true);
        let ceiling = square(4.0, 0.0, 1.0, false);
        let reach = 2f64.sqrt();
        let near = |board: Parallelogram| {
            let quads = [floor, ceiling, board];
            let bvh = Bvh::occluders(&quads);
            occluder_near(&bvh, Piece::whole(0), Piece::whole(1), reach)
        };
        assert!(near(square(0.1, 0.4, 0.6, true)));
        assert!(!near(square(3.9, 0.4, 0.6, true)));
        let beside = Parallelogram::new(&[
            [1.1, 0.4, 0.1],
            [1.3, 0.4, 0.1],
            [1.3, 0.6, 0.1],
            [1.1, 0.6, 0.1],
        ]);
        assert!(!near(beside));
    }

    /// The memo of the thorough hull test answers a triple once from the test and then from
    /// what it kept, and a full shard still answers (by testing again).
    #[test]
    fn the_hull_memo_tests_each_triple_once_while_it_has_room() {
        let memo = HullMemo::new();
        let calls = std::cell::Cell::new(0);
        let test = |answer: bool| {
            calls.set(calls.get() + 1);
            answer
        };
        assert!(memo.get_or([1, 2, 3], || test(true)));
        assert!(memo.get_or([1, 2, 3], || test(false)));
        assert!(!memo.get_or([2, 1, 3], || test(false)));
        assert_eq!(calls.get(), 2);
        for k in 0..HullMemo::SHARDS * HullMemo::SHARD_LIMIT + 1000 {
            memo.get_or([7, 8, k], || k % 2 == 0);
        }
        let kept: usize = memo.shards.iter().map(|s| s.lock().unwrap().len()).sum();
        assert!(kept <= HullMemo::SHARDS * HullMemo::SHARD_LIMIT);
        let before = calls.get();
        let far = HullMemo::SHARDS * HullMemo::SHARD_LIMIT + 999;
        assert!(!memo.get_or([7, 8, far], || test(false)));
        assert!(calls.get() <= before + 1);
    }

    #[test]
    fn hull_test_is_conservative_and_clears_room_walls() {
        // floor, ceiling, a blocker between them, a wall beside them and one far away
        let floor = square(0.0, 0.0, 1.0, true);
        let ceiling = square(1.0, 0.0, 1.0, false);
        let blocker = square(0.5, 0.3, 0.6, true);
        let wall = Parallelogram::new(&[
            [0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 1.0, 1.0],
            [0.0, 0.0, 1.0],
        ]);
        let far = square(3.0, 5.0, 6.0, true);
        let quads = [floor, ceiling, blocker, wall, far];
        // the blocker may come between the floor and the ceiling; without it, neither the
        // wall beside them nor the far square may
        let (whole0, whole1) = (Piece::whole(0), Piece::whole(1));
        let tree = Bvh::occluders(&quads);
        assert!(!occluders(&tree, &HullMemo::new(), whole0, whole1).clear());
        let open = [floor, ceiling, wall, far];
        let tree = Bvh::occluders(&open);
        assert!(occluders(&tree, &HullMemo::new(), whole0, whole1).clear());
        let bvh = Bvh::new(&quads);
        let mut rays = 0;
        let v = visible_fraction(&bvh, Piece::whole(0), Piece::whole(1), 8, 7, &mut rays).whole;
        assert_eq!(rays, 64);
        assert!(v > 0.5 && v < 1.0, "{v}");
        // same seed, same answer
        let w = visible_fraction(&bvh, Piece::whole(0), Piece::whole(1), 8, 7, &mut rays).whole;
        assert_eq!(v, w);
        // a piece under the blocker sees nothing of the piece above it
        let a = Piece {
            upper: false,
            surface: 0,
            s: [0.4, 0.5],
            t: [0.4, 0.5],
        };
        let b = Piece {
            upper: false,
            surface: 1,
            s: [0.4, 0.5],
            t: [0.5, 0.6],
        };
        assert_eq!(visible_fraction(&bvh, a, b, 4, 1, &mut rays).whole, 0.0);
    }

    /// The hull's faces leave out a box only where no segment between the pieces passes:
    /// between a unit square on the floor and one a unit above it shifted 2 along x (a
    /// slanted prism, whose bounding box is three times its volume), every point of 2000
    /// random segments is kept, and the points of the bounding box outside the prism are
    /// left out (at height z the prism spans 2z ≤ x ≤ 2z + 1); so are a triangle's.
    #[test]
    fn the_hull_keeps_every_segment_between_the_pieces_and_leaves_out_the_rest() {
        let floor = square(0.0, 0.0, 1.0, true);
        let ceiling = Parallelogram::new(&[
            [2.0, 0.0, 1.0],
            [2.0, 1.0, 1.0],
            [3.0, 1.0, 1.0],
            [3.0, 0.0, 1.0],
        ]);
        let quads = [floor, ceiling];
        let pts = corners_of_pair(&quads, Piece::whole(0), Piece::whole(1));
        let hull = Hull::of(&pts);
        hull.met.set(Hull::BOXES_BEFORE_FACES);
        let point = |x: V3| hull.may_meet(x, x);
        let mut rng = SplitMix(11);
        for _ in 0..2000 {
            let a = quads[0].at(rng.next_f64(), rng.next_f64());
            let b = quads[1].at(rng.next_f64(), rng.next_f64());
            let t = rng.next_f64();
            let x = crate::three_d::geometry::add(scale(a, 1.0 - t), scale(b, t));
            assert!(point(x));
        }
        let (mut inside, mut outside) = (0, 0);
        for _ in 0..2000 {
            let x = [3.0 * rng.next_f64(), rng.next_f64(), rng.next_f64()];
            // (points within 1e-6 of a slanted face are left to the faces' widening)
            let (left, right) = (x[0] - 2.0 * x[2], 2.0 * x[2] + 1.0 - x[0]);
            if left.abs() < 1e-6 || right.abs() < 1e-6 {
                continue;
            }
            let within = left > 0.0 && right > 0.0;
            assert_eq!(point(x), within, "{x:?}");
            if within {
                inside += 1;
            } else {
                outside += 1;
            }
        }
        assert!(
            inside > 400 && outside > 800,
            "{inside} inside, {outside} outside"
        );
        // a box across a slanted face is kept (its nearest corner is inside), one beyond it
        // is not
        assert!(hull.may_meet([1.9, 0.2, 0.5], [2.5, 0.8, 0.5]));
        assert!(!hull.may_meet([2.1, 0.2, 0.5], [2.5, 0.8, 0.5]));
        // a triangle's corners repeat its last: the same faces hold
        let tri = Parallelogram {
            tri: true,
            ..ceiling
        };
        let quads = [floor, tri];
        let pts = corners_of_pair(&quads, Piece::whole(0), Piece::whole(1));
        let hull = Hull::of(&pts);
        hull.met.set(Hull::BOXES_BEFORE_FACES);
        assert!(hull.may_meet([2.25, 0.25, 1.0], [2.25, 0.25, 1.0]));
        assert!(!hull.may_meet([2.8, 0.8, 1.0], [2.8, 0.8, 1.0]));
        assert!(!hull.may_meet([2.8, 0.8, 0.99], [2.9, 0.9, 0.999]));
    }

    /// The listed occluders change no ray's answer: between pieces of a floor and of a
    /// ceiling with 6 × 6 small tilted plates between them, the visible fraction through
    /// the list of [`occluders`] is the tree's to the bit, and a pair found clear is clear to
    /// every ray of the tree. Pairs of quarters use lists; the whole floor and ceiling,
    /// with all 36 plates in their box, walk the tree.
    #[test]
    fn the_listed_occluders_answer_every_ray_as_the_tree_does() {
        let mut quads = vec![square(0.0, 0.0, 1.0, true), square(1.0, 0.0, 1.0, false)];
        let mut rng = SplitMix(5);
        for i in 0..6 {
            for j in 0..6 {
                let (x, y) = (i as f64 / 6.0 + 0.02, j as f64 / 6.0 + 0.02);
                let (z, tilt) = (0.2 + 0.6 * rng.next_f64(), 0.05 * (rng.next_f64() - 0.5));
                quads.push(Parallelogram::new(&[
                    [x, y, z],
                    [x + 0.1, y, z + tilt],
                    [x + 0.1, y + 0.1, z],
                    [x, y + 0.1, z - tilt],
                ]));
            }
        }
        let bvh = Bvh::occluders(&quads);
        let memo = HullMemo::new();
        let tree = Occluders::all(&bvh);
        let piece = |surface: usize, q: usize| {
            let (s, t) = ((q % 4) as f64 / 4.0, (q / 4) as f64 / 4.0);
            Piece {
                upper: false,
                surface,
                s: [s, s + 0.25],
                t: [t, t + 0.25],
            }
        };
        let mut pairs = vec![(Piece::whole(0), Piece::whole(1))];
        pairs.extend((0..16).flat_map(|a| (0..16).map(move |b| (piece(0, a), piece(1, b)))));
        let (mut listed, mut walked, mut clear) = (0, 0, 0);
        for (k, &(a, b)) in pairs.iter().enumerate() {
            let found = occluders(&bvh, &memo, a, b);
            let seed = k as u64;
            let through = |o: &Occluders| visible_fraction_over(o, a, None, b, 8, seed, &mut 0);
            let (v, w) = (through(&found), through(&tree));
            assert_eq!(v, w, "pair {k}");
            if found.clear() {
                clear += 1;
                assert_eq!(w.whole, 1.0, "pair {k}");
            } else if found.few.is_some() {
                listed += 1;
            } else {
                walked += 1;
            }
        }
        assert!(
            listed > 100 && walked >= 1,
            "{listed} listed, {walked} walked"
        );
        assert!(clear + listed + walked == pairs.len());
    }

    /// A unit floor under a unit ceiling 1 above it, and a blocker just under the ceiling's
    /// half x < ½.
    fn half_hidden_ceiling() -> [Parallelogram; 3] {
        let floor = square(0.0, 0.0, 1.0, true);
        let ceiling = square(1.0, 0.0, 1.0, false);
        let blocker = Parallelogram::new(&[
            [0.0, 0.0, 0.999],
            [0.0, 1.0, 0.999],
            [0.5, 1.0, 0.999],
            [0.5, 0.0, 0.999],
        ]);
        [floor, ceiling, blocker]
    }

    #[test]
    fn half_a_source_hidden_is_half_of_the_light_by_symmetry() {
        // a unit floor under a unit ceiling, a blocker just under the ceiling's half s < ½:
        // by the mirror symmetry s ↦ 1 − s of the floor, the hidden half carries exactly half
        // of the floor's form factor, V = ½, and mirrored step cells add to 1. The stratified
        // estimate converges to it: over 24 seeds its mean error falls at least threefold
        // from 4 × 4 to 16 × 16 points, and stays within 0.02 at 16 × 16
        let quads = half_hidden_ceiling();
        let bvh = Bvh::new(&quads);
        let (a, b) = (Piece::whole(0), Piece::whole(1));
        let mut rays = 0;
        let mean_error = |n: usize, rays: &mut u64| {
            (0..24)
                .map(|seed| (visible_fraction(&bvh, a, b, n, seed, rays).whole - 0.5).abs())
                .sum::<f64>()
                / 24.0
        };
        let (coarse, fine) = (mean_error(4, &mut rays), mean_error(16, &mut rays));
        assert!(fine < 0.02 && fine * 3.0 < coarse, "{coarse} {fine}");
        assert_eq!(rays, 24 * (16 + 256));
        // the cells over the hidden half see less of the ceiling (16 rays each: noisy one by
        // one, about 0.41 on average), and the two halves' means add to 1
        let v = visible_fraction(&bvh, a, b, 16, 5, &mut rays);
        let half = |far: bool| {
            (0..CELLS)
                .filter(|c| (c % STEP >= STEP / 2) == far)
                .map(|c| v.cell(c))
                .sum::<f64>()
                / (CELLS / 2) as f64
        };
        let (near, far) = (half(false), half(true));
        assert!(near < 0.45 && far > 0.55, "{near} {far}");
        assert!((near + far - 1.0).abs() < 0.03, "{near} {far}");
    }

    /// The same floor, ceiling and blocker, the ceiling's hidden half dark (a shadow) and its
    /// open half lit: half of the rays are stopped but none of the light, so the share of the
    /// light is 1 (to the rays that cross the blocker's edge, a 1000th of the way), and with
    /// the hidden half lit and the open half dark it is 0; lit uniformly, it is the share of
    /// the rays, seed for seed.
    #[test]
    fn the_share_of_the_light_weighs_each_ray_by_the_source_where_it_ends() {
        let quads = half_hidden_ceiling();
        let bvh = Bvh::new(&quads);
        let (a, b) = (Piece::whole(0), Piece::whole(1));
        let x = |s: f64, t: f64| quads[1].at(s, t)[0];
        let open = |s: f64, t: f64| if x(s, t) >= 0.5 { 1.0 } else { 1e-300 };
        let hidden = |s: f64, t: f64| if x(s, t) < 0.5 { 1.0 } else { 1e-300 };
        let all = Occluders::all(&bvh);
        let mut rays = 0;
        for seed in 0..8 {
            let lit = visible_share_of_light(&all, a, None, b, 16, seed, &mut rays, &open, None);
            assert!(lit.whole > 0.99, "{}", lit.whole);
            let dark = visible_share_of_light(&all, a, None, b, 16, seed, &mut rays, &hidden, None);
            assert!(dark.whole < 0.01, "{}", dark.whole);
            let uniform =
                visible_share_of_light(&all, a, None, b, 16, seed, &mut rays, &|_, _| 2.0, None);
            let plain = visible_fraction(&bvh, a, b, 16, seed, &mut rays);
            assert!((uniform.whole - plain.whole).abs() < 1e-12);
        }
    }

    /// A small receiver 1 under the middle of a unit source whose light is all in its middle
    /// quarter (1 there, 0 elsewhere): the polynomial of order 1 that a link carries is the
    /// light's mean, ¼, flat, and the kernel, which peaks in the middle, gathers more of
    /// the light than of its mean. The ratio of the rays (16 × 16, eight seeds) is that of
    /// the two transfers by quadrature (the point kernel, 10 × 10 points of the receiver
    /// against 120 × 120 of the source) within 2 %, and each seed's within 5 %; about 1.22,
    /// so a link that carries the polynomial alone gathers 18 % too little. Without a
    /// polynomial there is no ratio.
    #[test]
    fn the_ratio_of_the_light_to_the_polynomial_is_that_of_their_transfers() {
        let quads = [square(0.0, 0.4, 0.6, true), square(1.0, 0.0, 1.0, false)];
        let bvh = Bvh::new(&quads);
        let (a, b) = (Piece::whole(0), Piece::whole(1));
        let middle = |p: V3| (p[0] - 0.5).abs() < 0.25 && (p[1] - 0.5).abs() < 0.25;
        let light = |s: f64, t: f64| if middle(quads[1].at(s, t)) { 1.0 } else { 0.0 };
        let flat = |_: f64, _: f64| 0.25;
        let (mut lit, mut spread) = (0.0, 0.0);
        for i in 0..10 {
            for j in 0..10 {
                let x = quads[0].at((i as f64 + 0.5) / 10.0, (j as f64 + 0.5) / 10.0);
                for u in 0..120 {
                    for v in 0..120 {
                        let y = quads[1].at((u as f64 + 0.5) / 120.0, (v as f64 + 0.5) / 120.0);
                        let d = sub(y, x);
                        let r2 = dot(d, d);
                        let k = dot(d, quads[0].n) * -dot(d, quads[1].n) / (r2 * r2);
                        lit += k * if middle(y) { 1.0 } else { 0.0 };
                        spread += k * 0.25;
                    }
                }
            }
        }
        let exact = lit / spread;
        assert!(exact > 1.15, "{exact}");
        let all = Occluders::all(&bvh);
        let mut rays = 0;
        let mut mean = 0.0;
        for seed in 0..8 {
            let seen =
                visible_share_of_light(&all, a, None, b, 16, seed, &mut rays, &light, Some(&flat));
            assert_eq!(seen.whole, 1.0);
            let ratio = f64::from(seen.detail);
            assert!((ratio / exact - 1.0).abs() < 0.05, "{ratio} {exact}");
            mean += ratio / 8.0;
            let alone = visible_share_of_light(&all, a, None, b, 16, seed, &mut rays, &light, None);
            assert_eq!(alone.detail, 1.0);
        }
        assert!((mean / exact - 1.0).abs() < 0.02, "{mean} {exact}");
    }

    #[test]
    fn pairs_nothing_can_come_between_cast_no_rays() {
        use crate::scene::parse_value;
        // a floor, a ceiling over it and a blocker beside them, outside the hull of every
        // floor–ceiling pair: no rays; moved between them: rays
        let doc = |x: f64| {
            serde_json::json!({ "scene": { "kind": "3d", "surfaces": [
                { "name": "floor", "corners": [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], "reflectance": 0.5 },
                { "name": "ceiling", "corners": [[0, 0, 1], [0, 1, 1], [1, 1, 1], [1, 0, 1]], "reflectance": 0.5, "emission": 1 },
                { "name": "blocker", "corners": [[x, 0.3, 0.5], [x + 0.3, 0.3, 0.5], [x + 0.3, 0.6, 0.5], [x, 0.6, 0.5]], "reflectance": 0.5 }
            ]}})
        };
        for (x, cast) in [(2.0, false), (0.3, true)] {
            let job = parse_value(&doc(x), &crate::scene::Limits::default()).expect("valid");
            let crate::scene::SceneKind::ThreeD(quads) = &job.scene.kind else {
                unreachable!()
            };
            let geo = crate::three_d::projection::Geometry::new(quads);
            let mut rays = 0;
            let v = geo.visibility(Piece::whole(0), Piece::whole(1), 1, 8, &mut rays);
            assert_eq!(rays > 0, cast, "x = {x}: {rays} rays");
            assert_eq!(v.whole == 1.0, !cast, "x = {x}: {v:?}");
        }
    }

    #[test]
    fn step_grams_are_exact_and_sum_to_the_identity() {
        for k in 1..=4 {
            let q = Steps::new(k);
            let kk = k * k;
            for a in 0..kk {
                for c in 0..kk {
                    let sum: f64 = q.m.iter().map(|m| m[a * kk + c]).sum();
                    let want = if a == c { 1.0 } else { 0.0 };
                    assert!((sum - want).abs() < 1e-13, "k {k} ({a}, {c}): {sum}");
                }
            }
        }
        // k = 2 on the quarter [0, ½]² (the cells i, j < 2): (∫₀^½ φ_p φ_q)_pq =
        // [[½, −√3/4], [−√3/4, ½]] in each direction, and the Gram matrix is their tensor
        // product; on the cell [0, ¼]², (∫₀^¼ φ_p φ_q)_pq = [[¼, −3√3/16], [−3√3/16, 7/16]]
        let q = Steps::new(2);
        let r3 = (3f64).sqrt();
        let h = [[0.5, -r3 / 4.0], [-r3 / 4.0, 0.5]];
        let c = [[0.25, -3.0 * r3 / 16.0], [-3.0 * r3 / 16.0, 7.0 / 16.0]];
        for a in 0..4 {
            for d in 0..4 {
                let quarter: f64 = [0, 1, STEP, STEP + 1]
                    .iter()
                    .map(|&i| q.m[i][a * 4 + d])
                    .sum();
                let want = h[a / 2][d / 2] * h[a % 2][d % 2];
                assert!((quarter - want).abs() < 1e-15);
                let want = c[a / 2][d / 2] * c[a % 2][d % 2];
                assert!((q.m[0][a * 4 + d] - want).abs() < 1e-15);
            }
        }
    }

    #[test]
    fn a_step_of_visibility_projects_onto_the_receiver() {
        // a block that delivers a constant 1 to the receiver (first column e₀), seen on the
        // half ŝ < ½ only: the receiver gets the projection of that step, ½ − (√3/4) φ₁(ŝ)
        let k = 2;
        let mut block = vec![0.0; 16];
        block[0] = 1.0;
        let seen = Seen::new(
            0.5,
            std::array::from_fn(|c| if c % STEP < STEP / 2 { 1.0 } else { 0.0 }),
            false,
        );
        seen.weigh(&Steps::new(k), &mut block);
        let column: Vec<f64> = (0..4).map(|a| block[a * 4]).collect();
        let want = [0.5, -(3f64).sqrt() / 4.0, 0.0, 0.0];
        for (g, w) in column.iter().zip(want) {
            assert!((g - w).abs() < 1e-15, "{column:?}");
        }
        // seen on the first quarter of ŝ only: ∫₀^¼ φ₀ = ¼, ∫₀^¼ φ₁ = √3 (¼² ·2 − ¼) = −3√3/16
        let mut block = vec![0.0; 16];
        block[0] = 1.0;
        Seen::new(
            0.25,
            std::array::from_fn(|c| if c % STEP == 0 { 1.0 } else { 0.0 }),
            false,
        )
        .weigh(&Steps::new(k), &mut block);
        let column: Vec<f64> = (0..4).map(|a| block[a * 4]).collect();
        let want = [0.25, -3.0 * (3f64).sqrt() / 16.0, 0.0, 0.0];
        for (g, w) in column.iter().zip(want) {
            assert!((g - w).abs() < 1e-15, "{column:?}");
        }
        // equal cells scale the block
        let mut block = vec![2.0; 16];
        Seen::new(0.25, [0.25; CELLS], false).weigh(&Steps::new(k), &mut block);
        assert!(block.iter().all(|&x| x == 0.5));
    }

    /// `floor` (on z = 0, over x and y from 0 to 1), a light over it at z = 1, and between
    /// them at z = 0.3 a blocker over the part x < ½.
    fn under_a_half_blocked_light(floor: Parallelogram) -> [Parallelogram; 3] {
        let light = square(1.0, 0.0, 1.0, false);
        let blocker = Parallelogram::new(&[
            [-0.5, -0.5, 0.3],
            [0.5, -0.5, 0.3],
            [0.5, 1.5, 0.3],
            [-0.5, 1.5, 0.3],
        ]);
        [floor, light, blocker]
    }

    #[test]
    fn quarters_see_a_shadow_edge_across_the_receiver() {
        // a floor under a light, with a blocker over the floor's half s < ½ only: the quarters
        // on that side see less of the light than the others
        let floor = square(0.0, 0.0, 1.0, true);
        let quads = under_a_half_blocked_light(floor);
        let bvh = Bvh::new(&quads);
        let mut rays = 0;
        let v = visible_fraction(&bvh, Piece::whole(0), Piece::whole(1), 16, 3, &mut rays);
        let [q0, q1, q2, q3] = v.quarters();
        assert!(q0 < 0.5 * q1 && q2 < 0.5 * q3, "{v:?}");
        assert!(q0 < v.whole && v.whole < q1, "{v:?}");
        // with four points in each step cell, each cell has its own fraction: the light
        // falls on the floor from above the blocker's edge at s = ½ at slants up to 45°, so
        // the shadow deepens away from the edge, cell by cell
        let row: Vec<f64> = (0..STEP).map(|i| v.cell(i + STEP)).collect();
        assert!(
            row[0] < row[1] && row[1] < row[2] && row[2] <= row[3],
            "{row:?}"
        );
        // with two points per cell, one value per quarter
        let v = visible_fraction(&bvh, Piece::whole(0), Piece::whole(1), 4, 3, &mut rays);
        assert_eq!(v.cell(0), v.cell(STEP + 1));
        // the missing quarters of a receiver behind the source on one side are extended
        let known = [Some(0.2), Some(0.6), None, Some(0.8)];
        assert!((extend(&known, 2, 0.5, false) - 0.4).abs() < 1e-15);
        assert_eq!(extend(&[Some(0.2), None, None, None], 3, 0.5, false), 0.2);
        assert_eq!(extend(&[None; 4], 0, 0.5, false), 0.5);
        // a triangle's children do not lie in rows: the mean of those known
        assert!((extend(&known, 2, 0.5, true) - 1.6 / 3.0).abs() < 1e-15);
    }

    /// A triangle receiver keeps a step of its visible fraction over the sixteen cells of
    /// two midpoint splits, as a parallelogram does over its grid: the floor's triangle
    /// (0, 0), (1, 0), (0, 1) under a light, with a blocker over the part x < ½ only (its
    /// children 0 and 2 lie there, 1 beyond it; the centre child 3 straddles the edge).
    #[test]
    fn a_triangle_receiver_sees_a_shadow_edge_across_it() {
        let mut floor = square(0.0, 0.0, 1.0, true);
        floor.tri = true;
        floor.area *= 0.5;
        let quads = under_a_half_blocked_light(floor);
        let bvh = Bvh::new(&quads);
        let mut rays = 0;
        let v = visible_fraction(&bvh, Piece::whole(0), Piece::whole(1), 16, 3, &mut rays);
        assert!(v.tri);
        let [q0, q1, q2, q3] = v.quarters();
        assert!(q0 < 0.5 * q1 && q2 < 0.5 * q1, "{v:?}");
        assert!(q0 < q3 && q3 < q1, "{v:?}");
        assert!(q0 < v.whole && v.whole < q1, "{v:?}");
        // the cells of child 1, at x from ½ to 1: its corner cell (x > ¾) sees more than the
        // cell at its corner x = ½
        assert!(v.cell(4) < v.cell(4 + 1), "{v:?}");
        // with one point per cell, one value per child
        let v = visible_fraction(&bvh, Piece::whole(0), Piece::whole(1), 4, 3, &mut rays);
        assert!((0..4).all(|c| v.cell(4 + c) == v.cell(4)), "{v:?}");
    }

    /// A step on a triangle weighs a block by the triangle basis' Gram matrices of its
    /// cells: a block delivering a constant 1, seen everywhere but on the corner child 0,
    /// delivers 1 minus the indicator of that child, projected: its mean ¾, and its linear
    /// part −¼ φ_j at the child's centroid (⅙, ⅙) (the mean of a linear function over a
    /// triangle is its value at the centroid).
    #[test]
    fn a_step_on_a_triangle_projects_onto_its_basis() {
        let k = 2;
        let mut block = vec![0.0; 16];
        block[0] = 1.0;
        let seen = Seen::new(
            0.75,
            std::array::from_fn(|c| if c < 4 { 0.0 } else { 1.0 }),
            true,
        );
        seen.weigh(&Steps::new(k), &mut block);
        let mut phi = [0.0; 3];
        crate::math::triangle::TriangleBasis::of_order(1).eval(1.0 / 6.0, 1.0 / 6.0, &mut phi);
        let want = [1.0 - 0.25 * phi[0], -0.25 * phi[1], -0.25 * phi[2], 0.0];
        let column: Vec<f64> = (0..4).map(|a| block[a * 4]).collect();
        for (g, w) in column.iter().zip(want) {
            assert!((g - w).abs() < 1e-14, "{column:?} {want:?}");
        }
    }
}
