//! Polynomials on triangles for the element trees of triangle meshes: an orthonormal basis of the
//! polynomials of total degree ≤ m, the four-way midpoint split with its exact two-scale relation
//! (push and pull), and a triangle quadrature exact to any stated degree.
//!
//! # The basis (Koornwinder 1975; Dubiner 1991; Sherwin and Karniadakis 1995)
//!
//! On the reference triangle T̂ = {(s, t) : s, t ≥ 0, s + t ≤ 1}, with vertices (0, 0), (1, 0),
//! (0, 1), the collapsed coordinates a = 2s / (1 − t) − 1 and b = 2t − 1 map T̂ onto the square
//! [−1, 1]², and the functions
//!
//! ```text
//! φ_pq(s, t) = √((2p + 1)(p + q + 1)) · P_p(a) ((1 − b)/2)^p · P_q^(2p+1, 0)(b),   p + q ≤ m,
//! ```
//!
//! (P_p Legendre, P_q^(α,β) Jacobi) are the orthogonal polynomials of Koornwinder ("Two-variable
//! analogues of the classical orthogonal polynomials", in *Theory and Application of Special
//! Functions*, ed. R. Askey, Academic Press 1975, pp. 435–495), introduced for spectral methods
//! by M. Dubiner ("Spectral methods on triangles and other domains", J. Sci. Comput. 6, 1991,
//! 345–390) and written in this collapsed form, the principal functions ψ^a_p(η₁) ψ^b_pq(η₂), by
//! S. J. Sherwin and G. E. Karniadakis ("A new triangular and tetrahedral basis for high-order
//! (hp) finite element methods", Int. J. Numer. Meth. Eng. 38, 1995, 3775–3802). Although a
//! alone is singular at the top vertex t = 1, P_p(a) (1 − t)^p is a polynomial of degree p in
//! (s, t): with x = a (1 − t) = 2s + t − 1 and y = 1 − t, Legendre's recurrence becomes
//! (p + 1) Q_{p+1} = (2p + 1) x Q_p − p y² Q_{p−1} for Q_p = P_p(a) y^p, which is what is
//! evaluated. So φ_pq is a polynomial of total degree p + q, and the (m + 1)(m + 2)/2 of them
//! with p + q ≤ m are a basis of the polynomials of degree ≤ m.
//!
//! # Normalisation: orthonormal in area, as the parallelograms' tensor Legendre basis
//!
//! The Jacobi norms give ∫_T̂ φ_pq² ds dt = ½ = area(T̂), so the φ are orthonormal in the mean:
//! (1 / area(T̂)) ∫_T̂ φ_i φ_j = δ_ij, with φ₀₀ = 1. On a triangle T of area A with the affine
//! parametrisation x = v₀ + s (v₁ − v₀) + t (v₂ − v₀), the basis functions are
//! ψ_j = φ_j(s, t) / √A, orthonormal in area (∫_T ψ_i ψ_j dA = δ_ij), exactly as the elements of
//! [`crate::three_d::hierarchy`]'s quadtrees carry tensor Legendre coefficients orthonormal in their area
//! (φ_p(s) φ_q(t) / √A). A function's coefficients are c_j = ∫_T f ψ_j dA; its mean over T is
//! c₀ / √A and its value at (s, t) is Σ c_j φ_j(s, t) / √A. With these coefficients the
//! two-scale relation is an orthogonal one and pull is exactly the transpose of push, with no
//! area factor (as [`crate::three_d::hierarchy`]'s `push` and `pull` use Alpert's filters H and Hᵀ).
//!
//! Ordering: φ_pq is function number j = n(n + 1)/2 + p with n = p + q, by total degree, so the
//! first (m' + 1)(m' + 2)/2 functions of order m are those of order m' ≤ m.
//!
//! # The midpoint split
//!
//! A triangle (v₀, v₁, v₂) splits at its edge midpoints m₀₁, m₁₂, m₀₂ into four children of a
//! quarter of its area, each the affine image of the reference triangle with its vertices, in
//! order, at (`CHILDREN`, in the parent's (s, t)):
//!
//! | child | vertices            | map F_c(s, t) from the child's (s, t) to the parent's |
//! | ----- | ------------------- | ----------------------------------------------------- |
//! | 0     | (v₀, m₀₁, m₀₂)      | (s/2, t/2)                                            |
//! | 1     | (m₀₁, v₁, m₁₂)      | (½ + s/2, t/2)                                        |
//! | 2     | (m₀₂, m₁₂, v₂)      | (s/2, ½ + t/2)                                        |
//! | 3     | (m₁₂, m₀₂, m₀₁)     | (½ − s/2, ½ − t/2)                                    |
//!
//! The corner child c keeps the parent's vertex c as its own vertex c; the centre child is the
//! parent scaled by −½ about its centroid (a half turn in the plane, not a mirror image): its
//! vertex i is the midpoint of the edge opposite the parent's vertex i. Every F_c has Jacobian
//! determinant +¼, so every child has the parent's orientation: (w₁ − w₀) × (w₂ − w₀) of its
//! world vertices points along the parent's front normal. Midpoints are computed as ½(a + b),
//! symmetric in a and b, so two triangles sharing an edge get the same midpoint to the bit.
//!
//! # The two-scale relation
//!
//! With ψ_j the parent's functions and χ^c_i those of child c (both orthonormal in area), a
//! parent polynomial restricted to a child is a polynomial of the same degree, so
//! ψ_j = Σ_c Σ_i H^c_ji χ^c_i exactly, with
//! H^c_ji = ∫_{T_c} ψ_j χ^c_i dA = ½ · (1 / area(T̂)) ∫_T̂ φ_j(F_c(u)) φ_i(u) du. Push (the
//! children's coefficients of a parent polynomial) is d^c = (H^c)ᵀ c, exact; pull (the L²
//! projection of piecewise polynomials on the children onto the parent's space) is
//! c = Σ_c H^c d^c. The n × 4n matrix [H⁰ H¹ H² H³] has orthonormal rows, so pull ∘ push is the
//! identity. (In coefficients normalised by the mean instead of the area, a_j = c_j / √A, push
//! would be 2 (H^c)ᵀ and pull Σ_c ½ H^c: the transpose up to the children's area fraction ¼.)
//! H is computed once per m by a quadrature exact for degree 2m, so it is exact to rounding.
//!
//! # Quadrature
//!
//! [`TriangleRule`] is the conical product (Duffy) rule: s = u (1 − t), ds dt = (1 − t) du dt
//! maps the unit square onto T̂, and Gauss–Legendre in u and in t integrates s^a t^b, which is
//! u^a (1 − t)^{a+1} t^b there, exactly when ⌊d/2⌋ + 1 points in u and ⌈d/2⌉ + 1 in t
//! cover a ≤ d and a + b + 1 ≤ d + 1. It is exact for total degree d and for no more (s^{d+1}
//! is not integrated exactly), for any d, from the same Gauss–Legendre nodes as
//! [`crate::math::quadrature`]. It is written here rather than taken from a crate: the crates of
//! tabulated symmetric triangle rules (fewer points for the same degree) stop at a fixed degree
//! and have not had a release in years, and the Gauss–Jacobi rule of `gauss-quad` 0.3, which
//! would absorb the weight (1 − t) and save one point in t, puts the middle node of an
//! odd-sized rule at 0, right only for symmetric weights (α = β): with α = 1, β = 0 its 3-point
//! rule misses ∫ (1 − x) x^k dx, k ≤ 5, by up to 0.17.

