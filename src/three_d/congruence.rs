//! Congruent pairs of pieces, and how their Galerkin blocks map onto each other.
//!
//! The transfer of eq. (11) between two pieces (the slides' Galerkin entries with the kernel of
//! eq. (3), as [`crate::three_d::transfer`] integrates them) depends only on distances and angles, since
//! K = cosθx cosθy / (π r²), and on how each piece is labelled by its parameters (ŝ, t̂) ∈ [0,1]²:
//! the basis is N_qr = φ_r(ŝ) φ_q(t̂) / √A. So two pairs related by an isometry of space
//! (translation, rotation or reflection) once each piece is relabelled by one of the eight
//! symmetries of the square have the same block in those labels. In the old labels the blocks
//! differ by a signed permutation: swapping ŝ and t̂ swaps q and r, and φ_p(1 − x) = (−1)^p φ_p(x)
//! (the shifted Legendre polynomials are even or odd about ½) makes a flip change the sign of
//! the odd functions. The quadtrees of a room repeat a few shapes at every level, most of them
//! mirrored or turned copies of each other (floor to left wall and floor to right wall, a
//! piece and its reverse): one block per class is integrated and the rest are mapped.
//!
//! The class of a pair is named by a key of integers: the first piece's shape and the other's
//! centroid, then the other's corner and edges and normal, all in a frame of the first piece
//! (its centroid; its first edge, the second made orthogonal to it, and its front normal) and
//! rounded to a grid (2⁻³² of the scene, the caller's `unit`). Of the labellings of both pieces
//! (and of both orders, when the pair is not directed) the smallest key names the class.

use crate::three_d::geometry::Piece;
use crate::three_d::geometry::{dot, norm, scale, sub, Parallelogram, V3};

/// One of the eight symmetries of a piece's unit square of parameters, as a new labelling:
/// the old ŝ replaced by 1 − ŝ (`flip_s`), t̂ by 1 − t̂ (`flip_t`), then the two exchanged
/// (`swap`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Relabel {
    swap: bool,
    flip_s: bool,
    flip_t: bool,
}

impl Relabel {
    /// The flips (ŝ, t̂) that put the origin at each corner, in the order of
    /// [`Parallelogram::piece`]: (0,0), (1,0), (1,1), (0,1).
    const ORIGIN_FLIPS: [(bool, bool); 4] =
        [(false, false), (true, false), (true, true), (false, true)];

    /// The labelling with its origin at `corner`, with or without the swap.
    fn from_corner(corner: usize, swap: bool) -> Relabel {
        let (flip_s, flip_t) = Relabel::ORIGIN_FLIPS[corner];
        Relabel {
            swap,
            flip_s,
            flip_t,
        }
    }

    /// Which corners of a piece (in the order of [`Parallelogram::piece`]) are the origin and
    /// the ends of the first and second edge in the new labels.
    fn corners(self) -> [usize; 3] {
        let origin = Relabel::ORIGIN_FLIPS
            .iter()
            .position(|&f| f == (self.flip_s, self.flip_t))
            .expect("four corners for four pairs of flips");
        // the corner across the old ŝ edge and across the old t̂ edge from the origin
        let across_s = [1, 0, 3, 2][origin];
        let across_t = [3, 2, 1, 0][origin];
        if self.swap {
            [origin, across_t, across_s]
        } else {
            [origin, across_s, across_t]
        }
    }

    /// Basis function `i = q·k + r` of the new labels (q the degree in the new t̂, r in the
    /// new ŝ) as (index, sign) of the old ones: N'_i = sign · N_index.
    fn map(self, i: usize, k: usize) -> (usize, f64) {
        let (q, r) = (i / k, i % k);
        // the flips of the new ŝ and t̂
        let (fs, ft) = if self.swap {
            (self.flip_t, self.flip_s)
        } else {
            (self.flip_s, self.flip_t)
        };
        let odd = (fs && r % 2 == 1) != (ft && q % 2 == 1);
        let index = if self.swap { r * k + q } else { i };
        (index, if odd { -1.0 } else { 1.0 })
    }
}

/// Entries of a class key: 6 of the coarse part, 12 of the fine.
type Key = [i64; 18];

/// A pair's class and how its labels map to the class's.
#[derive(Debug, Clone, Copy)]
pub(super) struct Congruence {
    pub(super) key: Key,
    pub(super) labels: Labels,
}

