//! Points, vectors and parallelograms of 3D scenes (`docs/job-document.md`, kind `3d`):
//! p(s, t) = p0 + s (p1 − p0) + t (p3 − p0), front normal normalize((p1 − p0) × (p3 − p0)),
//! and the distances between pieces of them that the integrators and the visibility tests need.
//! The r and cos θ of the kernel, the slides' eq. (3), are measured with these.

pub(crate) type V3 = [f64; 3];

#[inline(always)]
pub(crate) fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline(always)]
pub(crate) fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
#[inline(always)]
pub(crate) fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
#[inline(always)]
pub(crate) fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline(always)]
pub(crate) fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
#[inline(always)]
pub(crate) fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}

/// The bounding box (least and greatest corner) of the patches `quads`.
pub(crate) fn bounding_box(quads: &[Parallelogram]) -> (V3, V3) {
    box_of(quads.iter().flat_map(|q| q.outline()))
}

/// The smallest axis-aligned box [lo, hi] that holds `points` (lo > hi when there are none).
#[inline]
pub(crate) fn box_of(points: impl IntoIterator<Item = V3>) -> (V3, V3) {
    points.into_iter().fold(
        ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
        |(lo, hi), p| {
            (
                [0, 1, 2].map(|i| lo[i].min(p[i])),
                [0, 1, 2].map(|i| hi[i].max(p[i])),
            )
        },
    )
}

pub(crate) fn normalize(a: V3) -> V3 {
    scale(a, 1.0 / norm(a))
}

/// A symmetric 3 × 3 matrix: xx, yy, zz, xy, xz, yz.
pub(crate) type Sym = [f64; 6];

/// The symmetric matrix a bᵀ + b aᵀ over two, or a aᵀ for a = b.
pub(crate) fn sym(a: V3, b: V3) -> Sym {
    [
        a[0] * b[0],
        a[1] * b[1],
        a[2] * b[2],
        0.5 * (a[0] * b[1] + a[1] * b[0]),
        0.5 * (a[0] * b[2] + a[2] * b[0]),
        0.5 * (a[1] * b[2] + a[2] * b[1]),
    ]
}

pub(crate) fn sym_of(a: V3) -> Sym {
    sym(a, a)
}

pub(crate) fn sym_axpy(a: f64, x: &Sym, y: &Sym) -> Sym {
    [0, 1, 2, 3, 4, 5].map(|i| a * x[i] + y[i])
}

/// The centroid of a parallelogram with corners c₀ … c₃ in order (its diagonal's
/// midpoint), or of a triangle c₀ c₁ c₂ when `triangle`.
pub(crate) fn centroid(c: &[V3; 4], triangle: bool) -> V3 {
    if triangle {
        scale(add(add(c[0], c[1]), c[2]), 1.0 / 3.0)
    } else {
        scale(add(c[0], c[2]), 0.5)
    }
}

/// The covariance about its centroid of a uniform point on a parallelogram with corners
/// c₀ … c₃ in order, (e₁ e₁ᵀ + e₂ e₂ᵀ) / 12, or on a triangle c₀ c₁ c₂, Σ_i v_i v_iᵀ / 12 with
/// v_i the vertices' offsets from the centroid (the barycentric coordinates' variance is
/// 1/18 and their covariance −1/36).
pub(crate) fn covariance(c: &[V3; 4], triangle: bool) -> Sym {
    if triangle {
        let centre = centroid(c, true);
        let mut out = [0.0; 6];
        for v in &c[..3] {
            let o = sub(*v, centre);
            out = sym_axpy(1.0 / 12.0, &sym_of(o), &out);
        }
        out
    } else {
        let (a, b) = (sym_of(sub(c[1], c[0])), sym_of(sub(c[3], c[0])));
        [0, 1, 2, 3, 4, 5].map(|i| (a[i] + b[i]) / 12.0)
    }
}

/// A parallelogram surface with the dual basis that maps a point of its plane back to (s, t);
/// or, with `tri`, the triangle s + t ≤ 1 of the same map (a patch of a triangle or a mesh).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Parallelogram {
    pub(super) p0: V3,
    pub(crate) e1: V3,
    pub(crate) e3: V3,
    /// Unit front normal.
    pub(crate) n: V3,
    /// The area of the surface: the parallelogram's, or the triangle's.
    pub(crate) area: f64,
    /// |e1 × e3|, the area of the parameter square's image: dA = jac ds dt. Twice `area` on a
    /// triangle.
    pub(super) jac: f64,
    pub tri: bool,
    /// s = (p − p0)·u, t = (p − p0)·v for p in the plane.
    pub(super) u: V3,
    pub(super) v: V3,
}