use crate::math::quadrature::{Rule, MAX_CACHED};
use smallvec::{smallvec, SmallVec};
use std::sync::{Mutex, OnceLock};

/// The local coordinates (ŝ, t̂) of the point (x, y) in the triangle that is the lower-left
/// half of the square `[s0, s1] × [t0, t1]` (the right angle at (s0, t0)), or with `upper` its
/// upper-right half (the right angle at (s1, t1), turned by half a turn): the triangles of the
/// four-way split of a triangle whose (s, t) square is the unit one.
#[inline(always)]
pub(crate) fn local_in_half(s: [f64; 2], t: [f64; 2], upper: bool, x: f64, y: f64) -> (f64, f64) {
    let h = s[1] - s[0];
    if upper {
        ((s[1] - x) / h, (t[1] - y) / h)
    } else {
        ((x - s[0]) / h, (y - t[0]) / h)
    }
}

/// The halves of the cells of an `n × n` grid over a square that its lower-left half (or with
/// `upper` its upper-right half) is made of: `(i, j, upper half of the cell)`, i along s. A cell
/// wholly inside gives both halves; one on the diagonal, the half on the triangle's side.
pub(crate) fn cell_halves(n: usize, upper: bool) -> impl Iterator<Item = (usize, usize, bool)> {
    (0..n * n).flat_map(move |c| {
        let (i, j) = (c % n, c / n);
        // (a, b): the cell counted from the triangle's right angle
        let (a, b) = if upper {
            (n - 1 - i, n - 1 - j)
        } else {
            (i, j)
        };
        let halves: &[bool] = if a + b + 1 < n {
            &[false, true]
        } else if a + b + 1 == n {
            if upper {
                &[true]
            } else {
                &[false]
            }
        } else {
            &[]
        };
        halves.iter().map(move |&h| (i, j, h))
    })
}

/// The reference triangle's vertices (s, t), in order.
const VERTICES: [[f64; 2]; 3] = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];

/// The midpoint split's children in the parent's reference coordinates: child c is the affine
/// image of the reference triangle whose vertex i is `CHILDREN[c][i]` (see the module's table).
const CHILDREN: [[[f64; 2]; 3]; 4] = [
    [[0.0, 0.0], [0.5, 0.0], [0.0, 0.5]],
    [[0.5, 0.0], [1.0, 0.0], [0.5, 0.5]],
    [[0.0, 0.5], [0.5, 0.5], [0.0, 1.0]],
    [[0.5, 0.5], [0.0, 0.5], [0.5, 0.0]],
];

