//! The visibility term V(x, y) of the slides' eq. (3) between two pieces of parallelograms.
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

use crate::bvh::Bvh;
use crate::space::{cross, dot, norm, sub, Parallelogram, V3};

/// A piece `[s0,s1] × [t0,t1]` of surface `surface`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Piece {
    pub surface: usize,
    pub s: [f64; 2],
    pub t: [f64; 2],
}

impl Piece {
    pub fn whole(surface: usize) -> Piece {
        Piece {
            surface,
            s: [0.0, 1.0],
            t: [0.0, 1.0],
        }
    }
    pub fn corners(&self, quads: &[Parallelogram]) -> [V3; 4] {
        quads[self.surface].piece(self.s, self.t)
    }
}

/// Whether the parallelogram `q` may meet the convex hull of `points` (conservative). With
/// `thorough`, every candidate axis of the hull is tried (its edges and faces through any of
/// the points); without, only the axes that are cheap and decide most pairs of a room: `q`'s
/// normal, the coordinate axes, the normals of the two pieces and the cross products of their
/// edges with `q`'s. The per-element test runs for every link, where a dozen rays cost less
/// than the ~100 axes of the thorough test; the per-surface test runs once.
pub fn may_occlude(points: &[V3; 8], thorough: bool, q: &Parallelogram) -> bool {
    let qc = q.piece([0.0, 1.0], [0.0, 1.0]);
    // the tolerance's scale: q's size plus the points' bounding box
    let (mut lo, mut hi) = (points[0], points[0]);
    for p in &points[1..] {
        for i in 0..3 {
            lo[i] = lo[i].min(p[i]);
            hi[i] = hi[i].max(p[i]);
        }
    }
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

/// The surfaces that may occlude some ray between pieces `a` and `b`, out of `candidates`
/// (see [`may_occlude`] for `thorough`).
pub fn occluders_of(
    quads: &[Parallelogram],
    a: Piece,
    b: Piece,
    candidates: &[usize],
    thorough: bool,
) -> Vec<usize> {
    let ca = a.corners(quads);
    let cb = b.corners(quads);
    let pts = [ca[0], ca[1], ca[2], ca[3], cb[0], cb[1], cb[2], cb[3]];
    candidates
        .iter()
        .copied()
        .filter(|&k| k != a.surface && k != b.surface && may_occlude(&pts, thorough, &quads[k]))
        .collect()
}

/// Whether any of `candidates` (other than the pieces' own surfaces) may occlude some ray
/// between pieces `a` and `b`: the quick test of [`may_occlude`], stopping at the first.
pub fn any_occluder(quads: &[Parallelogram], a: Piece, b: Piece, candidates: &[usize]) -> bool {
    let ca = a.corners(quads);
    let cb = b.corners(quads);
    let pts = [ca[0], ca[1], ca[2], ca[3], cb[0], cb[1], cb[2], cb[3]];
    candidates
        .iter()
        .any(|&k| k != a.surface && k != b.surface && may_occlude(&pts, false, &quads[k]))
}

/// For every ordered pair of surfaces (row-major `S × S`), the surfaces that may occlude it.
pub fn surface_occluders(quads: &[Parallelogram]) -> Vec<Vec<usize>> {
    let n = quads.len();
    let all: Vec<usize> = (0..n).collect();
    let mut out = vec![Vec::new(); n * n];
    for i in 0..n {
        for j in i + 1..n {
            let o = occluders_of(quads, Piece::whole(i), Piece::whole(j), &all, true);
            out[j * n + i] = o.clone();
            out[i * n + j] = o;
        }
    }
    out
}

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

/// A seed from two element identities (order matters: the pair is directed).
pub fn pair_seed(a: u64, b: u64) -> u64 {
    let mut r = SplitMix(a.wrapping_mul(0x100_0000_01B3) ^ b.rotate_left(32));
    r.next_u64()
}

/// The visible fraction of the transfer between `a` and `b`: over a stratified `n × n` set of
/// point pairs, Σ w V / Σ w with w the point-to-disc kernel cosθa cosθb / (π r² + A) (A the
/// smaller piece's area, which keeps the weight finite for touching pieces). Pairs that do not
/// face each other carry no weight and cast no ray: counting them would make a block's
/// back-facing part, which a ray through the block itself always finds occluded, darken its
/// front. Returns 0 when no pair faces; the number of rays cast is added to `rays`.
pub fn visible_fraction(bvh: &Bvh, a: Piece, b: Piece, n: usize, seed: u64, rays: &mut u64) -> f64 {
    let quads = bvh.quads();
    let (qa, qb) = (&quads[a.surface], &quads[b.surface]);
    let area = |p: &Piece, q: &Parallelogram| q.area * (p.s[1] - p.s[0]) * (p.t[1] - p.t[0]);
    let disc = area(&a, qa).min(area(&b, qb)) / std::f64::consts::PI;
    let mut rng = SplitMix(seed);
    let m = n * n;
    let mut perm: Vec<usize> = (0..m).collect();
    for i in (1..m).rev() {
        let j = (rng.next_u64() % (i as u64 + 1)) as usize;
        perm.swap(i, j);
    }
    let (mut seen, mut total) = (0.0, 0.0);
    let cell = 1.0 / n as f64;
    for (i, &j) in perm.iter().enumerate() {
        let (ia, ja) = (i % n, i / n);
        let (ib, jb) = (j % n, j / n);
        let sa = a.s[0] + (a.s[1] - a.s[0]) * (ia as f64 + rng.next_f64()) * cell;
        let ta = a.t[0] + (a.t[1] - a.t[0]) * (ja as f64 + rng.next_f64()) * cell;
        let sb = b.s[0] + (b.s[1] - b.s[0]) * (ib as f64 + rng.next_f64()) * cell;
        let tb = b.t[0] + (b.t[1] - b.t[0]) * (jb as f64 + rng.next_f64()) * cell;
        let (x, y) = (qa.at(sa, ta), qb.at(sb, tb));
        let d = sub(y, x);
        let (ca, cb) = (dot(d, qa.n), -dot(d, qb.n));
        if ca <= 0.0 || cb <= 0.0 {
            continue;
        }
        let r2 = dot(d, d);
        let w = ca * cb / (r2 * (r2 + disc));
        total += w;
        *rays += 1;
        if !bvh.occluded(x, y, [a.surface, b.surface]) {
            seen += w;
        }
    }
    if total > 0.0 {
        seen / total
    } else {
        0.0
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
        let occ = surface_occluders(&quads);
        assert_eq!(occ[1], vec![2]);
        let bvh = Bvh::new(&quads);
        let mut rays = 0;
        let v = visible_fraction(&bvh, Piece::whole(0), Piece::whole(1), 8, 7, &mut rays);
        assert_eq!(rays, 64);
        assert!(v > 0.5 && v < 1.0, "{v}");
        // same seed, same answer
        let w = visible_fraction(&bvh, Piece::whole(0), Piece::whole(1), 8, 7, &mut rays);
        assert_eq!(v, w);
        // a piece under the blocker sees nothing of the piece above it
        let a = Piece {
            surface: 0,
            s: [0.4, 0.5],
            t: [0.4, 0.5],
        };
        let b = Piece {
            surface: 1,
            s: [0.4, 0.5],
            t: [0.5, 0.6],
        };
        assert_eq!(visible_fraction(&bvh, a, b, 4, 1, &mut rays), 0.0);
    }
}