impl Parallelogram {
    pub fn new(corners: &[V3; 4]) -> Parallelogram {
        let p0 = corners[0];
        let e1 = sub(corners[1], p0);
        let e3 = sub(corners[3], p0);
        let c = cross(e1, e3);
        let area = norm(c);
        let n = scale(c, 1.0 / area);
        // dual basis: u ⟂ e3, u·e1 = 1; v ⟂ e1, v·e3 = 1
        let u = cross(e3, n);
        let u = scale(u, 1.0 / dot(u, e1));
        let v = cross(n, e1);
        let v = scale(v, 1.0 / dot(v, e3));
        Parallelogram {
            p0,
            e1,
            e3,
            n,
            area,
            jac: area,
            tri: false,
            u,
            v,
        }
    }

    /// The patch of a scene: a parallelogram, or the triangle (p0, p1, p3) of its corners.
    pub(crate) fn of(q: &crate::scene::Quad) -> Parallelogram {
        let mut p = Parallelogram::new(&q.corners);
        if q.triangle {
            p.tri = true;
            p.area = 0.5 * p.jac;
        }
        p
    }

    /// The corners of the whole surface, counter-clockwise; a triangle's third repeated.
    pub(crate) fn outline(&self) -> [V3; 4] {
        let c = self.piece([0.0, 1.0], [0.0, 1.0]);
        if self.tri {
            [c[0], c[1], c[3], c[3]]
        } else {
            c
        }
    }

    #[inline(always)]
    pub fn at(&self, s: f64, t: f64) -> V3 {
        [
            self.p0[0] + s * self.e1[0] + t * self.e3[0],
            self.p0[1] + s * self.e1[1] + t * self.e3[1],
            self.p0[2] + s * self.e1[2] + t * self.e3[2],
        ]
    }

    /// (s, t) of the projection of p onto the plane.
    #[inline(always)]
    pub(super) fn params(&self, p: V3) -> (f64, f64) {
        let d = sub(p, self.p0);
        (dot(d, self.u), dot(d, self.v))
    }

    /// The point of `piece` (of this patch) at (s, t), moved into the piece to a hundredth of
    /// its size from its edges: along each side of a parallelogram piece, and in the local
    /// coordinates (ŝ, t̂) of a triangle piece, toward its first vertex past its diagonal.
    pub(super) fn at_clamped(&self, piece: &Piece, s: f64, t: f64) -> V3 {
        if self.tri {
            let (u, v) = piece.local(s, t);
            let (u, v) = (u.max(0.01), v.max(0.01));
            let (u, v) = if u + v > 0.98 {
                let k = 0.98 / (u + v);
                (u * k, v * k)
            } else {
                (u, v)
            };
            let (s, t) = piece.at_local(u, v);
            return self.at(s, t);
        }
        let local =
            |x: f64, lo: f64, hi: f64| lo + ((x - lo) / (hi - lo)).clamp(0.01, 0.99) * (hi - lo);
        self.at(
            local(s, piece.s[0], piece.s[1]),
            local(t, piece.t[0], piece.t[1]),
        )
    }

    /// Signed distance of p from the plane, positive in front.
    #[inline(always)]
    pub(super) fn side(&self, p: V3) -> f64 {
        dot(sub(p, self.p0), self.n)
    }

    /// The corners of the piece `[s0,s1] × [t0,t1]`, counter-clockwise.
    pub(super) fn piece(&self, s: [f64; 2], t: [f64; 2]) -> [V3; 4] {
        [
            self.at(s[0], t[0]),
            self.at(s[1], t[0]),
            self.at(s[1], t[1]),
            self.at(s[0], t[1]),
        ]
    }

    /// Length of the longer diagonal of the whole parallelogram; a triangle's longest side.
    pub(super) fn diameter(&self) -> f64 {
        if self.tri {
            return norm(self.e1)
                .max(norm(self.e3))
                .max(norm(sub(self.e1, self.e3)));
        }
        norm(add(self.e1, self.e3)).max(norm(sub(self.e1, self.e3)))
    }
}