/// How a pair's labels map to its class's: what a link needs of its class once the class's
/// block is known (a few bytes, where the key is 144).
#[derive(Debug, Clone, Copy)]
pub(super) struct Labels {
    /// The class's first piece is the pair's second.
    reverse: bool,
    /// Relabellings of the class's first and second piece.
    first: Relabel,
    second: Relabel,
}

impl Congruence {
    /// The class of the pair (a, b). `directed`: only that order (for what is not symmetric
    /// in the two pieces, like the oracle's estimate); else (b, a) too, whose block is the
    /// transpose.
    pub(super) fn of(
        quads: &[Parallelogram],
        a: Piece,
        b: Piece,
        unit: f64,
        directed: bool,
    ) -> Self {
        if quads[a.surface].tri || quads[b.surface].tri {
            return Congruence::alone(a, b);
        }
        let (ca, cb) = (a.corners(quads), b.corners(quads));
        let (na, nb) = (quads[a.surface].n, quads[b.surface].n);
        let ab = ordered((&ca, na), (&cb, nb), unit);
        let best = if directed {
            (ab, false)
        } else {
            let ba = ordered((&cb, nb), (&ca, na), unit);
            if ba.0 < ab.0 {
                (ba, true)
            } else {
                (ab, false)
            }
        };
        let ((key, first, second), reverse) = best;
        Congruence {
            key,
            labels: Labels {
                reverse,
                first,
                second,
            },
        }
    }

    /// A class of its own for a pair with a triangle piece: the symmetries above are those of
    /// the square, not the triangle's, so such a pair shares its block with no other.
    fn alone(a: Piece, b: Piece) -> Self {
        let id = |p: Piece| {
            [
                p.surface as i64,
                p.s[0].to_bits() as i64,
                p.t[0].to_bits() as i64,
                p.s[1].to_bits() as i64,
                i64::from(p.upper),
            ]
        };
        let mut key = [0; 18];
        key[0] = i64::MIN;
        key[1..6].copy_from_slice(&id(a));
        key[6..11].copy_from_slice(&id(b));
        let same = Relabel {
            swap: false,
            flip_s: false,
            flip_t: false,
        };
        Congruence {
            key,
            labels: Labels {
                reverse: false,
                first: same,
                second: same,
            },
        }
    }
}

impl Labels {
    /// For every entry of a k² × k² block in the class's labels, the pair's entry (row =
    /// a's function, column = b's) and the sign between them.
    fn entries(&self, k: usize) -> impl Iterator<Item = (usize, usize, f64)> + '_ {
        let kk = k * k;
        (0..kk * kk).map(move |c| {
            let (pi, si) = self.first.map(c / kk, k);
            let (pj, sj) = self.second.map(c % kk, k);
            let own = if self.reverse {
                pj * kk + pi
            } else {
                pi * kk + pj
            };
            (c, own, si * sj)
        })
    }

    /// A block of this pair (row = a's function, column = b's) in the class's labels.
    #[allow(clippy::wrong_self_convention)] // names of the direction, not conversions of `self`
    pub(super) fn to_class(&self, block: &[f64], k: usize) -> Vec<f64> {
        let mut out = vec![0.0; block.len()];
        for (c, own, sign) in self.entries(k) {
            out[c] = sign * block[own];
        }
        out
    }

    /// The class's block in this pair's labels.
    #[cfg(test)]
    #[allow(clippy::wrong_self_convention)]
    pub(super) fn from_class(&self, class: &[f64], k: usize) -> Vec<f64> {
        let mut out = vec![0.0; class.len()];
        self.from_class_into(class, k, &mut out);
        out
    }

    /// The class's block in this pair's labels, into `out` (zero where no entry maps).
    #[allow(clippy::wrong_self_convention)]
    pub(super) fn from_class_into(&self, class: &[f64], k: usize, out: &mut [f64]) {
        out.iter_mut().for_each(|x| *x = 0.0);
        for (c, own, sign) in self.entries(k) {
            out[own] = sign * class[c];
        }
    }
}

