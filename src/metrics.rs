//! The slides' error measures and the energy balance.
//!
//! - Eq. (5), the relative error of the kernel projection, ∫∫(K − K̂)² / ∫∫K². With an
//!   orthonormal basis and K̂ = Σ_kept K_ij N_i N_j, ∫∫(K − K̂)² = ∫∫K² − Σ_kept K_ij², so only
//!   ∫∫K² needs a (finer) quadrature; it is taken over the pairs of surfaces that do not touch.
//! - Eq. (6), the relative error of B, ∫(B − B̂)² / ∫B², against an exact solution or a finer
//!   reference, integrated exactly piece by piece.
//! - Energy: emitted power ∫E against absorbed power ∫(1 − ρ)H, H = ∫K B the irradiance.

use crate::math::field::Field;
use crate::math::quadrature::Rule;
use crate::result::EnergyBalance;
use crate::scene::Rgb;

/// Eq. (5) from ∫∫K² and Σ_kept K_ij² (clamped at 0 against rounding).
pub(crate) fn kernel_relative_error(integral_k2: f64, kept_k2: f64) -> Option<f64> {
    (integral_k2 > 0.0).then(|| ((integral_k2 - kept_k2) / integral_k2).max(0.0))
}

/// [`l2_difference`] over a triangle patch: a triangle rule of degree 2m on both halves of
/// every cell of the common grid that lie in the triangle s + t ≤ 1 (measure ½ in (s, t)).
fn l2_difference_triangle(a: &Field, b: &Field, measure: f64) -> (f64, f64) {
    let res = a.res.max(b.res);
    let rule = crate::math::triangle::TriangleRule::for_degree(2 * a.order.max(b.order));
    let h = 1.0 / res as f64;
    let (mut diff, mut norm) = (0.0, 0.0);
    for ct in 0..res {
        for cs in 0..res - ct {
            for upper in [false, true] {
                if upper && cs + ct + 1 >= res {
                    continue;
                }
                for (p, w) in rule.points.iter().zip(&rule.weights) {
                    let (x, y) = if upper {
                        (
                            (cs + 1) as f64 * h - p[0] * h,
                            (ct + 1) as f64 * h - p[1] * h,
                        )
                    } else {
                        (cs as f64 * h + p[0] * h, ct as f64 * h + p[1] * h)
                    };
                    let (va, vb) = (a.eval(x, y), b.eval(x, y));
                    // each half-cell is h²/2 of the triangle's ½
                    let w = w * h * h;
                    for ch in 0..3 {
                        diff += w * (va[ch] - vb[ch]).powi(2);
                        norm += w * vb[ch] * vb[ch];
                    }
                }
            }
        }
    }
    (diff * measure, norm * measure)
}

/// (∫ Σ_c (a − b)², ∫ Σ_c b²) over a surface of the given measure, exact for the piecewise
/// polynomials on both grids: integrated on the common refinement of their finest grids.
pub fn l2_difference(a: &Field, b: &Field, measure: f64) -> (f64, f64) {
    if a.tri {
        return l2_difference_triangle(a, b, measure);
    }
    let res = lcm(a.res, b.res).min(1 << 14);
    let rule = Rule::for_degree(2 * a.order.max(b.order));
    let h = 1.0 / res as f64;
    let (mut diff, mut norm) = (0.0, 0.0);
    let rows = if a.dims == 2 { res } else { 1 };
    for r in 0..rows {
        for c in 0..res {
            let s = [c as f64 * h, (c + 1) as f64 * h];
            let t = if a.dims == 2 {
                [r as f64 * h, (r + 1) as f64 * h]
            } else {
                [0.0, 1.0]
            };
            let mut add = |x: f64, y: f64, w: f64| {
                let (va, vb) = (a.eval(x, y), b.eval(x, y));
                for ch in 0..3 {
                    diff += w * (va[ch] - vb[ch]).powi(2);
                    norm += w * vb[ch] * vb[ch];
                }
            };
            for (x, wx) in rule.mapped(s[0], s[1]) {
                if a.dims == 2 {
                    for (y, wy) in rule.mapped(t[0], t[1]) {
                        add(x, y, wx * wy);
                    }
                } else {
                    add(x, 0.0, wx);
                }
            }
        }
    }
    (diff * measure, norm * measure)
}

/// (∫ (exact − B̂)², ∫ exact²) for a 1D field on a domain of length `measure`, with a rule of
/// `m + 12` points on every cell (exact is not a polynomial).
pub(crate) fn l2_against(field: &Field, measure: f64, exact: impl Fn(f64) -> f64) -> (f64, f64) {
    let rule = Rule::gauss(field.order + 12);
    let (mut diff, mut norm) = (0.0, 0.0);
    for leaf in &field.leaves {
        for (s, w) in rule.mapped(leaf.s[0], leaf.s[1]) {
            let e = exact(s);
            let v = field.eval_leaf(leaf, s, 0.0)[0];
            diff += w * (e - v).powi(2);
            norm += w * e * e;
        }
    }
    (diff * measure, norm * measure)
}

/// Emitted and absorbed power per channel from the fields of E and H and the surfaces' ρ.
/// Absorbed is what the fronts absorb, (1 − ρ) ∫ H: light that leaves an open scene or falls
/// on the (black) back of a surface is not in it, so the ratio is 1 only in a closed scene
/// whose backs no light reaches.
pub(crate) fn energy(
    emission: &[Field],
    irradiance: &[Field],
    rho: &[Rgb],
    measure: &[f64],
) -> EnergyBalance {
    let mut emitted = [0.0; 3];
    let mut absorbed = [0.0; 3];
    for i in 0..emission.len() {
        let e = emission[i].mean();
        let h = irradiance[i].mean();
        for c in 0..3 {
            emitted[c] += e[c] * measure[i];
            absorbed[c] += (1.0 - rho[i][c]) * h[c] * measure[i];
        }
    }
    let balance = [0, 1, 2].map(|c| {
        if emitted[c] > 0.0 {
            absorbed[c] / emitted[c]
        } else {
            0.0
        }
    });
    EnergyBalance {
        emitted,
        absorbed,
        balance,
    }
}

fn lcm(a: usize, b: usize) -> usize {
    fn gcd(a: usize, b: usize) -> usize {
        if b == 0 {
            a
        } else {
            gcd(b, a % b)
        }
    }
    a / gcd(a, b) * b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn l2_of_a_constant_against_a_linear_field() {
        // a = 1 on one cell, b = s on 4 cells (order 1); ∫(1 − s)² = 1/3, ∫s² = 1/3
        let a = Field::uniform_line(0, 1, &[[1.0; 3]]);
        let h = 0.25;
        let local: Vec<[f64; 3]> = (0..4)
            .flat_map(|c| [[(c as f64 + 0.5) * h; 3], [h / (2.0 * 3f64.sqrt()); 3]])
            .collect();
        let b = Field::uniform_line(1, 4, &local);
        let (d, n) = l2_difference(&a, &b, 2.0);
        assert!((d - 3.0 * 2.0 / 3.0).abs() < 1e-14);
        assert!((n - 3.0 * 2.0 / 3.0).abs() < 1e-14);
        let (d, n) = l2_against(&b, 1.0, |s| s);
        assert!(d < 1e-28 && (n - 1.0 / 3.0).abs() < 1e-15);
    }
}