/// The number of polynomials of total degree ≤ m in two variables: (m + 1)(m + 2)/2.
pub(crate) const fn dimension(m: usize) -> usize {
    (m + 1) * (m + 2) / 2
}

/// The point of the parent, in its (s, t), that is point (s, t) of child `child`: F_c(s, t).
pub(crate) fn to_parent(child: usize, s: f64, t: f64) -> [f64; 2] {
    let [a, b, c] = CHILDREN[child];
    [
        a[0] + s * (b[0] - a[0]) + t * (c[0] - a[0]),
        a[1] + s * (b[1] - a[1]) + t * (c[1] - a[1]),
    ]
}

/// The child that holds the parent's point (s, t) (a point of the triangle), and that point in
/// the child's (s, t): the inverse of [`to_parent`]. A point on an edge between two children
/// goes to the corner child rather than the centre one, and (½, ½) to child 1.
pub(crate) fn locate(s: f64, t: f64) -> (usize, [f64; 2]) {
    if s >= 0.5 {
        (1, [2.0 * s - 1.0, 2.0 * t])
    } else if t >= 0.5 {
        (2, [2.0 * s, 2.0 * t - 1.0])
    } else if s + t <= 0.5 {
        (0, [2.0 * s, 2.0 * t])
    } else {
        (3, [1.0 - 2.0 * s, 1.0 - 2.0 * t])
    }
}

/// The four children of the triangle with vertices `v` (in any dimension), in the order and
/// with the vertex order of `CHILDREN`.
#[cfg(test)]
pub(crate) fn split<const D: usize>(v: &[[f64; D]; 3]) -> [[[f64; D]; 3]; 4] {
    let mid =
        |a: usize, b: usize| -> [f64; D] { std::array::from_fn(|k| 0.5 * (v[a][k] + v[b][k])) };
    let (m01, m12, m02) = (mid(0, 1), mid(1, 2), mid(0, 2));
    [
        [v[0], m01, m02],
        [m01, v[1], m12],
        [m02, m12, v[2]],
        [m12, m02, m01],
    ]
}

/// Writes φ_0 … φ_{n−1}(s, t), n = [`dimension`]`(m)`, into `out`: the basis of the module's
/// doc, orthonormal in the mean over the reference triangle, φ_0 = 1.
fn dubiner(m: usize, s: f64, t: f64, out: &mut [f64]) {
    debug_assert_eq!(out.len(), dimension(m));
    let x = 2.0 * s + t - 1.0;
    let y = 1.0 - t;
    let y2 = y * y;
    let b = 2.0 * t - 1.0;
    let (mut q_prev, mut q_p) = (0.0, 1.0);
    for p in 0..=m {
        if p == 1 {
            (q_prev, q_p) = (q_p, x);
        } else if p > 1 {
            let pf = (p - 1) as f64;
            let next = ((2.0 * pf + 1.0) * x * q_p - pf * y2 * q_prev) / (pf + 1.0);
            (q_prev, q_p) = (q_p, next);
        }
        // Jacobi P_q^(α,0)(b), α = 2p + 1, by the three-term recurrence.
        let alpha = (2 * p + 1) as f64;
        let (mut j_prev, mut j_q) = (0.0, 1.0);
        for q in 0..=m - p {
            if q == 1 {
                (j_prev, j_q) = (j_q, 0.5 * ((alpha + 2.0) * b + alpha));
            } else if q > 1 {
                let n = q as f64;
                let c = 2.0 * n + alpha;
                let a1 = 2.0 * n * (n + alpha) * (c - 2.0);
                let a2 = (c - 1.0) * (c * (c - 2.0) * b + alpha * alpha);
                let a3 = 2.0 * (n + alpha - 1.0) * (n - 1.0) * c;
                let next = (a2 * j_q - a3 * j_prev) / a1;
                (j_prev, j_q) = (j_q, next);
            }
            let deg = p + q;
            let norm = ((2 * p + 1) as f64 * (deg + 1) as f64).sqrt();
            out[deg * (deg + 1) / 2 + p] = norm * q_p * j_q;
        }
    }
}

/// A quadrature rule on the reference triangle: Σ_k w_k f(p_k) = (1 / area(T̂)) ∫_T̂ f, the
/// mean of f, exactly for every polynomial of total degree ≤ `degree` (the module's doc). On a
/// triangle of area A parametrised by the same (s, t), ∫_T f dA = A Σ_k w_k f(p_k).
#[derive(Debug, Clone, PartialEq)]
pub struct TriangleRule {
    /// Points (s, t), all inside the triangle.
    pub(crate) points: Vec<[f64; 2]>,
    /// Positive weights summing to 1.
    pub(crate) weights: Vec<f64>,
    /// The total degree to which it is exact.
    degree: usize,
}

