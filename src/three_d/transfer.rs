//! The Galerkin transfer between two pieces of parallelograms, the slides' eq. (11) in 3D:
//! T_ij = ∫_a ∫_b K(x, y) N_i(x) N_j(y) dy dx with K = cosθx cosθy / (π r²) of eq. (3) (without
//! V: the callers scale by a visibility estimate) and N the tensor shifted-Legendre functions of
//! order m on each piece, orthonormal in area: N = φ_p(ŝ) φ_q(t̂) / √A.
//!
//! Far pairs (distance ≥ the larger diameter) take a tensor Gauss rule whose order follows the
//! separation (`points`). Near pairs (shared edges of a room, a box standing on the floor) are
//! integrated as an outer rule over `a`, split adaptively toward `b` along the axis over which
//! the distance changes (strips toward a shared edge), and an inner integral over `b` for each
//! outer point, split as a quadtree around the point. Both recursions stop at a depth limit,
//! which bounds the cost and the error next to the singular edge.

use crate::math::basis::legendre;
use crate::math::quadrature::Rule;
use crate::math::triangle::{TriangleBasis, TriangleRule};
use crate::three_d::geometry::Piece;
use crate::three_d::geometry::{
    centroid, cross, dot, norm, point_quad, quad_quad, sub, Parallelogram, V3,
};

/// Largest k = m + 1 (the document allows m ≤ 8) and Gauss rule handled on the stack.
pub(super) const MAX_K: usize = 9;
const MAX_Q: usize = 16;

/// How hard to work.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Accuracy {
    /// Fewest Gauss points per direction.
    pub(super) q_min: usize,
    /// Decimal digits the far-field rules aim at.
    pub(super) digits: f64,
    /// Deepest split of the outer piece toward a near target, and of the inner piece around a
    /// point.
    pub(super) outer_depth: u32,
    pub(super) inner_depth: u32,
}

impl Accuracy {
    /// Close to machine precision (closed-form checks, the projection method).
    #[cfg(test)]
    pub(crate) fn fine(q_min: usize) -> Accuracy {
        Accuracy {
            q_min,
            digits: 13.0,
            outer_depth: 18,
            inner_depth: 24,
        }
    }
    /// A few digits (the links of the hierarchical method, which an oracle already bounds:
    /// 1e-4 of a link is far below the tolerance of the oracle; six digits cost a third more
    /// and moved no cell mean of the Cornell box by 1e-4).
    pub(super) fn coarse(q_min: usize) -> Accuracy {
        Accuracy {
            q_min,
            digits: 4.0,
            outer_depth: 3,
            inner_depth: 0,
        }
    }
}

/// Gauss points per direction for a pair at distance `dist` of size `size`: the error of a
/// q-point rule decays like ρ^(−2q), ρ the Bernstein ellipse parameter of the separation.
fn points(dist: f64, size: f64, digits: f64) -> usize {
    let a = 1.0 + 2.0 * dist / size.max(1e-300);
    let rho = a + (a * a - 1.0).max(0.0).sqrt();
    (digits * std::f64::consts::LN_10 / (2.0 * rho.ln()))
        .ceil()
        .clamp(1.0, MAX_Q as f64) as usize
}

/// What to integrate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Integrand {
    /// K N_i N_j, a k² × k² block (row = a's `q·k + p`, column = b's).
    Galerkin { k: usize },
    /// K², one number (the denominator of eq. (5)), over the pieces' areas.
    Squared,
}

/// Adds the transfer from `b` to `a` to `out` (k² × k² for Galerkin, 1 for Squared).
/// Returns the number of kernel evaluations (a closed-form point-to-polygon form factor
/// counts as one).
pub(super) fn block(
    quads: &[Parallelogram],
    a: Piece,
    b: Piece,
    what: Integrand,
    acc: Accuracy,
    out: &mut [f64],
) -> u64 {
    let (qa, qb) = (&quads[a.surface], &quads[b.surface]);
    // a triangle piece is half of its square of parameters, and its triangle half of the
    // parallelogram: its area is area · ds · dt either way
    let area = |q: &Parallelogram, p: &Piece| q.area * (p.s[1] - p.s[0]) * (p.t[1] - p.t[0]);
    // the rules integrate over (s, t); dA = jac ds dt
    let (k, scale) = match what {
        Integrand::Galerkin { k } => {
            assert!(k <= MAX_K);
            (k, qa.jac * qb.jac / (area(qa, &a) * area(qb, &b)).sqrt())
        }
        Integrand::Squared => (1, qa.jac * qb.jac),
    };
    let ctx = Ctx {
        qa,
        qb,
        a,
        b,
        k,
        squared: what == Integrand::Squared,
        acc,
        scale,
        evaluations: std::cell::Cell::new(0),
        tri_basis: (qa.tri || qb.tri).then(|| TriangleBasis::of_order(k - 1)),
        samples: std::cell::RefCell::new(Vec::new()),
    };
    ctx.pair(Rect::of(qa, a), Rect::of(qb, b), 0, out);
    ctx.evaluations.get()
}