/// Distance between point p and segment [a, b].
fn point_segment(p: V3, a: V3, b: V3) -> f64 {
    let d = sub(b, a);
    let l2 = dot(d, d);
    let t = if l2 > 0.0 {
        (dot(sub(p, a), d) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    norm(sub(add(a, scale(d, t)), p))
}

/// Distance between the segments [p1, q1] and [p2, q2] (Ericson, Real-Time Collision
/// Detection, §5.1.9).
fn segment_segment(p1: V3, q1: V3, p2: V3, q2: V3) -> f64 {
    let d1 = sub(q1, p1);
    let d2 = sub(q2, p2);
    let r = sub(p1, p2);
    let a = dot(d1, d1);
    let e = dot(d2, d2);
    let f = dot(d2, r);
    let eps = 1e-30;
    let (s, t);
    if a <= eps && e <= eps {
        return norm(r);
    }
    if a <= eps {
        s = 0.0;
        t = (f / e).clamp(0.0, 1.0);
    } else {
        let c = dot(d1, r);
        if e <= eps {
            t = 0.0;
            s = (-c / a).clamp(0.0, 1.0);
        } else {
            let b = dot(d1, d2);
            let den = a * e - b * b;
            let mut s0 = if den > eps * a * e {
                ((b * f - c * e) / den).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let mut t0 = (b * s0 + f) / e;
            if t0 < 0.0 {
                t0 = 0.0;
                s0 = (-c / a).clamp(0.0, 1.0);
            } else if t0 > 1.0 {
                t0 = 1.0;
                s0 = ((b - c) / a).clamp(0.0, 1.0);
            }
            s = s0;
            t = t0;
        }
    }
    norm(sub(add(p1, scale(d1, s)), add(p2, scale(d2, t))))
}

/// Distance from p to the convex planar quadrilateral `q` (corners in order, normal `n`).
pub(super) fn point_quad(p: V3, q: &[V3; 4], n: V3) -> f64 {
    let mut inside = true;
    for i in 0..4 {
        let e = sub(q[(i + 1) % 4], q[i]);
        if dot(cross(e, sub(p, q[i])), n) < 0.0 {
            inside = false;
            break;
        }
    }
    if inside {
        return dot(sub(p, q[0]), n).abs();
    }
    (0..4)
        .map(|i| point_segment(p, q[i], q[(i + 1) % 4]))
        .fold(f64::INFINITY, f64::min)
}

/// Whether the segment [a, b] crosses the convex planar quadrilateral `q` with normal `n`.
fn segment_crosses(a: V3, b: V3, q: &[V3; 4], n: V3) -> bool {
    let da = dot(sub(a, q[0]), n);
    let db = dot(sub(b, q[0]), n);
    if (da > 0.0 && db > 0.0) || (da < 0.0 && db < 0.0) || da == db {
        return false;
    }
    let x = add(a, scale(sub(b, a), da / (da - db)));
    (0..4).all(|i| dot(cross(sub(q[(i + 1) % 4], q[i]), sub(x, q[i])), n) >= 0.0)
}

/// Distance between two convex planar quadrilaterals (0 when they meet).
pub(super) fn quad_quad(a: &[V3; 4], na: V3, b: &[V3; 4], nb: V3) -> f64 {
    let mut d = f64::INFINITY;
    for i in 0..4 {
        let (a0, a1) = (a[i], a[(i + 1) % 4]);
        let (b0, b1) = (b[i], b[(i + 1) % 4]);
        if segment_crosses(a0, a1, b, nb) || segment_crosses(b0, b1, a, na) {
            return 0.0;
        }
        for j in 0..4 {
            d = d.min(segment_segment(a0, a1, b[j], b[(j + 1) % 4]));
        }
        d = d.min(point_quad(a[i], b, nb)).min(point_quad(b[i], a, na));
    }
    d
}

/// A piece `[s0,s1] × [t0,t1]` of surface `surface`. On a triangle patch (whose pieces are
/// those of the four-way midpoint split, squares in (s, t)) it is half of that square: the
/// lower-left half (s − s0) + (t − t0) ≤ h, or with `upper` the upper-right half
/// (s1 − s) + (t1 − t) ≤ h, h = s1 − s0. Either is the image of the reference triangle of
/// [`crate::math::triangle`] under its local coordinates `Piece::local`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Piece {
    pub(super) surface: usize,
    pub(super) s: [f64; 2],
    pub(super) t: [f64; 2],
    pub(super) upper: bool,
}

impl Piece {
    pub(super) fn whole(surface: usize) -> Piece {
        Piece {
            surface,
            s: [0.0, 1.0],
            t: [0.0, 1.0],
            upper: false,
        }
    }

    /// Its corners, counter-clockwise; a triangle's three with the last repeated.
    pub(super) fn corners(&self, quads: &[Parallelogram]) -> [V3; 4] {
        let q = &quads[self.surface];
        if !q.tri {
            return q.piece(self.s, self.t);
        }
        let [a, b, c] = self.triangle();
        let at = |p: [f64; 2]| q.at(p[0], p[1]);
        [at(a), at(b), at(c), at(c)]
    }

    /// Its centroid.
    pub(super) fn centre(&self, quads: &[Parallelogram]) -> V3 {
        centroid(&self.corners(quads), quads[self.surface].tri)
    }

    /// Half its surface's diameter scaled by the piece's side in parameters: the radius of a
    /// parallelogram piece's sphere about its centre, and about a triangle's (whose vertices
    /// may lie up to 2/√3 of it from its centroid, an equilateral one's).
    pub(super) fn radius(&self, quads: &[Parallelogram]) -> f64 {
        0.5 * quads[self.surface].diameter() * (self.s[1] - self.s[0])
    }

    /// Child `c` (0…3) of its four-way midpoint split: a triangle's as
    /// [`Piece::tri_child`] numbers them, a parallelogram's with s halved by `c % 2` and t by
    /// `c / 2`.
    pub(super) fn child(&self, triangle: bool, c: usize) -> Piece {
        if triangle {
            return self.tri_child(c);
        }
        let (ms, mt) = (0.5 * (self.s[0] + self.s[1]), 0.5 * (self.t[0] + self.t[1]));
        Piece {
            s: if c.is_multiple_of(2) {
                [self.s[0], ms]
            } else {
                [ms, self.s[1]]
            },
            t: if c / 2 == 0 {
                [self.t[0], mt]
            } else {
                [mt, self.t[1]]
            },
            ..*self
        }
    }

    /// The (s, t) of a triangle piece's vertices, in the order of the reference triangle's.
    pub(super) fn triangle(&self) -> [[f64; 2]; 3] {
        let (s, t) = (self.s, self.t);
        if self.upper {
            [[s[1], t[1]], [s[0], t[1]], [s[1], t[0]]]
        } else {
            [[s[0], t[0]], [s[1], t[0]], [s[0], t[1]]]
        }
    }

    /// The local coordinates of (s, t) in a triangle piece: (0, 0) at its first vertex, the
    /// reference triangle's (ŝ, t̂).
    #[inline(always)]
    pub(super) fn local(&self, s: f64, t: f64) -> (f64, f64) {
        crate::math::triangle::local_in_half(self.s, self.t, self.upper, s, t)
    }

    /// (s, t) of the local coordinates (ŝ, t̂) of a triangle piece.
    #[inline(always)]
    pub(super) fn at_local(&self, u: f64, v: f64) -> (f64, f64) {
        let h = self.s[1] - self.s[0];
        if self.upper {
            (self.s[1] - u * h, self.t[1] - v * h)
        } else {
            (self.s[0] + u * h, self.t[0] + v * h)
        }
    }

    /// Child `c` of the four-way midpoint split of a triangle piece, numbered as
    /// [`crate::math::triangle::CHILDREN`]: the corner children keep the orientation, the
    /// centre one (3) is turned by half a turn.
    pub(super) fn tri_child(&self, c: usize) -> Piece {
        let (ms, mt) = (0.5 * (self.s[0] + self.s[1]), 0.5 * (self.t[0] + self.t[1]));
        let lo_s = [self.s[0], ms];
        let hi_s = [ms, self.s[1]];
        let lo_t = [self.t[0], mt];
        let hi_t = [mt, self.t[1]];
        // in local coordinates the corner children sit at the origin, along ŝ and along t̂,
        // and the centre child at the origin's square, turned
        let (s, t, upper) = match (self.upper, c) {
            (false, 0) => (lo_s, lo_t, false),
            (false, 1) => (hi_s, lo_t, false),
            (false, 2) => (lo_s, hi_t, false),
            (false, _) => (lo_s, lo_t, true),
            (true, 0) => (hi_s, hi_t, true),
            (true, 1) => (lo_s, hi_t, true),
            (true, 2) => (hi_s, lo_t, true),
            (true, _) => (hi_s, hi_t, false),
        };
        Piece {
            surface: self.surface,
            s,
            t,
            upper,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parametrisation_round_trips() {
        let q = Parallelogram::new(&[
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [3.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
        ]);
        assert_eq!(q.n, [0.0, 0.0, 1.0]);
        assert!((q.area - 2.0).abs() < 1e-15);
        let (s, t) = q.params(q.at(0.3, 0.7));
        assert!((s - 0.3).abs() < 1e-15 && (t - 0.7).abs() < 1e-15);
    }

    #[test]
    fn distances() {
        let a = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        let up = [0.0, 0.0, 1.0];
        let lifted = a.map(|p| [p[0] + 0.5, p[1], p[2] + 2.0]);
        assert!((quad_quad(&a, up, &lifted, up) - 2.0).abs() < 1e-15);
        // a wall sharing the edge x = 1
        let wall = [
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [1.0, 1.0, 1.0],
            [1.0, 0.0, 1.0],
        ];
        assert_eq!(quad_quad(&a, up, &wall, [1.0, 0.0, 0.0]), 0.0);
        // a segment piercing the square
        let pierce = [
            [0.5, 0.5, -1.0],
            [0.6, 0.5, -1.0],
            [0.6, 0.5, 1.0],
            [0.5, 0.5, 1.0],
        ];
        assert_eq!(quad_quad(&a, up, &pierce, [0.0, -1.0, 0.0]), 0.0);
        assert!(
            (segment_segment([0.0; 3], [1.0, 0.0, 0.0], [0.5, 1.0, 1.0], [0.5, 1.0, 2.0])
                - 2f64.sqrt())
            .abs()
                < 1e-15
        );
    }
}
