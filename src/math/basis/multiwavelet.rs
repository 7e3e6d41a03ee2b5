//! Alpert's Legendre multiwavelets of any order, built from their defining properties.
//!
//! Let V₀ be the polynomials of degree ≤ m on [0, 1) and V₁ the piecewise polynomials of degree
//! ≤ m on [0, ½) and [½, 1); k = m + 1. The wavelet space W₀ = V₁ ⊖ V₀ has dimension k. Alpert
//! (1993, §3) picks the orthonormal basis f₀ … f_{k−1} of W₀ with f_j ⟂ x^i for i < k + j: every
//! wavelet has k vanishing moments and f_j has j more. The flag of subspaces that this defines is
//! spanned by the projections onto W₀ of the Legendre polynomials P_k, P_{k+1}, … (a better
//! conditioned choice than the monomials, spanning the same flag), so a QR factorisation of those
//! projections, in order, gives f₀ … f_{k−1} up to sign. The sign is fixed by f_j(1⁻) > 0, which
//! reproduces the slides' LLMW and QLMW functions (with their ψ⁰ typo corrected).
//!
//! Everything is expressed in the orthonormal basis of V₁: χ_{L,q}(x) = √2 φ_q(2x) on [0, ½) and
//! χ_{R,q}(x) = √2 φ_q(2x − 1) on [½, 1). The two-scale filters are the coordinates of the
//! scaling functions (H) and the wavelets (G) in that basis; [H; G] is a 2k × 2k orthogonal
//! matrix (Alpert's eq. (3.9) and the "two-scale relations").

use super::legendre::{legendre, legendre_at_one};
use crate::math::quadrature::Rule;
use nalgebra::DMatrix;
use std::sync::{Mutex, OnceLock};

/// The two-scale filters of order m: rows of `h` and `g` are k × 2k, row-major, columns
/// `[χ_{L,0} … χ_{L,m}, χ_{R,0} … χ_{R,m}]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Filters {
    pub(crate) k: usize,
    pub(crate) h: Vec<f64>,
    pub(super) g: Vec<f64>,
}