/// A part of a piece over which a rule runs: a rectangle of parameters, or on a triangle
/// patch the half of one that a triangle piece is ([`Piece`]).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Rect {
    s: [f64; 2],
    t: [f64; 2],
    tri: bool,
    upper: bool,
}

impl Rect {
    fn of(q: &Parallelogram, p: Piece) -> Rect {
        Rect {
            s: p.s,
            t: p.t,
            tri: q.tri,
            upper: p.upper,
        }
    }

    fn piece(&self) -> Piece {
        Piece {
            surface: 0,
            s: self.s,
            t: self.t,
            upper: self.upper,
        }
    }

    /// Four parts: the quarters of a rectangle (s first), the midpoint split of a triangle.
    fn quarters(&self) -> [Rect; 4] {
        if self.tri {
            return std::array::from_fn(|c| {
                let p = self.piece().tri_child(c);
                Rect {
                    s: p.s,
                    t: p.t,
                    tri: true,
                    upper: p.upper,
                }
            });
        }
        let [a, b] = self.halves_s();
        let [a0, a1] = a.halves_t();
        let [b0, b1] = b.halves_t();
        [a0, a1, b0, b1]
    }

    /// The points (s, t) and weights (in ds dt) of a rule of q × q points: tensor Gauss on a
    /// rectangle (exact to degree 2q − 1 in each variable), the collapsed rule of degree
    /// 2q − 2 on a triangle (also q² points).
    fn rule(&self, q: usize, mut f: impl FnMut(f64, f64, f64)) {
        if self.tri {
            let h = self.s[1] - self.s[0];
            let measure = 0.5 * h * h;
            let rule = TriangleRule::for_degree(2 * q - 2);
            let p = self.piece();
            for (x, w) in rule.points.iter().zip(&rule.weights) {
                let (s, t) = p.at_local(x[0], x[1]);
                f(s, t, w * measure);
            }
            return;
        }
        let rule = Rule::gauss(q);
        for (t, wt) in rule.mapped(self.t[0], self.t[1]) {
            for (s, ws) in rule.mapped(self.s[0], self.s[1]) {
                f(s, t, ws * wt);
            }
        }
    }

    /// The point of the part nearest to (s, t) in parameters (on a triangle, near enough:
    /// clamped to its square, then pulled onto its diagonal).
    fn clamp(&self, s: f64, t: f64) -> (f64, f64) {
        let (s, t) = (s.clamp(self.s[0], self.s[1]), t.clamp(self.t[0], self.t[1]));
        if !self.tri {
            return (s, t);
        }
        let p = self.piece();
        let (u, v) = p.local(s, t);
        if u + v <= 1.0 {
            return (s, t);
        }
        p.at_local(u / (u + v), v / (u + v))
    }

    fn halves_s(&self) -> [Rect; 2] {
        let m = 0.5 * (self.s[0] + self.s[1]);
        [
            Rect {
                s: [self.s[0], m],
                ..*self
            },
            Rect {
                s: [m, self.s[1]],
                ..*self
            },
        ]
    }
    fn halves_t(&self) -> [Rect; 2] {
        let m = 0.5 * (self.t[0] + self.t[1]);
        [
            Rect {
                t: [self.t[0], m],
                ..*self
            },
            Rect {
                t: [m, self.t[1]],
                ..*self
            },
        ]
    }
}

