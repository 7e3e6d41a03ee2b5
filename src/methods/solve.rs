//! Iterative solution of the slides' eq. (12), B = E + KB, i.e. (I − ρK) B = E, for the three
//! channels at once, with K sparse.
//!
//! - Jacobi (the slides' "Implementation of Algorithm"): B⁺_i = (E_i + ρ_i Σ_{j≠i} K_ij B_j) /
//!   (1 − ρ_i K_ii), rows in parallel. When K has no diagonal (planar patches in the scaling
//!   basis) this is the slides' B⁺ = E + ρKB.
//! - Gauss–Seidel: the same sweep using each new value at once.
//!
//! Both stop when the relative change ‖B⁺ − B‖ / ‖B⁺‖ falls below `tolerance` or after
//! `max_iterations` sweeps, and fail on NaN or growth instead of returning garbage.

use crate::methods::operator::Operator;
use crate::progress::{Cancelled, Phase, Progress};
use crate::scene::{Iteration, Rgb};
use rayon::prelude::*;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    pub iteration: Iteration,
    pub tolerance: f64,
    pub max_iterations: usize,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Solved {
    pub(crate) b: Vec<Rgb>,
    pub(crate) iterations: usize,
    /// Relative change at each sweep.
    pub(crate) history: Vec<f64>,
    /// ‖E + ρKB − B‖ / ‖B‖ at the end.
    pub(crate) residual: f64,
    pub(crate) converged: bool,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolveError {
    #[error("cancelled")]
    Cancelled,
    #[error("the iteration diverged at sweep {iteration}: {reason}")]
    Diverged { iteration: usize, reason: String },
}

impl From<Cancelled> for SolveError {
    fn from(_: Cancelled) -> Self {
        SolveError::Cancelled
    }
}

/// Solves B = E + diag(ρ) K B. `rho[i]` is the reflectance of row i.
pub fn solve(
    k: &dyn Operator,
    rho: &[Rgb],
    e: &[Rgb],
    settings: Settings,
    progress: &dyn Progress,
) -> Result<Solved, SolveError> {
    let n = k.size();
    assert!(rho.len() == n && e.len() == n);
    // 1 / (1 − ρ_i K_ii) per row and channel
    let mut inv_diag = vec![[1.0; 3]; n];
    for i in 0..n {
        let d = k.diagonal(i);
        for c in 0..3 {
            let den = 1.0 - rho[i][c] * d;
            if den <= 0.0 {
                return Err(SolveError::Diverged {
                    iteration: 0,
                    reason: format!(
                        "row {i} has ρK_ii = {} ≥ 1: the system is not diagonally solvable",
                        rho[i][c] * d
                    ),
                });
            }
            inv_diag[i][c] = 1.0 / den;
        }
    }
    let norm_e = norm(e);
    let mut b = e.to_vec();
    let mut next = vec![[0.0; 3]; n];
    let mut history = Vec::new();
    let mut converged = false;
    progress.report(Phase::Solve, 0.0);
    for it in 1..=settings.max_iterations {
        progress.check()?;
        let change = match settings.iteration {
            Iteration::Jacobi => {
                next.par_iter_mut().enumerate().for_each(|(i, out)| {
                    *out = sweep_row(k, i, rho, e, &inv_diag, &b);
                });
                let diff = diff_norm(&next, &b);
                std::mem::swap(&mut b, &mut next);
                diff
            }
            Iteration::GaussSeidel => {
                let mut diff = 0.0;
                for i in 0..n {
                    let new = sweep_row(k, i, rho, e, &inv_diag, &b);
                    for c in 0..3 {
                        diff += (new[c] - b[i][c]).powi(2);
                    }
                    b[i] = new;
                }
                diff.sqrt()
            }
        };
        let nb = norm(&b);
        let rel = if nb > 0.0 { change / nb } else { change };
        history.push(rel);
        if !rel.is_finite() || !nb.is_finite() {
            return Err(SolveError::Diverged {
                iteration: it,
                reason: "B is no longer finite".into(),
            });
        }
        if nb > 1e12 * norm_e.max(f64::MIN_POSITIVE) {
            return Err(SolveError::Diverged {
                iteration: it,
                reason: format!("‖B‖ grew to {nb:.3e}, 10¹² times ‖E‖"),
            });
        }
        if growing(&history) {
            return Err(SolveError::Diverged {
                iteration: it,
                reason: "the change between sweeps has grown for 50 sweeps: the spectral radius of ρK is at least 1".into(),
            });
        }
        if it % 4 == 0 || rel < settings.tolerance {
            let done = (settings.tolerance.ln() / rel.max(1e-300).ln()).clamp(0.0, 1.0);
            progress.report(
                Phase::Solve,
                done.max(it as f64 / settings.max_iterations as f64),
            );
        }
        if rel < settings.tolerance {
            converged = true;
            break;
        }
    }
    let residual = residual(k, rho, e, &b);
    progress.report(Phase::Solve, 1.0);
    Ok(Solved {
        iterations: history.len(),
        b,
        history,
        residual,
        converged,
    })
}

#[inline]
fn sweep_row(
    k: &dyn Operator,
    i: usize,
    rho: &[Rgb],
    e: &[Rgb],
    inv_diag: &[Rgb],
    b: &[Rgb],
) -> Rgb {
    let acc = k.off_diagonal_dot(i, b);
    let mut out = [0.0; 3];
    for c in 0..3 {
        out[c] = (e[i][c] + rho[i][c] * acc[c]) * inv_diag[i][c];
    }
    out
}

/// ‖E + ρKB − B‖ / ‖B‖.
fn residual(k: &dyn Operator, rho: &[Rgb], e: &[Rgb], b: &[Rgb]) -> f64 {
    let kb = multiply(k, b);
    let mut r = 0.0;
    for i in 0..k.size() {
        for c in 0..3 {
            r += (e[i][c] + rho[i][c] * kb[i][c] - b[i][c]).powi(2);
        }
    }
    let nb = norm(b);
    if nb > 0.0 {
        r.sqrt() / nb
    } else {
        r.sqrt()
    }
}

/// K B for three channels.
pub(crate) fn multiply(k: &dyn Operator, b: &[Rgb]) -> Vec<Rgb> {
    (0..k.size()).into_par_iter().map(|i| k.dot(i, b)).collect()
}

fn norm(v: &[Rgb]) -> f64 {
    v.iter()
        .map(|x| x[0] * x[0] + x[1] * x[1] + x[2] * x[2])
        .sum::<f64>()
        .sqrt()
}

fn diff_norm(a: &[Rgb], b: &[Rgb]) -> f64 {
    // sequential: a parallel sum would change the rounding, and so the sweep count, run to run
    a.iter()
        .zip(b)
        .map(|(x, y)| (0..3).map(|c| (x[c] - y[c]).powi(2)).sum::<f64>())
        .sum::<f64>()
        .sqrt()
}

/// The change has grown at every one of the last 50 sweeps.
fn growing(history: &[f64]) -> bool {
    const RUN: usize = 50;
    history.len() > RUN
        && history[history.len() - RUN..]
            .windows(2)
            .all(|w| w[1] > w[0])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::methods::compress::Csr;
    use crate::progress::Silent;

    fn csr(dense: &[&[f64]]) -> Csr {
        let n = dense.len();
        let mut m = Csr {
            n,
            row_ptr: vec![0],
            ..Default::default()
        };
        for row in dense {
            for (j, v) in row.iter().enumerate() {
                if *v != 0.0 {
                    m.cols.push(j as u32);
                    m.vals.push(*v);
                }
            }
            m.row_ptr.push(m.vals.len());
        }
        m
    }

    fn settings(iteration: Iteration) -> Settings {
        Settings {
            iteration,
            tolerance: 1e-14,
            max_iterations: 500,
        }
    }

    /// (I − ρK) B = E with a 2 × 2 system solved by hand.
    #[test]
    fn both_iterations_reach_the_exact_solution() {
        let k = csr(&[&[0.1, 0.4], &[0.3, 0.2]]);
        let rho = vec![[0.5, 0.8, 0.0]; 2];
        let e = vec![[1.0, 1.0, 1.0], [0.0, 2.0, 0.0]];
        for it in [Iteration::Jacobi, Iteration::GaussSeidel] {
            let s = solve(&k, &rho, &e, settings(it), &Silent).unwrap();
            assert!(s.converged);
            for c in 0..3 {
                let r = rho[0][c];
                // [1 − 0.1r, −0.4r; −0.3r, 1 − 0.2r] B = E
                let (a, b, cc, d) = (1.0 - 0.1 * r, -0.4 * r, -0.3 * r, 1.0 - 0.2 * r);
                let det = a * d - b * cc;
                let b0 = (d * e[0][c] - b * e[1][c]) / det;
                let b1 = (a * e[1][c] - cc * e[0][c]) / det;
                assert!((s.b[0][c] - b0).abs() < 1e-13, "{it:?} {c}");
                assert!((s.b[1][c] - b1).abs() < 1e-13);
            }
            assert!(s.residual < 1e-13);
        }
    }

    #[test]
    fn divergence_is_an_error() {
        let k = csr(&[&[0.0, 1.5], &[1.5, 0.0]]);
        let rho = vec![[0.9; 3]; 2];
        let e = vec![[1.0; 3]; 2];
        let err = solve(&k, &rho, &e, settings(Iteration::Jacobi), &Silent).unwrap_err();
        assert!(matches!(err, SolveError::Diverged { .. }), "{err}");
    }

    #[test]
    fn stops_at_max_iterations_unconverged() {
        let k = csr(&[&[0.0, 0.99], &[0.99, 0.0]]);
        let rho = vec![[0.99; 3]; 2];
        let e = vec![[1.0; 3]; 2];
        let s = solve(
            &k,
            &rho,
            &e,
            Settings {
                max_iterations: 3,
                ..settings(Iteration::Jacobi)
            },
            &Silent,
        )
        .unwrap();
        assert!(!s.converged);
        assert_eq!(s.iterations, 3);
    }
}
