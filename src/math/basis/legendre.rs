//! Orthonormal shifted Legendre polynomials on [0, 1]: φ_p(x) = √(2p+1) P_p(2x − 1),
//! so that ∫₀¹ φ_p φ_q = δ_pq. On a cell [c/n, (c+1)/n] of an interval of length L the
//! orthonormal (in arc length) basis function is φ_p(n x − c) √(n / L). These are the N_i of
//! the slides' projection, eq. (7): B_p = Σ ⟨B, Ñ_i⟩ N_i, with Ñ_i = N_i since they are
//! orthonormal.

/// Writes φ_0(x) … φ_m(x) into `out` (length m + 1), by the three-term recurrence
/// (p+1) P_{p+1}(u) = (2p+1) u P_p(u) − p P_{p−1}(u), u = 2x − 1.
#[inline]
pub(crate) fn legendre(x: f64, out: &mut [f64]) {
    let u = 2.0 * x - 1.0;
    let mut p_prev = 1.0;
    let mut p = u;
    for (k, o) in out.iter_mut().enumerate() {
        let value = match k {
            0 => 1.0,
            1 => u,
            _ => {
                let kf = (k - 1) as f64;
                let next = ((2.0 * kf + 1.0) * u * p - kf * p_prev) / (kf + 1.0);
                p_prev = p;
                p = next;
                next
            }
        };
        *o = value * ((2 * k + 1) as f64).sqrt();
    }
}

/// φ_p(1) = √(2p + 1).
pub(crate) fn legendre_at_one(p: usize) -> f64 {
    ((2 * p + 1) as f64).sqrt()
}

/// ∫_u φ_p φ_q over an interval u of [0, 1], exactly (Gauss with k points), `[p][q]` for
/// p, q < k: the Gram matrix of the first k polynomials on a part of their interval.
pub(crate) fn interval_gram(u: [f64; 2], k: usize) -> Vec<f64> {
    let rule = crate::math::quadrature::Rule::for_degree(2 * (k - 1));
    let mut phi = vec![0.0; k];
    let mut m = vec![0.0; k * k];
    for (x, w) in rule.mapped(u[0], u[1]) {
        legendre(x, &mut phi);
        for p in 0..k {
            for q in 0..k {
                m[p * k + q] += w * phi[p] * phi[q];
            }
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::quadrature::Rule;

    #[test]
    fn orthonormal_up_to_degree_20() {
        let m = 20;
        let rule = Rule::gauss(m + 1);
        let mut gram = vec![0.0; (m + 1) * (m + 1)];
        let mut v = vec![0.0; m + 1];
        for (x, w) in rule.mapped(0.0, 1.0) {
            legendre(x, &mut v);
            for p in 0..=m {
                for q in 0..=m {
                    gram[p * (m + 1) + q] += w * v[p] * v[q];
                }
            }
        }
        for p in 0..=m {
            for q in 0..=m {
                let want = if p == q { 1.0 } else { 0.0 };
                assert!((gram[p * (m + 1) + q] - want).abs() < 1e-13, "({p},{q})");
            }
        }
    }

    #[test]
    fn closed_forms() {
        let mut v = [0.0; 3];
        legendre(0.3, &mut v);
        assert_eq!(v[0], 1.0);
        assert!((v[1] - 3f64.sqrt() * (2.0 * 0.3 - 1.0)).abs() < 1e-15);
        let x: f64 = 0.3;
        assert!((v[2] - 5f64.sqrt() * (6.0 * x * x - 6.0 * x + 1.0)).abs() < 1e-15);
        let mut w = [0.0; 6];
        legendre(1.0, &mut w);
        for (p, wp) in w.iter().enumerate() {
            assert!((wp - legendre_at_one(p)).abs() < 1e-13);
        }
    }
}