struct Ctx<'a> {
    qa: &'a Parallelogram,
    qb: &'a Parallelogram,
    a: Piece,
    b: Piece,
    k: usize,
    squared: bool,
    acc: Accuracy,
    scale: f64,
    evaluations: std::cell::Cell<u64>,
    /// The basis of a triangle piece, when there is one.
    tri_basis: Option<&'static TriangleBasis>,
    /// Rule points on pieces of `b` with the basis there, by (piece, q): the far rule and the
    /// inner integral of every outer point use the same few.
    samples: std::cell::RefCell<Vec<Samples>>,
}

/// A q × q Gauss rule on a piece of `b`: its points and the basis there times the weights.
struct Samples {
    rect: Rect,
    q: usize,
    /// The points' coordinates, one array each (so that the kernel loop vectorizes).
    points: [Vec<f64>; 3],
    weights: Vec<f64>,
    /// `weights[j] · N_c(points[j])`, row j.
    phi: Vec<f64>,
}

/// How many pieces' samples a block keeps: the far rules and the inner integrals of a near
/// pair need a few; a fine inner quadtree around each point would only churn a longer list.
const KEPT_SAMPLES: usize = 8;

fn corners(q: &Parallelogram, r: Rect) -> [V3; 4] {
    if r.tri {
        let [a, b, c] = r.piece().triangle().map(|p| q.at(p[0], p[1]));
        return [a, b, c, c];
    }
    q.piece(r.s, r.t)
}

/// The longer diagonal of a parallelogram given by its corners; the longest side of a
/// triangle (its third corner repeated).
pub(super) fn diameter(c: &[V3; 4]) -> f64 {
    if c[2] == c[3] {
        return norm(sub(c[1], c[0]))
            .max(norm(sub(c[2], c[0])))
            .max(norm(sub(c[2], c[1])));
    }
    norm(sub(c[2], c[0])).max(norm(sub(c[3], c[1])))
}

/// A ball around a piece given by its corners: (centre, radius).
fn ball(c: &[V3; 4]) -> (V3, f64) {
    if c[2] == c[3] {
        let m = centroid(c, true);
        let r = (0..3).map(|i| norm(sub(c[i], m))).fold(0.0, f64::max);
        return (m, r);
    }
    (centroid(c, false), 0.5 * diameter(c))
}