impl TriangleRule {
    /// The rule exact for total degree `d` (d ≤ 2 · [`MAX_CACHED`] − 2), computed once and
    /// cached: (⌊d/2⌋ + 1)(⌈d/2⌉ + 1) points.
    pub(crate) fn for_degree(d: usize) -> &'static TriangleRule {
        static CACHE: OnceLock<Mutex<Vec<Option<&'static TriangleRule>>>> = OnceLock::new();
        assert!(d + 2 <= 2 * MAX_CACHED, "triangle rule of degree {d}");
        let cache = CACHE.get_or_init(|| Mutex::new(Vec::new()));
        let mut c = cache.lock().unwrap_or_else(|e| e.into_inner());
        if c.len() <= d {
            c.resize(d + 1, None);
        }
        c[d].get_or_insert_with(|| Box::leak(Box::new(TriangleRule::compute(d))))
    }

    fn compute(d: usize) -> TriangleRule {
        let along = Rule::gauss(d / 2 + 1);
        let up = Rule::gauss(d.div_ceil(2) + 1);
        let mut points = Vec::with_capacity(along.len() * up.len());
        let mut weights = Vec::with_capacity(along.len() * up.len());
        for (&t, &wt) in up.nodes.iter().zip(&up.weights) {
            for (&u, &wu) in along.nodes.iter().zip(&along.weights) {
                points.push([u * (1.0 - t), t]);
                // ∫∫ (1 − t) du dt = ½ = area(T̂): twice the product weight sums to 1.
                weights.push(2.0 * wu * wt * (1.0 - t));
            }
        }
        TriangleRule {
            points,
            weights,
            degree: d,
        }
    }

    #[cfg(test)]
    pub(crate) fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The mean of f over the triangle, f as a function of (s, t).
    pub fn mean(&self, mut f: impl FnMut(f64, f64) -> f64) -> f64 {
        self.points
            .iter()
            .zip(&self.weights)
            .map(|(p, w)| w * f(p[0], p[1]))
            .sum()
    }

    /// ∫_T f dA over a triangle of area `area`, f as a function of its (s, t).
    #[cfg(test)]
    pub(crate) fn integrate(&self, area: f64, f: impl FnMut(f64, f64) -> f64) -> f64 {
        area * self.mean(f)
    }
}

/// The basis of order m on triangles (the module's doc) and its two-scale relation.
#[derive(Debug, Clone, PartialEq)]
pub struct TriangleBasis {
    /// The total degree m.
    m: usize,
    /// The number of functions, (m + 1)(m + 2)/2.
    n: usize,
    /// The two-scale coefficients of the four children: `h[c][j * n + i]` = H^c_ji =
    /// ∫_{T_c} ψ_j χ^c_i dA, parent function j and function i of child c.
    h: [Vec<f64>; 4],
    /// φ_j at the three vertices.
    vertices: [Vec<f64>; 3],
}