/// The smallest key of the ordered pair (x, y) over the labellings of both, with them.
fn ordered(
    (cx, n): (&[V3; 4], V3),
    (cy, ny): (&[V3; 4], V3),
    unit: f64,
) -> (Key, Relabel, Relabel) {
    let mid = |c: &[V3; 4]| scale(crate::three_d::geometry::add(c[0], c[2]), 0.5);
    let (mx, my) = (mid(cx), mid(cy));
    let d = sub(my, mx);
    // truncation toward zero: one instruction (round() is a library call here), and odd like
    // round, which the negations of the coarse part rely on
    let per_unit = 1.0 / unit;
    let len = |v: f64| (v * per_unit) as i64;
    // the coarse part for the labellings that keep or swap x's edges, before flips; a flip of
    // the new ŝ negates e1, of the new t̂ negates e2 (the second edge made orthogonal to e1)
    let (u0, v0) = (sub(cx[1], cx[0]), sub(cx[3], cx[0]));
    let mut best_coarse = [i64::MAX; 6];
    let mut ties: smallvec::SmallVec<[(Relabel, V3, V3); 8]> = smallvec::SmallVec::new();
    for swap in [false, true] {
        let (u, v) = if swap { (v0, u0) } else { (u0, v0) };
        let e1 = scale(u, 1.0 / norm(u));
        let w = sub(v, scale(e1, dot(v, e1)));
        let e2 = scale(w, 1.0 / norm(w));
        let (lu, ve1, ve2) = (len(norm(u)), len(dot(v, e1)), len(dot(v, e2)));
        let (d1, d2, dn) = (len(dot(d, e1)), len(dot(d, e2)), len(dot(d, n)));
        for (fa, fb) in [(false, false), (true, false), (false, true), (true, true)] {
            let neg = |f: bool, x: i64| if f { -x } else { x };
            let coarse = [lu, neg(fa != fb, ve1), ve2, neg(fa, d1), neg(fb, d2), dn];
            let relabel = Relabel {
                swap,
                flip_s: if swap { fb } else { fa },
                flip_t: if swap { fa } else { fb },
            };
            let frame = (
                relabel,
                if fa { scale(e1, -1.0) } else { e1 },
                if fb { scale(e2, -1.0) } else { e2 },
            );
            if coarse < best_coarse {
                best_coarse = coarse;
                ties.clear();
            }
            if coarse == best_coarse {
                ties.push(frame);
            }
        }
    }
    let unit_vector = |v: f64| (v * 2f64.powi(32)) as i64;
    let mut best: Option<(Key, Relabel, Relabel)> = None;
    for &(rx, e1, e2) in &ties {
        let coords = |v: V3| [dot(v, e1), dot(v, e2), dot(v, n)];
        // y's corners on the grid once; each labelling of y picks its origin and edges
        // from them
        let corners = cy.map(|c| coords(sub(c, mx)).map(len));
        let normal = coords(ny).map(unit_vector);
        // the key's fine part starts with the origin: the labellings of y that start at its
        // smallest corner (two: with or without the swap) are the only candidates
        let origin = (1..4).fold(0, |m, i| if corners[i] < corners[m] { i } else { m });
        for swap in [false, true] {
            let ry = Relabel::from_corner(origin, swap);
            let [o, a, b] = ry.corners().map(|i| corners[i]);
            let mut key = [0; 18];
            key[..6].copy_from_slice(&best_coarse);
            for i in 0..3 {
                key[6 + i] = o[i];
                key[9 + i] = a[i] - o[i];
                key[12 + i] = b[i] - o[i];
            }
            key[15..].copy_from_slice(&normal);
            if best.as_ref().is_none_or(|b| key < b.0) {
                best = Some((key, rx, ry));
            }
        }
    }
    best.expect("eight labellings of y for each tie")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::three_d::geometry::{add, cross};
    use crate::three_d::transfer::{block, Accuracy, Integrand};
    use rand::{rngs::SmallRng, Rng, SeedableRng};

    /// Every labelling.
    const ALL: [Relabel; 8] = {
        let mut all = [Relabel {
            swap: false,
            flip_s: false,
            flip_t: false,
        }; 8];
        let mut i = 0;
        while i < 8 {
            all[i] = Relabel {
                swap: i & 4 != 0,
                flip_s: i & 1 != 0,
                flip_t: i & 2 != 0,
            };
            i += 1;
        }
        all
    };

    /// The origin and the two edge vectors of a piece with corners `c` in the labels `r`.
    fn frame(r: Relabel, c: &[V3; 4]) -> (V3, V3, V3) {
        let [o, a, b] = r.corners();
        (c[o], sub(c[a], c[o]), sub(c[b], c[o]))
    }

    /// A parallelogram from its corners with the given front normal (a relabelling or a
    /// reflection reverses the corners' turn, not the side that faces the scene).
    fn with_normal(c: [V3; 4], n: V3) -> Parallelogram {
        Parallelogram {
            n,
            ..Parallelogram::new(&c)
        }
    }

    /// The same piece labelled by `r`: a surface whose corners are the old ones in the new
    /// order, and the piece's parameter ranges mapped accordingly.
    fn relabelled(
        q: &Parallelogram,
        p: Piece,
        r: Relabel,
        surface: usize,
    ) -> (Parallelogram, Piece) {
        let (o, u, v) = frame(r, &q.piece([0.0, 1.0], [0.0, 1.0]));
        let new = with_normal([o, add(o, u), add(add(o, u), v), add(o, v)], q.n);
        let flip = |x: [f64; 2], f: bool| if f { [1.0 - x[1], 1.0 - x[0]] } else { x };
        let (s, t) = (flip(p.s, r.flip_s), flip(p.t, r.flip_t));
        let (s, t) = if r.swap { (t, s) } else { (s, t) };
        (
            new,
            Piece {
                upper: false,
                surface,
                s,
                t,
            },
        )
    }

    fn galerkin(quads: &[Parallelogram], a: Piece, b: Piece, k: usize) -> Vec<f64> {
        let mut out = vec![0.0; k.pow(4)];
        block(
            quads,
            a,
            b,
            Integrand::Galerkin { k },
            Accuracy::fine(k + 2),
            &mut out,
        );
        out
    }

    fn close(x: &[f64], y: &[f64], what: &str) {
        let scale = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(scale > 0.0, "{what}: an empty block tests nothing");
        for (i, (a, b)) in x.iter().zip(y).enumerate() {
            assert!(
                (a - b).abs() < 1e-9 * scale,
                "{what}, entry {i}: {a} vs {b}"
            );
        }
    }

    #[test]
    fn relabelling_maps_the_block_by_signs_and_a_permutation() {
        // a slanted floor piece and a wall piece near it, every labelling of the first and
        // some of the second, orders 0 to 3: the block of the relabelled pair, integrated
        // directly, is the mapped block
        let floor = Parallelogram::new(&[
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [2.5, 1.0, 0.0],
            [0.5, 1.0, 0.0],
        ]);
        let wall = Parallelogram::new(&[
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 1.5],
            [2.0, 0.0, 1.5],
            [2.0, 0.0, 0.0],
        ]);
        let a = Piece {
            upper: false,
            surface: 0,
            s: [0.25, 0.5],
            t: [0.1, 0.5],
        };
        let b = Piece {
            upper: false,
            surface: 1,
            s: [0.1, 0.5],
            t: [0.5, 0.75],
        };
        for k in 1..=4 {
            let t = galerkin(&[floor, wall], a, b, k);
            for ra in ALL {
                for rb in [ALL[0], ALL[5], ALL[6]] {
                    let (fa, pa) = relabelled(&floor, a, ra, 0);
                    let (fb, pb) = relabelled(&wall, b, rb, 1);
                    let direct = galerkin(&[fa, fb], pa, pb, k);
                    let c = Labels {
                        reverse: false,
                        first: ra,
                        second: rb,
                    };
                    let mapped = c.to_class(&t, k);
                    close(&direct, &mapped, &format!("k={k} {ra:?} {rb:?}"));
                    assert_eq!(c.from_class(&mapped, k), t);
                }
            }
        }
    }

    /// A random orthogonal matrix (rows), a reflection half of the time.
    fn orthogonal(rng: &mut SmallRng) -> [V3; 3] {
        let mut v = || {
            [
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            ]
        };
        let a = crate::three_d::geometry::normalize(v());
        let b = crate::three_d::geometry::normalize(cross(a, v()));
        let c = cross(a, b);
        let c = if rng.random_bool(0.5) {
            scale(c, -1.0)
        } else {
            c
        };
        [a, b, c]
    }

    #[test]
    fn moved_mirrored_and_relabelled_pairs_share_a_class_and_map_their_blocks() {
        let mut rng = SmallRng::seed_from_u64(11);
        for case in 0..40 {
            // a random pair of parallelograms facing each other, near or far
            let corner = |rng: &mut SmallRng, lift: f64| {
                let p0 = [
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    lift,
                ];
                let e1 = [
                    rng.random_range(0.5..2.0),
                    rng.random_range(-0.3..0.3),
                    rng.random_range(-0.15..0.15),
                ];
                let e3 = [
                    rng.random_range(-0.3..0.3),
                    rng.random_range(0.5..2.0),
                    rng.random_range(-0.15..0.15),
                ];
                [p0, add(p0, e1), add(add(p0, e1), e3), add(p0, e3)]
            };
            let ca = corner(&mut rng, 0.0);
            let cb = corner(&mut rng, if case % 2 == 0 { 1.0 } else { 3.0 });
            let qa = Parallelogram::new(&ca);
            let qa = with_normal(
                ca,
                if qa.n[2] > 0.0 {
                    qa.n
                } else {
                    scale(qa.n, -1.0)
                },
            );
            let qb = Parallelogram::new(&cb);
            let qb = with_normal(
                cb,
                if qb.n[2] < 0.0 {
                    qb.n
                } else {
                    scale(qb.n, -1.0)
                },
            );
            let range = |rng: &mut SmallRng| {
                let lo: f64 = rng.random_range(0.0..0.6);
                [lo, lo + rng.random_range(0.2..0.4)]
            };
            let a = Piece {
                upper: false,
                surface: 0,
                s: range(&mut rng),
                t: range(&mut rng),
            };
            let b = Piece {
                upper: false,
                surface: 1,
                s: range(&mut rng),
                t: range(&mut rng),
            };
            // the same pair moved by an isometry, relabelled, and maybe in the other order
            let m = orthogonal(&mut rng);
            let shift = [
                rng.random_range(-5.0..5.0),
                rng.random_range(-5.0..5.0),
                1.0,
            ];
            let apply = |p: V3| add([dot(m[0], p), dot(m[1], p), dot(m[2], p)], shift);
            let turn = |v: V3| [dot(m[0], v), dot(m[1], v), dot(m[2], v)];
            let moved = |q: &Parallelogram| {
                with_normal(q.piece([0.0, 1.0], [0.0, 1.0]).map(apply), turn(q.n))
            };
            let (ra, rb) = (ALL[rng.random_range(0..8)], ALL[rng.random_range(0..8)]);
            let (ma, pa) = relabelled(&moved(&qa), a, ra, 0);
            let (mb, pb) = relabelled(&moved(&qb), b, rb, 1);
            let swapped = case % 3 == 0;
            let (there, pa, pb) = if swapped {
                (
                    [mb, ma],
                    Piece { surface: 1, ..pa },
                    Piece { surface: 0, ..pb },
                )
            } else {
                ([ma, mb], pa, pb)
            };
            let here = [qa, qb];
            let unit = 1e-9;
            let c1 = Congruence::of(&here, a, b, unit, false);
            let c2 = Congruence::of(&there, pa, pb, unit, false);
            assert_eq!(c1.key, c2.key, "case {case}");
            if !swapped {
                let d1 = Congruence::of(&here, a, b, unit, true);
                let d2 = Congruence::of(&there, pa, pb, unit, true);
                assert_eq!(d1.key, d2.key, "case {case}, directed");
            }
            for k in [1, 2, 3] {
                let t1 = galerkin(&here, a, b, k);
                let t2 = galerkin(&there, pa, pb, k);
                let mapped = c2.labels.from_class(&c1.labels.to_class(&t1, k), k);
                close(&t2, &mapped, &format!("case {case}, k={k}"));
            }
        }
    }

    #[test]
    fn different_pairs_have_different_keys() {
        // the same two squares at two distances, and one of them turned about its normal
        // by less than a right angle: three classes
        let floor = Parallelogram::new(&[
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ]);
        let top = |z: f64, turn: f64| {
            let (c, s) = (turn.cos(), turn.sin());
            let p = |x: f64, y: f64| {
                [
                    0.5 + c * (x - 0.5) - s * (y - 0.5),
                    0.5 + s * (x - 0.5) + c * (y - 0.5),
                    z,
                ]
            };
            Parallelogram::new(&[p(0.0, 0.0), p(0.0, 1.0), p(1.0, 1.0), p(1.0, 0.0)])
        };
        let key = |q: Parallelogram| {
            Congruence::of(&[floor, q], Piece::whole(0), Piece::whole(1), 1e-9, false).key
        };
        let (k1, k2, k3) = (key(top(1.0, 0.0)), key(top(2.0, 0.0)), key(top(1.0, 0.3)));
        assert!(k1 != k2 && k1 != k3 && k2 != k3);
        // a right angle is a relabelling of a square
        assert_eq!(k1, key(top(1.0, std::f64::consts::FRAC_PI_2)));
    }
}