impl Filters {
    /// The filters of order `m` (k = m + 1), computed once and cached.
    pub(crate) fn of_order(m: usize) -> &'static Filters {
        static CACHE: OnceLock<Mutex<Vec<Option<&'static Filters>>>> = OnceLock::new();
        let cache = CACHE.get_or_init(|| Mutex::new(Vec::new()));
        let mut c = cache.lock().unwrap_or_else(|e| e.into_inner());
        if c.len() <= m {
            c.resize(m + 1, None);
        }
        c[m].get_or_insert_with(|| Box::leak(Box::new(Filters::compute(m))))
    }

    fn compute(m: usize) -> Filters {
        let k = m + 1;
        // Quadrature exact for products of degree ≤ (2k − 1) + m on each half.
        let rule = Rule::for_degree(3 * k);
        let mut big = vec![0.0; 2 * k];
        let mut small = vec![0.0; k];
        // Inner products of a function f on [0,1] with the 2k basis functions χ of V₁.
        let coords = |f: &mut dyn FnMut(f64) -> f64| -> Vec<f64> {
            let mut out = vec![0.0; 2 * k];
            let mut v = vec![0.0; k];
            for half in 0..2 {
                let a = 0.5 * half as f64;
                for (x, w) in rule.mapped(a, a + 0.5) {
                    legendre(2.0 * x - half as f64, &mut v);
                    let fx = f(x);
                    for q in 0..k {
                        out[half * k + q] += w * fx * std::f64::consts::SQRT_2 * v[q];
                    }
                }
            }
            out
        };
        let mut h = Vec::with_capacity(k * 2 * k);
        for p in 0..k {
            h.extend(coords(&mut |x| {
                legendre(x, &mut small);
                small[p]
            }));
        }
        // The projections of P_k … P_{2k−1} onto V₁ lie in W₀ already: they are orthogonal to V₀.
        let mut a = DMatrix::<f64>::zeros(2 * k, k);
        for j in 0..k {
            let col = coords(&mut |x| {
                legendre(x, &mut big);
                big[k + j]
            });
            for (r, v) in col.iter().enumerate() {
                a[(r, j)] = *v;
            }
        }
        let q = a.qr().q();
        let mut g = Vec::with_capacity(k * 2 * k);
        for j in 0..k {
            let mut row: Vec<f64> = (0..2 * k).map(|r| q[(r, j)]).collect();
            // f_j(1⁻) = Σ_q g_{R,q} √2 φ_q(1)
            let at_one: f64 = (0..k)
                .map(|q| row[k + q] * std::f64::consts::SQRT_2 * legendre_at_one(q))
                .sum();
            if at_one < 0.0 {
                row.iter_mut().for_each(|v| *v = -*v);
            }
            g.extend(row);
        }
        Filters { k, h, g }
    }

    /// Value at x ∈ [0, 1) of the function whose V₁ coordinates are `row` (length 2k).
    fn eval_v1(&self, row: &[f64], x: f64) -> f64 {
        let k = self.k;
        let mut v = vec![0.0; k];
        let (half, local) = if x < 0.5 {
            (0, 2.0 * x)
        } else {
            (1, 2.0 * x - 1.0)
        };
        legendre(local, &mut v);
        (0..k)
            .map(|q| row[half * k + q] * std::f64::consts::SQRT_2 * v[q])
            .sum()
    }

    /// The mother wavelet ψ_j(x) on [0, 1).
    pub fn wavelet(&self, j: usize, x: f64) -> f64 {
        let k = self.k;
        self.eval_v1(&self.g[j * 2 * k..(j + 1) * 2 * k], x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ∫₀¹ f(x) g(x) dx for piecewise polynomials on the two halves, exactly.
    fn inner(f: impl Fn(f64) -> f64, g: impl Fn(f64) -> f64) -> f64 {
        let rule = Rule::gauss(24);
        rule.integrate(0.0, 0.5, |x| f(x) * g(x)) + rule.integrate(0.5, 1.0, |x| f(x) * g(x))
    }

    #[test]
    fn two_scale_matrix_is_orthogonal() {
        for m in 0..=8 {
            let f = Filters::of_order(m);
            let k = f.k;
            let rows: Vec<&[f64]> = f.h.chunks(2 * k).chain(f.g.chunks(2 * k)).collect();
            for (a, ra) in rows.iter().enumerate() {
                for (b, rb) in rows.iter().enumerate() {
                    let dot: f64 = ra.iter().zip(rb.iter()).map(|(x, y)| x * y).sum();
                    let want = if a == b { 1.0 } else { 0.0 };
                    assert!((dot - want).abs() < 1e-13, "m={m} rows {a},{b}: {dot}");
                }
            }
        }
    }

    #[test]
    fn wavelets_have_k_plus_j_vanishing_moments_and_unit_norm() {
        for m in 0..=6 {
            let f = Filters::of_order(m);
            let k = f.k;
            for j in 0..k {
                let psi = |x: f64| f.wavelet(j, x);
                let norm = inner(psi, psi);
                assert!((norm - 1.0).abs() < 1e-12, "m={m} j={j} norm {norm}");
                for i in 0..k + j {
                    // moments about the centre, better conditioned than about 0
                    let mom = inner(psi, |x| (x - 0.5).powi(i as i32));
                    assert!(mom.abs() < 1e-12, "m={m} j={j} moment {i}: {mom}");
                }
                // and not one more (f_{j+1} is the one with the extra moment)
                if j + 1 < k {
                    let next = inner(psi, |x| (x - 0.5).powi((k + j) as i32));
                    assert!(next.abs() > 1e-10, "m={m} j={j} moment {}: {next}", k + j);
                }
            }
        }
    }

    #[test]
    fn haar_is_the_slides_haar() {
        let f = Filters::of_order(0);
        assert!((f.wavelet(0, 0.25) + 1.0).abs() < 1e-14);
        assert!((f.wavelet(0, 0.75) - 1.0).abs() < 1e-14);
    }

    fn check_pieces(f: &Filters, j: usize, left: impl Fn(f64) -> f64, right: impl Fn(f64) -> f64) {
        for i in 0..50 {
            let x = (i as f64 + 0.5) / 100.0;
            assert!((f.wavelet(j, x) - left(x)).abs() < 1e-12, "ψ{j}({x})");
            let x = x + 0.5;
            assert!((f.wavelet(j, x) - right(x)).abs() < 1e-12, "ψ{j}({x})");
        }
    }

    /// The slides' LLMW, with ψ⁰ on [½, 1) corrected to √3(4x − 3).
    #[test]
    fn linear_legendre_multiwavelets_of_the_slides() {
        let f = Filters::of_order(1);
        let s3 = 3f64.sqrt();
        check_pieces(f, 0, |x| -s3 * (4.0 * x - 1.0), |x| s3 * (4.0 * x - 3.0));
        check_pieces(f, 1, |x| 6.0 * x - 1.0, |x| 6.0 * x - 5.0);
        // The slides' printed right half √3(4x − 1) is not orthogonal to constants:
        let printed = |x: f64| {
            if x < 0.5 {
                -s3 * (4.0 * x - 1.0)
            } else {
                s3 * (4.0 * x - 1.0)
            }
        };
        assert!(inner(printed, |_| 1.0).abs() > 0.5);
    }

    /// The slides' QLMW, all three printed correctly.
    #[test]
    fn quadratic_legendre_multiwavelets_of_the_slides() {
        let f = Filters::of_order(2);
        let s3 = 3f64.sqrt();
        let s5 = 5f64.sqrt();
        check_pieces(
            f,
            0,
            |x| -(120.0 * x * x - 72.0 * x + 7.0) / 3.0,
            |x| (120.0 * x * x - 168.0 * x + 55.0) / 3.0,
        );
        check_pieces(
            f,
            1,
            |x| s3 * (30.0 * x * x - 14.0 * x + 1.0),
            |x| s3 * (30.0 * x * x - 46.0 * x + 17.0),
        );
        check_pieces(
            f,
            2,
            |x| -s5 / 3.0 * (48.0 * x * x - 18.0 * x + 1.0),
            |x| s5 / 3.0 * (48.0 * x * x - 78.0 * x + 31.0),
        );
    }
}