impl TriangleBasis {
    /// The basis of total degree ≤ `m`, computed once and cached.
    pub(crate) fn of_order(m: usize) -> &'static TriangleBasis {
        static CACHE: OnceLock<Mutex<Vec<Option<&'static TriangleBasis>>>> = OnceLock::new();
        let cache = CACHE.get_or_init(|| Mutex::new(Vec::new()));
        let mut c = cache.lock().unwrap_or_else(|e| e.into_inner());
        if c.len() <= m {
            c.resize(m + 1, None);
        }
        c[m].get_or_insert_with(|| Box::leak(Box::new(TriangleBasis::compute(m))))
    }

    fn compute(m: usize) -> TriangleBasis {
        let n = dimension(m);
        let rule = TriangleRule::for_degree(2 * m);
        let mut child = vec![0.0; n];
        let mut parent = vec![0.0; n];
        let h = std::array::from_fn(|c| {
            let mut hc = vec![0.0; n * n];
            for (p, w) in rule.points.iter().zip(&rule.weights) {
                dubiner(m, p[0], p[1], &mut child);
                let [s, t] = to_parent(c, p[0], p[1]);
                dubiner(m, s, t, &mut parent);
                // ∫_{T_c} ψ_j χ_i dA = (A/4) mean(φ_j ∘ F_c · φ_i) / (√A √(A/4))
                for j in 0..n {
                    for i in 0..n {
                        hc[j * n + i] += 0.5 * w * parent[j] * child[i];
                    }
                }
            }
            hc
        });
        let vertices = std::array::from_fn(|v| {
            let mut out = vec![0.0; n];
            dubiner(m, VERTICES[v][0], VERTICES[v][1], &mut out);
            out
        });
        TriangleBasis { m, n, h, vertices }
    }

    /// φ_0 … φ_{n−1} at the reference point (s, t) into `out` (length n): orthonormal in the
    /// mean, so the element's ψ_j = φ_j / √A.
    pub(crate) fn eval(&self, s: f64, t: f64, out: &mut [f64]) {
        assert_eq!(out.len(), self.n);
        dubiner(self.m, s, t, out);
    }

    /// The value at (s, t) of the function with coefficients `coeffs` (orthonormal in area) on
    /// a triangle of area `area`.
    pub fn value<const C: usize>(
        &self,
        coeffs: &[[f64; C]],
        area: f64,
        s: f64,
        t: f64,
    ) -> [f64; C] {
        let mut phi: SmallVec<[f64; 36]> = smallvec![0.0; self.n];
        dubiner(self.m, s, t, &mut phi);
        combine(coeffs, &phi, area)
    }

    /// The values at the triangle's three vertices, in order.
    #[cfg(test)]
    pub(crate) fn vertex_values<const C: usize>(
        &self,
        coeffs: &[[f64; C]],
        area: f64,
    ) -> [[f64; C]; 3] {
        std::array::from_fn(|v| combine(coeffs, &self.vertices[v], area))
    }

    /// The mean over the triangle: c₀ / √A.
    #[cfg(test)]
    pub(crate) fn mean<const C: usize>(&self, coeffs: &[[f64; C]], area: f64) -> [f64; C] {
        let r = area.sqrt().recip();
        coeffs[0].map(|v| v * r)
    }

    /// The coefficients of the L² projection of `f` (a function of (s, t)) onto the basis of a
    /// triangle of area `area`, c_j = ∫_T f ψ_j dA, by `rule`: exact when f is a polynomial of
    /// degree ≤ `rule.degree` − m.
    #[cfg(test)]
    pub(crate) fn project<const C: usize>(
        &self,
        area: f64,
        rule: &TriangleRule,
        mut f: impl FnMut(f64, f64) -> [f64; C],
    ) -> Vec<[f64; C]> {
        let mut phi = vec![0.0; self.n];
        let mut out = vec![[0.0; C]; self.n];
        for (p, w) in rule.points.iter().zip(&rule.weights) {
            dubiner(self.m, p[0], p[1], &mut phi);
            let v = f(p[0], p[1]);
            for (o, ph) in out.iter_mut().zip(&phi) {
                for k in 0..C {
                    o[k] += w * ph * v[k];
                }
            }
        }
        let r = area.sqrt();
        out.iter_mut()
            .for_each(|o| o.iter_mut().for_each(|v| *v *= r));
        out
    }

    /// Push: the coefficients on child `child` of the parent's polynomial `parent` (exact),
    /// written into `out`.
    pub(crate) fn push<const C: usize>(
        &self,
        parent: &[[f64; C]],
        child: usize,
        out: &mut [[f64; C]],
    ) {
        let n = self.n;
        let h = &self.h[child];
        for (i, o) in out[..n].iter_mut().enumerate() {
            let mut acc = [0.0; C];
            for (j, p) in parent[..n].iter().enumerate() {
                let w = h[j * n + i];
                for k in 0..C {
                    acc[k] += w * p[k];
                }
            }
            *o = acc;
        }
    }

    /// Pull: adds the L² projection onto the parent's space of child `child`'s polynomial
    /// `coeffs` to `parent`. Summed over the four children, this is the parent's projection of
    /// the piecewise polynomial.
    pub(crate) fn pull<const C: usize>(
        &self,
        coeffs: &[[f64; C]],
        child: usize,
        parent: &mut [[f64; C]],
    ) {
        let n = self.n;
        let h = &self.h[child];
        for (j, p) in parent[..n].iter_mut().enumerate() {
            let row = &h[j * n..(j + 1) * n];
            for (w, d) in row.iter().zip(&coeffs[..n]) {
                for k in 0..C {
                    p[k] += w * d[k];
                }
            }
        }
    }
}