impl Ctx<'_> {
    /// Basis values of piece `a` (or `b`) at parameter (s, t), times `w`, into `out[..k²]`.
    fn basis(&self, of_a: bool, s: f64, t: f64, w: f64, out: &mut [f64]) {
        let k = self.k;
        let p = if of_a { &self.a } else { &self.b };
        let tri = if of_a { self.qa.tri } else { self.qb.tri };
        if let Some(basis) = self.tri_basis.filter(|_| tri) {
            // the orthonormal polynomials of total degree < k, the rest of the k² slots zero
            let n = crate::math::triangle::dimension(k - 1);
            let (u, v) = p.local(s, t);
            basis.eval(u, v, &mut out[..n]);
            out[..n].iter_mut().for_each(|x| *x *= w);
            out[n..k * k].fill(0.0);
            return;
        }
        let mut ps = [0.0; MAX_K];
        let mut pt = [0.0; MAX_K];
        legendre((s - p.s[0]) / (p.s[1] - p.s[0]), &mut ps[..k]);
        legendre((t - p.t[0]) / (p.t[1] - p.t[0]), &mut pt[..k]);
        for q in 0..k {
            for r in 0..k {
                out[q * k + r] = w * pt[q] * ps[r];
            }
        }
    }

    /// Far apart: a tensor rule. Near but apart: both pieces split in four, until the sixteen
    /// pairs are far relative to their size. Touching (or nearly): outer and inner integrals.
    fn pair(&self, ra: Rect, rb: Rect, depth: u32, out: &mut [f64]) {
        let ca = corners(self.qa, ra);
        let cb = corners(self.qb, rb);
        let size = diameter(&ca).max(diameter(&cb));
        // most pairs are far enough that their fewest points do, which a lower bound of the
        // distance (between the pieces' enclosing balls) shows without the exact distance
        let ((ma, ra_), (mb, rb_)) = (ball(&ca), ball(&cb));
        let below = norm(sub(ma, mb)) - ra_ - rb_;
        if below >= size && points(below, size, self.acc.digits) <= self.acc.q_min {
            return self.far(ra, rb, self.acc.q_min.min(MAX_Q), out);
        }
        let dist = quad_quad(&ca, self.qa.n, &cb, self.qb.n);
        if dist >= size {
            let q = points(dist, size, self.acc.digits)
                .max(self.acc.q_min)
                .min(MAX_Q);
            self.far(ra, rb, q, out);
        } else if dist > 0.5 * size && depth < 2 {
            for a in ra.quarters() {
                for b in rb.quarters() {
                    self.pair(a, b, depth + 1, out);
                }
            }
        } else {
            self.outer(ra, rb, &cb, 0, out);
        }
    }

    /// The samples of `rb` at q × q points, made once per block.
    fn with_samples<R>(&self, rb: Rect, q: usize, f: impl FnOnce(&Samples) -> R) -> R {
        let same = |x: &Samples| x.q == q && x.rect == rb;
        if let Some(hit) = self.samples.borrow().iter().find(|x| same(x)) {
            return f(hit);
        }
        let kk = self.k * self.k;
        let mut made = Samples {
            rect: rb,
            q,
            points: std::array::from_fn(|_| Vec::with_capacity(q * q)),
            weights: Vec::with_capacity(q * q),
            phi: vec![0.0; q * q * kk],
        };
        rb.rule(q, |s, t, w| {
            let n = made.weights.len();
            self.basis(false, s, t, w, &mut made.phi[n * kk..(n + 1) * kk]);
            let y = self.qb.at(s, t);
            (0..3).for_each(|i| made.points[i].push(y[i]));
            made.weights.push(w);
        });
        let out = f(&made);
        let mut kept = self.samples.borrow_mut();
        if kept.len() < KEPT_SAMPLES {
            kept.push(made);
        }
        out
    }

    /// K(x, y_j) for every sample point, without a branch (so that the loop vectorizes);
    /// squared for [`Integrand::Squared`].
    fn kernels(&self, x: V3, points: &[Vec<f64>; 3], out: &mut [f64]) {
        let (na, nb) = (self.qa.n, self.qb.n);
        let [px, py, pz] = points;
        let n = out.len();
        for (j, k) in out.iter_mut().enumerate() {
            *k = kernel(x, na, [px[j], py[j], pz[j]], nb);
        }
        if self.squared {
            out.iter_mut().for_each(|k| *k *= *k);
        }
        self.evaluations.set(self.evaluations.get() + n as u64);
    }

    /// Tensor rule: q² points on each piece.
    fn far(&self, ra: Rect, rb: Rect, q: usize, out: &mut [f64]) {
        let kk = self.k * self.k;
        self.with_samples(rb, q, |b| {
            let mut kv = [0.0; MAX_Q * MAX_Q];
            let kv = &mut kv[..b.weights.len()];
            let mut phi_a = [0.0; MAX_K * MAX_K];
            let mut tmp = [0.0; MAX_K * MAX_K];
            ra.rule(q, |s, t, w| {
                self.kernels(self.qa.at(s, t), &b.points, kv);
                tmp[..kk].fill(0.0);
                for (kj, phi) in kv.iter().zip(b.phi.chunks_exact(kk)) {
                    for c in 0..kk {
                        tmp[c] += kj * phi[c];
                    }
                }
                self.basis(true, s, t, w * self.scale, &mut phi_a[..kk]);
                for r in 0..kk {
                    for c in 0..kk {
                        out[r * kk + c] += phi_a[r] * tmp[c];
                    }
                }
            });
        })
    }

    /// The outer integral over `ra`, split toward `rb` where the distance changes.
    fn outer(&self, ra: Rect, rb: Rect, cb: &[V3; 4], depth: u32, out: &mut [f64]) {
        let ca = corners(self.qa, ra);
        let dist = |r: &Rect| quad_quad(&corners(self.qa, *r), self.qa.n, cb, self.qb.n);
        // distance to the nearest corner of the target: the integrand also varies fast next
        // to the ends of a shared edge
        let vertex = |r: &Rect| {
            let c = corners(self.qa, *r);
            cb.iter()
                .map(|v| point_quad(*v, &c, self.qa.n))
                .fold(f64::INFINITY, f64::min)
        };
        let d = quad_quad(&ca, self.qa.n, cb, self.qb.n);
        if ra.tri {
            // a triangle is split in four while the target is nearer than it is wide
            let size = diameter(&ca);
            if depth < self.acc.outer_depth && (d < size || vertex(&ra) < size) {
                return self.quarters(ra, rb, cb, depth, out);
            }
            return self.outer_rule(ra, rb, d, size, out);
        }
        let dv = vertex(&ra);
        let ext_s = norm(sub(ca[1], ca[0]));
        let ext_t = norm(sub(ca[3], ca[0]));
        if depth < self.acc.outer_depth && (d < ext_s || d < ext_t) {
            let hs = ra.halves_s();
            let ht = ra.halves_t();
            let toward = |h: &[Rect; 2], near: f64, ext: f64, f: &dyn Fn(&Rect) -> f64| {
                near < ext && (f(&h[0]) - f(&h[1])).abs() > 0.1 * ext
            };
            let split_s = toward(&hs, d, ext_s, &dist) || dv < ext_s;
            let split_t = toward(&ht, d, ext_t, &dist) || dv < ext_t;
            // neither half is farther, yet the target is closer than the piece is wide: it
            // meets the piece's interior (a box standing on a floor cell)
            let inside = d < ext_s.min(ext_t);
            match (split_s, split_t) {
                (true, false) => {
                    return hs
                        .iter()
                        .for_each(|r| self.outer(*r, rb, cb, depth + 1, out))
                }
                (false, true) => {
                    return ht
                        .iter()
                        .for_each(|r| self.outer(*r, rb, cb, depth + 1, out))
                }
                (true, true) => return self.quarters(ra, rb, cb, depth, out),
                (false, false) if inside => return self.quarters(ra, rb, cb, depth, out),
                (false, false) => {}
            }
        }
        self.outer_rule(ra, rb, d, ext_s.max(ext_t), out)
    }

    /// The outer rule over `ra` at distance `d` from `rb`, each point with its inner integral.
    fn outer_rule(&self, ra: Rect, rb: Rect, d: f64, size: f64, out: &mut [f64]) {
        let kk = self.k * self.k;
        let q = points(d, size, self.acc.digits)
            .max(self.acc.q_min)
            .clamp(2, 6);
        let mut tmp = [0.0; MAX_K * MAX_K];
        let mut phi_a = [0.0; MAX_K * MAX_K];
        ra.rule(q, |s, t, w| {
            let x = self.qa.at(s, t);
            if self.qb.side(x) <= 0.0 {
                return;
            }
            tmp[..kk].fill(0.0);
            self.inner_subtracted(x, rb, &mut tmp[..kk]);
            self.basis(true, s, t, w * self.scale, &mut phi_a[..kk]);
            for r in 0..kk {
                for c in 0..kk {
                    out[r * kk + c] += phi_a[r] * tmp[c];
                }
            }
        });
    }

    fn quarters(&self, ra: Rect, rb: Rect, cb: &[V3; 4], depth: u32, out: &mut [f64]) {
        for r in ra.quarters() {
            self.outer(r, rb, cb, depth + 1, out);
        }
    }

    /// ∫_rb K(x, y) N_j(y) dy with the singularity subtracted: N_j(y0) ∫ K (the point-to-
    /// polygon form factor in closed form) plus ∫ K (N_j(y) − N_j(y0)), whose integrand vanishes
    /// at y0, the point of the piece nearest x; for order 0 the first term is all.
    fn inner_subtracted(&self, x: V3, rb: Rect, out: &mut [f64]) {
        if self.squared {
            return self.inner(x, rb, 0, None, out);
        }
        let cb = corners(self.qb, rb);
        self.evaluations.set(self.evaluations.get() + 1);
        let f = point_polygon(x, self.qa.n, &cb) / self.qb.jac;
        let kk = self.k * self.k;
        let (s, t) = self.qb.params(x);
        let (s, t) = rb.clamp(s, t);
        let mut base = [0.0; MAX_K * MAX_K];
        self.basis(false, s, t, 1.0, &mut base[..kk]);
        for c in 0..kk {
            out[c] += f * base[c];
        }
        if self.k > 1 {
            self.inner(x, rb, 0, Some(&base[..kk]), out);
        }
    }

    /// ∫_rb K(x, y) (N_j(y) − base_j) dy, split as a quadtree around x.
    fn inner(&self, x: V3, rb: Rect, depth: u32, base: Option<&[f64]>, out: &mut [f64]) {
        let cb = corners(self.qb, rb);
        let diam = diameter(&cb);
        let d = point_quad(x, &cb, self.qb.n);
        if d < diam && depth < self.acc.inner_depth {
            for r in rb.quarters() {
                self.inner(x, r, depth + 1, base, out);
            }
            return;
        }
        let kk = self.k * self.k;
        // at the depth limit the piece is still near x: what is left is a small part of the
        // integral, which a modest rule takes
        let q = if d < diam {
            self.acc.q_min.max(4)
        } else {
            points(d, diam, self.acc.digits).max(self.acc.q_min)
        }
        .min(MAX_Q);
        self.with_samples(rb, q, |b| {
            let mut kv = [0.0; MAX_Q * MAX_Q];
            let kv = &mut kv[..b.weights.len()];
            self.kernels(x, &b.points, kv);
            for (kj, phi) in kv.iter().zip(b.phi.chunks_exact(kk)) {
                for c in 0..kk {
                    out[c] += kj * phi[c];
                }
            }
            // minus base_j ∫ K: the subtracted value at the point nearest x
            if let Some(base) = base {
                let sum: f64 = kv.iter().zip(&b.weights).map(|(k, w)| k * w).sum();
                for c in 0..kk {
                    out[c] -= sum * base[c];
                }
            }
        })
    }
}