/// Σ_j c_j φ_j / √A.
fn combine<const C: usize>(coeffs: &[[f64; C]], phi: &[f64], area: f64) -> [f64; C] {
    let mut acc = [0.0; C];
    for (c, p) in coeffs.iter().zip(phi) {
        for k in 0..C {
            acc[k] += c[k] * p;
        }
    }
    let r = area.sqrt().recip();
    acc.map(|v| v * r)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The mean of s^a t^b over the reference triangle, 2 a! b! / (a + b + 2)!, from exact
    /// integers (each conversion to f64 rounds once).
    fn monomial_mean(a: u32, b: u32) -> f64 {
        let fact = |k: u32| (1..=k as u128).product::<u128>();
        2.0 * (fact(a) * fact(b)) as f64 / fact(a + b + 2) as f64
    }

    fn monomial(s: f64, t: f64, a: u32, b: u32) -> f64 {
        s.powi(a as i32) * t.powi(b as i32)
    }

    /// Points spread over the triangle, its vertices, edges and interior.
    fn sample_points() -> Vec<[f64; 2]> {
        let mut pts = VERTICES.to_vec();
        pts.extend([[0.5, 0.0], [0.5, 0.5], [0.0, 0.5], [1.0 / 3.0, 1.0 / 3.0]]);
        for i in 0..7 {
            for j in 0..7 - i {
                let s = (i as f64 + 0.31) / 7.4;
                let t = (j as f64 + 0.17) / 7.4;
                if s + t <= 1.0 {
                    pts.push([s, t]);
                }
            }
        }
        pts
    }

    /// Coefficients with no structure: different in every function and channel.
    fn some_coeffs(n: usize) -> Vec<[f64; 3]> {
        (0..n)
            .map(|j| {
                let x = j as f64;
                [1.0 + 0.5 * x, (0.7 * x).sin(), 0.3 - 0.11 * x * x]
            })
            .collect()
    }

    /// Every monomial of degree ≤ d has its closed-form mean, and s^{d+1} does not, for
    /// d = 0 … 24; the weights are positive, the points inside, the sizes as documented.
    #[test]
    fn rule_is_exact_to_its_degree_and_no_further() {
        for d in 0..=24 {
            let rule = TriangleRule::for_degree(d);
            assert_eq!(rule.degree, d);
            assert_eq!(rule.len(), (d / 2 + 1) * (d.div_ceil(2) + 1));
            for (p, w) in rule.points.iter().zip(&rule.weights) {
                assert!(*w > 0.0 && p[0] > 0.0 && p[1] > 0.0 && p[0] + p[1] < 1.0);
            }
            for total in 0..=d as u32 {
                for a in 0..=total {
                    let b = total - a;
                    let got = rule.mean(|s, t| monomial(s, t, a, b));
                    let want = monomial_mean(a, b);
                    // rounding only: a sum of at most 169 positive terms
                    assert!(
                        (got - want).abs() <= 1e-13 * want,
                        "degree {d}: s^{a} t^{b}: {got} vs {want}"
                    );
                }
            }
            if d <= 12 {
                let a = d as u32 + 1;
                let got = rule.mean(|s, _| s.powi(a as i32));
                let want = monomial_mean(a, 0);
                // far above rounding (the Gauss error of s^{d+1} shrinks with d; checked
                // where it is at least 1e-8 of the value)
                assert!(
                    (got - want).abs() > 1e-9 * want,
                    "degree {d} rule integrates s^{a} exactly"
                );
            }
        }
    }

    #[test]
    fn rule_integrates_over_a_triangle_of_any_area() {
        // ∫ over the triangle (0,0), (2,0), (0,3) of x² y dA = 2·3·(2² · 3)·∫_T̂ s² t = 72 / 60
        let area = 3.0;
        let rule = TriangleRule::for_degree(3);
        let got = rule.integrate(area, |s, t| (2.0 * s).powi(2) * (3.0 * t));
        assert!((got - 72.0 / 60.0).abs() < 1e-14);
    }

    /// The mean of φ_i φ_j over the triangle is δ_ij (m = 0 … 12), by a rule exact for 2m.
    #[test]
    fn orthonormal_in_the_mean() {
        for m in 0..=12 {
            let basis = TriangleBasis::of_order(m);
            let n = basis.n;
            assert_eq!(n, (m + 1) * (m + 2) / 2);
            let rule = TriangleRule::for_degree(2 * m);
            let mut phi = vec![0.0; n];
            let mut gram = vec![0.0; n * n];
            for (p, w) in rule.points.iter().zip(&rule.weights) {
                basis.eval(p[0], p[1], &mut phi);
                for i in 0..n {
                    for j in 0..n {
                        gram[i * n + j] += w * phi[i] * phi[j];
                    }
                }
            }
            for i in 0..n {
                for j in 0..n {
                    let want = if i == j { 1.0 } else { 0.0 };
                    let got = gram[i * n + j];
                    assert!((got - want).abs() < 1e-12, "m={m} ({i},{j}): {got}");
                }
            }
        }
    }

    /// φ_00 = 1, φ_01 = √2 (3t − 1), φ_10 = √6 (2s + t − 1): the first functions in closed form,
    /// and the first functions of every order are those of the lower orders.
    #[test]
    fn closed_forms_and_nested_orders() {
        let mut phi = vec![0.0; 3];
        for [s, t] in sample_points() {
            TriangleBasis::of_order(1).eval(s, t, &mut phi);
            assert_eq!(phi[0], 1.0);
            assert!((phi[1] - 2f64.sqrt() * (3.0 * t - 1.0)).abs() < 1e-15);
            assert!((phi[2] - 6f64.sqrt() * (2.0 * s + t - 1.0)).abs() < 1e-15);
        }
        let big = TriangleBasis::of_order(6);
        let mut all = vec![0.0; big.n];
        for [s, t] in sample_points() {
            big.eval(s, t, &mut all);
            for m in 0..6 {
                let small = TriangleBasis::of_order(m);
                let mut v = vec![0.0; small.n];
                small.eval(s, t, &mut v);
                assert_eq!(v[..], all[..small.n]);
            }
        }
    }

    /// The basis of order m spans every monomial of degree ≤ m: its projection reproduces the
    /// monomial everywhere (with n = dim P_m orthonormal functions, the span is P_m). A monomial
    /// of degree m + 1 is not reproduced.
    #[test]
    fn spans_the_polynomials_of_degree_m() {
        for m in 0..=6 {
            let basis = TriangleBasis::of_order(m);
            let area = 0.37;
            let rule = TriangleRule::for_degree(2 * m + 2);
            for total in 0..=m as u32 + 1 {
                for a in 0..=total {
                    let b = total - a;
                    let c = basis.project(area, rule, |s, t| [monomial(s, t, a, b)]);
                    let worst = sample_points()
                        .iter()
                        .map(|&[s, t]| {
                            (basis.value(&c, area, s, t)[0] - monomial(s, t, a, b)).abs()
                        })
                        .fold(0.0, f64::max);
                    if total as usize <= m {
                        assert!(worst < 1e-12, "m={m} s^{a} t^{b}: {worst}");
                    } else {
                        assert!(worst > 1e-8, "m={m} reproduces s^{a} t^{b}");
                    }
                }
            }
        }
    }

    /// A parent polynomial and its push agree at every point of every child, on a triangle of
    /// any area (m = 0 … 6); `locate` finds the child and point that `to_parent` maps.
    #[test]
    fn push_is_exact() {
        let area = 2.75;
        for m in 0..=6 {
            let basis = TriangleBasis::of_order(m);
            let parent = some_coeffs(basis.n);
            let mut child = vec![[0.0; 3]; basis.n];
            for c in 0..4 {
                basis.push(&parent, c, &mut child);
                for [s, t] in sample_points() {
                    let [ps, pt] = to_parent(c, s, t);
                    let want = basis.value(&parent, area, ps, pt);
                    let got = basis.value(&child, area / 4.0, s, t);
                    for k in 0..3 {
                        let scale = 1.0 + want[k].abs();
                        assert!((got[k] - want[k]).abs() < 1e-12 * scale, "m={m} c={c}");
                    }
                    // interior points of a child come back to it
                    if s > 0.0 && t > 0.0 && s + t < 1.0 {
                        let (found, [ls, lt]) = locate(ps, pt);
                        assert_eq!(found, c);
                        assert!((ls - s).abs() < 1e-15 && (lt - t).abs() < 1e-15);
                    }
                }
            }
        }
    }

    /// [H⁰ H¹ H² H³] has orthonormal rows, and pulling the four pushes gives the parent back.
    #[test]
    fn push_then_pull_is_the_identity() {
        for m in 0..=6 {
            let basis = TriangleBasis::of_order(m);
            let n = basis.n;
            for j in 0..n {
                for l in 0..n {
                    let dot: f64 = (0..4)
                        .map(|c| {
                            (0..n)
                                .map(|i| basis.h[c][j * n + i] * basis.h[c][l * n + i])
                                .sum::<f64>()
                        })
                        .sum();
                    let want = if j == l { 1.0 } else { 0.0 };
                    assert!((dot - want).abs() < 1e-13, "m={m} rows {j},{l}: {dot}");
                }
            }
            let parent = some_coeffs(n);
            let mut child = vec![[0.0; 3]; n];
            let mut back = vec![[0.0; 3]; n];
            for c in 0..4 {
                basis.push(&parent, c, &mut child);
                basis.pull(&child, c, &mut back);
            }
            for (b, p) in back.iter().zip(&parent) {
                for k in 0..3 {
                    assert!((b[k] - p[k]).abs() < 1e-12 * (1.0 + p[k].abs()), "m={m}");
                }
            }
        }
    }

    /// The children's projections of a function, pulled, are the parent's projection of it.
    /// With a function that jumps across the children's edges, both sides integrate with the
    /// same points (a rule on each child), so they agree to rounding whatever the function.
    #[test]
    fn pull_of_the_childrens_projections_is_the_parents_projection() {
        let f = |s: f64, t: f64| -> [f64; 2] {
            let jump = if s + 0.8 * t > 0.41 { 1.0 } else { -0.5 };
            [
                jump + (s * t).sqrt(),
                (3.0 * s - t).exp() * (1.0 - s - t).sqrt(),
            ]
        };
        let area = 1.6;
        let rule = TriangleRule::for_degree(10);
        for m in 0..=5 {
            let basis = TriangleBasis::of_order(m);
            let n = basis.n;
            let mut pulled = vec![[0.0; 2]; n];
            let mut direct = vec![[0.0; 2]; n];
            let mut phi = vec![0.0; n];
            for c in 0..4 {
                let proj = basis.project(area / 4.0, rule, |s, t| {
                    let [ps, pt] = to_parent(c, s, t);
                    f(ps, pt)
                });
                basis.pull(&proj, c, &mut pulled);
                // ∫_{T_c} f ψ_j dA with the same points, mapped to the parent
                for (p, w) in rule.points.iter().zip(&rule.weights) {
                    let [ps, pt] = to_parent(c, p[0], p[1]);
                    basis.eval(ps, pt, &mut phi);
                    let v = f(ps, pt);
                    for j in 0..n {
                        for k in 0..2 {
                            direct[j][k] += area / 4.0 * w * v[k] * phi[j] / area.sqrt();
                        }
                    }
                }
            }
            for j in 0..n {
                for k in 0..2 {
                    let (a, b) = (pulled[j][k], direct[j][k]);
                    assert!(
                        (a - b).abs() < 1e-13 * (1.0 + b.abs()),
                        "m={m} j={j}: {a} vs {b}"
                    );
                }
            }
        }
    }

    /// For a smooth (analytic, non-polynomial) function, the pulled projections of the children
    /// equal the parent's projection by one rule on the whole triangle: the rules of degree 40
    /// both integrate it to rounding.
    #[test]
    fn pull_matches_a_direct_projection_of_a_smooth_function() {
        let f = |s: f64, t: f64| [(2.0 * s - t).exp() * (3.0 * s * t).cos()];
        let area = 0.8;
        let rule = TriangleRule::for_degree(40);
        for m in 0..=4 {
            let basis = TriangleBasis::of_order(m);
            let direct = basis.project(area, rule, f);
            let mut pulled = vec![[0.0]; basis.n];
            for c in 0..4 {
                let proj = basis.project(area / 4.0, rule, |s, t| {
                    let [ps, pt] = to_parent(c, s, t);
                    f(ps, pt)
                });
                basis.pull(&proj, c, &mut pulled);
            }
            for (a, b) in pulled.iter().zip(&direct) {
                assert!((a[0] - b[0]).abs() < 1e-13, "m={m}: {} vs {}", a[0], b[0]);
            }
        }
    }

    /// Vertex values are the values at the vertices; the mean is the rule's mean of the values;
    /// a parent's vertex is its corner child's same vertex after a push.
    #[test]
    fn vertices_and_mean() {
        let area = 5.0;
        for m in 0..=5 {
            let basis = TriangleBasis::of_order(m);
            let c = some_coeffs(basis.n);
            let at = basis.vertex_values(&c, area);
            for v in 0..3 {
                let want = basis.value(&c, area, VERTICES[v][0], VERTICES[v][1]);
                assert_eq!(at[v], want);
            }
            let mean = basis.mean(&c, area);
            let rule = TriangleRule::for_degree(m);
            for k in 0..3 {
                let want = rule.mean(|s, t| basis.value(&c, area, s, t)[k]);
                assert!((mean[k] - want).abs() < 1e-12 * (1.0 + want.abs()), "m={m}");
            }
            let mut child = vec![[0.0; 3]; basis.n];
            for v in 0..3 {
                basis.push(&c, v, &mut child);
                let got = basis.vertex_values(&child, area / 4.0)[v];
                for k in 0..3 {
                    assert!((got[k] - at[v][k]).abs() < 1e-12 * (1.0 + at[v][k].abs()));
                }
            }
        }
    }

    /// The split of a triangle in space: children of a quarter of the area, facing the parent's
    /// way, at the affine images of [`CHILDREN`], with shared midpoints equal to the bit.
    #[test]
    fn split_keeps_area_orientation_and_shared_edges() {
        let v = [[0.3, -1.2, 2.0], [2.9, 0.4, 1.1], [-0.7, 1.5, 3.3]];
        let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        let cross = |a: [f64; 3], b: [f64; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let normal = |w: &[[f64; 3]; 3]| cross(sub(w[1], w[0]), sub(w[2], w[0]));
        let np = normal(&v);
        let norm2 = |a: [f64; 3]| a.iter().map(|x| x * x).sum::<f64>();
        let children = split(&v);
        for (c, w) in children.iter().enumerate() {
            let nc = normal(w);
            // parallel, same way, a quarter of the length (twice the area)
            let dot: f64 = (0..3).map(|k| nc[k] * np[k]).sum();
            assert!(
                (dot - 0.25 * norm2(np)).abs() < 1e-12 * norm2(np),
                "child {c}"
            );
            assert!(norm2(cross(nc, np)) < 1e-24 * norm2(np) * norm2(np));
            for i in 0..3 {
                let [s, t] = CHILDREN[c][i];
                for k in 0..3 {
                    let want = v[0][k] + s * (v[1][k] - v[0][k]) + t * (v[2][k] - v[0][k]);
                    assert!((w[i][k] - want).abs() < 1e-15);
                }
                let [s, t] = VERTICES[i];
                assert_eq!(to_parent(c, s, t), CHILDREN[c][i]);
            }
        }
        // the neighbour across edge v1–v2, listed the other way round, has the same midpoint
        let other = split(&[v[2], v[1], [4.0, 4.0, 4.0]]);
        assert_eq!(other[0][1], children[1][2]);
    }
}