/// The slides' eq. (3) without V: K(x, y) = cosθx cosθy / (π r²) for points x, y with unit
/// front normals nx, ny; zero unless y is in front of x and x in front of y. Without a branch
/// (the cosines clamped at zero), so that the loops over sample points vectorise.
#[inline(always)]
pub(super) fn kernel(x: V3, nx: V3, y: V3, ny: V3) -> f64 {
    let r = [y[0] - x[0], y[1] - x[1], y[2] - x[2]];
    let cx = (r[0] * nx[0] + r[1] * nx[1] + r[2] * nx[2]).max(0.0);
    let cy = (-(r[0] * ny[0] + r[1] * ny[1] + r[2] * ny[2])).max(0.0);
    let r2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
    cx * cy / (std::f64::consts::PI * r2 * r2)
}

/// The form factor from a point x with normal n to a convex polygon facing it, in closed form
/// (Lambert 1760; Baum, Rushmeier and Winget 1989, eq. (3)): (1/2π) Σ γ_i n·(R_i × R_i+1)/|…|,
/// R_i the vectors to the vertices and γ_i the angles between them. The polygon is first clipped
/// to the half-space in front of x.
pub(super) fn point_polygon(x: V3, n: V3, poly: &[V3; 4]) -> f64 {
    let mut clipped: smallvec::SmallVec<[V3; 8]> = smallvec::SmallVec::new();
    for i in 0..4 {
        let (a, b) = (sub(poly[i], x), sub(poly[(i + 1) % 4], x));
        let (da, db) = (dot(a, n), dot(b, n));
        if da > 0.0 {
            clipped.push(a);
        }
        if (da > 0.0) != (db > 0.0) {
            let t = da / (da - db);
            clipped.push([
                a[0] + t * (b[0] - a[0]),
                a[1] + t * (b[1] - a[1]),
                a[2] + t * (b[2] - a[2]),
            ]);
        }
    }
    let m = clipped.len();
    if m < 3 {
        return 0.0;
    }
    let mut sum = 0.0;
    for i in 0..m {
        let (a, b) = (clipped[i], clipped[(i + 1) % m]);
        let c = cross(a, b);
        let lc = norm(c);
        if lc > 0.0 {
            sum += lc.atan2(dot(a, b)) * dot(n, c) / lc;
        }
    }
    sum.abs() / (2.0 * std::f64::consts::PI)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernel_is_one_sided_and_symmetric() {
        let (up, down) = ([0.0, 0.0, 1.0], [0.0, 0.0, -1.0]);
        let (x, y) = ([0.0; 3], [0.0, 0.0, 2.0]);
        // two points facing each other at distance 2: 1 / (π · 4)
        assert_eq!(kernel(x, up, y, down), 1.0 / (4.0 * std::f64::consts::PI));
        assert_eq!(kernel(x, down, y, down), 0.0);
        assert_eq!(kernel(x, up, y, up), 0.0);
        assert_eq!(kernel(y, down, x, up), kernel(x, up, y, down));
    }
    use std::f64::consts::PI;

    fn unit(corners: [V3; 4]) -> Parallelogram {
        Parallelogram::new(&corners)
    }

    /// Howell's C-11: directly opposed parallel rectangles a × b at distance c.
    fn parallel_opposed(a: f64, b: f64, c: f64) -> f64 {
        let (x, y) = (a / c, b / c);
        let (x1, y1) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
        2.0 / (PI * x * y)
            * (((1.0 + x * x) * (1.0 + y * y) / (1.0 + x * x + y * y))
                .sqrt()
                .ln()
                + x * y1 * (x / y1).atan()
                + y * x1 * (y / x1).atan()
                - x * x.atan()
                - y * y.atan())
    }

    /// Howell's C-14: perpendicular rectangles with a common edge of length l, widths w (the
    /// emitter) and h: F from the w × l rectangle to the h × l one.
    fn perpendicular_common_edge(w: f64, h: f64, l: f64) -> f64 {
        let (hh, ww) = (h / l, w / l);
        let a = (1.0 + hh * hh) * (1.0 + ww * ww) / (1.0 + hh * hh + ww * ww);
        let b = ww * ww * (1.0 + hh * hh + ww * ww) / ((1.0 + ww * ww) * (hh * hh + ww * ww));
        let c = hh * hh * (1.0 + hh * hh + ww * ww) / ((1.0 + hh * hh) * (hh * hh + ww * ww));
        1.0 / (PI * ww)
            * (ww * (1.0 / ww).atan() + hh * (1.0 / hh).atan()
                - (hh * hh + ww * ww).sqrt() * (1.0 / (hh * hh + ww * ww).sqrt()).atan()
                + 0.25 * (a * b.powf(ww * ww) * c.powf(hh * hh)).ln())
    }

    fn form_factor(quads: &[Parallelogram]) -> f64 {
        let mut out = [0.0];
        block(
            quads,
            Piece::whole(0),
            Piece::whole(1),
            Integrand::Galerkin { k: 1 },
            Accuracy::fine(4),
            &mut out,
        );
        // T = ∫∫K / √(A_a A_b) = F_ab √(A_a / A_b)
        out[0] * (quads[1].area / quads[0].area).sqrt()
    }

    #[test]
    fn parallel_unit_squares_match_c11() {
        let floor = unit([
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ]);
        for c in [0.25, 1.0, 3.0] {
            let top = unit([[0.0, 0.0, c], [0.0, 1.0, c], [1.0, 1.0, c], [1.0, 0.0, c]]);
            let f = form_factor(&[floor, top]);
            let want = parallel_opposed(1.0, 1.0, c);
            assert!((f - want).abs() < 1e-8, "c={c}: {f} vs {want}");
        }
        assert!((parallel_opposed(1.0, 1.0, 1.0) - 0.199825).abs() < 1e-6);
    }

    #[test]
    fn perpendicular_unit_squares_match_c14() {
        let floor = unit([
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ]);
        let wall = unit([
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [1.0, 0.0, 0.0],
        ]);
        let f = form_factor(&[floor, wall]);
        let want = perpendicular_common_edge(1.0, 1.0, 1.0);
        assert!((want - 0.200044).abs() < 1e-6, "{want}");
        assert!((f - want).abs() < 1e-6, "{f} vs {want}");
    }

    #[test]
    fn reciprocity_of_linear_blocks() {
        // T_ab = T_baᵀ for any order, near or far
        let floor = unit([
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ]);
        let wall = unit([
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [1.0, 0.0, 0.0],
        ]);
        let quads = [floor, wall];
        let (a, b) = (
            Piece::whole(0),
            Piece {
                upper: false,
                surface: 1,
                s: [0.0, 0.5],
                t: [0.5, 1.0],
            },
        );
        let mut ab = [0.0; 16];
        let mut ba = [0.0; 16];
        block(
            &quads,
            a,
            b,
            Integrand::Galerkin { k: 2 },
            Accuracy::fine(4),
            &mut ab,
        );
        block(
            &quads,
            b,
            a,
            Integrand::Galerkin { k: 2 },
            Accuracy::fine(4),
            &mut ba,
        );
        for r in 0..4 {
            for c in 0..4 {
                assert!(
                    (ab[r * 4 + c] - ba[c * 4 + r]).abs() < 1e-6,
                    "{r},{c}: {} {}",
                    ab[r * 4 + c],
                    ba[c * 4 + r]
                );
            }
        }
    }
}
