//! The Galerkin system of the slides' eq. (11)–(12): K_ij = ∫∫ K(x,y) N_j(y) N_i(x) dy dx and
//! E_i = ∫ E N_i, with N the orthonormal scaling basis (piecewise shifted Legendre polynomials
//! of degree ≤ m on n cells of each surface, normalised in arc length or area).
//!
//! The matrix is kept without ρ: ρ is constant on each surface, so B = E + diag(ρ) K B shares
//! one K between the three channels, and diag(ρ) commutes with the per-surface wavelet transform.

use crate::methods::operator::Operator;
use crate::scene::Rgb;

/// A dense row-major square matrix.
#[derive(Debug, Clone, PartialEq)]
pub struct Dense {
    pub(super) n: usize,
    pub data: Vec<f64>,
}

impl Dense {
    pub(crate) fn zeros(n: usize) -> Dense {
        Dense {
            n,
            data: vec![0.0; n * n],
        }
    }
    #[inline]
    pub fn get(&self, i: usize, j: usize) -> f64 {
        self.data[i * self.n + j]
    }
    pub(super) fn row(&self, i: usize) -> &[f64] {
        &self.data[i * self.n..(i + 1) * self.n]
    }
    /// In-place transpose, blocked for the cache.
    pub(super) fn transpose(&mut self) {
        let n = self.n;
        const B: usize = 32;
        for ib in (0..n).step_by(B) {
            for jb in (ib..n).step_by(B) {
                for i in ib..(ib + B).min(n) {
                    let j0 = if ib == jb { i + 1 } else { jb };
                    for j in j0..(jb + B).min(n) {
                        self.data.swap(i * n + j, j * n + i);
                    }
                }
            }
        }
    }
}

/// How the coefficients of one surface are laid out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Layout {
    /// n cells × k = m + 1 Legendre coefficients, `[cell][p]`.
    Line { cells: usize, k: usize },
    /// n × n cells × k² tensor coefficients, `[cell_t][cell_s][p_t][p_s]`.
    Square { cells: usize, k: usize },
}

impl Layout {
    pub(crate) fn len(&self) -> usize {
        match *self {
            Layout::Line { cells, k } => cells * k,
            Layout::Square { cells, k } => cells * cells * k * k,
        }
    }
    pub(crate) fn k(&self) -> usize {
        match *self {
            Layout::Line { k, .. } | Layout::Square { k, .. } => k,
        }
    }
    pub(crate) fn cells(&self) -> usize {
        match *self {
            Layout::Line { cells, .. } | Layout::Square { cells, .. } => cells,
        }
    }
}

/// The discrete radiosity system in the scaling basis.
#[derive(Debug, Clone)]
pub struct System {
    pub(crate) layout: Layout,
    pub(crate) surfaces: usize,
    /// K without ρ.
    pub matrix: Dense,
    /// E per channel.
    pub emission: Vec<Rgb>,
    /// ρ per surface and channel (1 for a `fredholm` equation).
    pub reflectance: Vec<Rgb>,
    /// Length or area of each surface.
    pub measure: Vec<f64>,
    /// Pairs of surfaces (i < j) that touch: ∫∫K² diverges there, so eq. (5) leaves them out.
    pub(crate) touching: Vec<(usize, usize)>,
    /// Kernel evaluations the matrix took, where the integrator counts them.
    pub(crate) kernel_evaluations: Option<u64>,
}

impl System {
    pub fn size(&self) -> usize {
        self.surfaces * self.layout.len()
    }
    pub fn surface_of(&self, row: usize) -> usize {
        row / self.layout.len()
    }
}

/// Discretisation parameters: order m, cells per side n, Gauss points per cell q.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Discretization {
    pub order: usize,
    pub cells: usize,
    pub quadrature: usize,
}

/// Gauss points needed on a pair of cells at distance `dist` apart, of size `size`, for the
/// quadrature error of a kernel analytic off the diagonal to be about 1e-13: the error of a
/// q-point rule decays like ρ^(−2q), ρ the Bernstein ellipse through the nearest singularity.
pub(crate) fn points_for_separation(dist: f64, size: f64) -> usize {
    let a = 1.0 + 2.0 * dist / size.max(1e-300);
    let rho = a + (a * a - 1.0).max(0.0).sqrt();
    let q = (15.0 / rho.ln()).ceil();
    // NaN (degenerate input) falls to the largest rule
    if q.is_nan() {
        24
    } else {
        q.clamp(1.0, 24.0) as usize
    }
}

impl Operator for Dense {
    fn size(&self) -> usize {
        self.n
    }
    fn diagonal(&self, i: usize) -> f64 {
        self.get(i, i)
    }
    #[inline]
    fn off_diagonal_dot(&self, i: usize, b: &[Rgb]) -> Rgb {
        let mut acc = [0.0; 3];
        for (j, (&v, bj)) in self.row(i).iter().zip(b).enumerate() {
            if j != i {
                acc[0] += v * bj[0];
                acc[1] += v * bj[1];
                acc[2] += v * bj[2];
            }
        }
        acc
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transpose_in_place() {
        let n = 70;
        let mut m = Dense::zeros(n);
        for i in 0..n * n {
            m.data[i] = i as f64;
        }
        let orig = m.clone();
        m.transpose();
        for i in 0..n {
            for j in 0..n {
                assert_eq!(m.get(i, j), orig.get(j, i));
            }
        }
    }

    #[test]
    fn more_points_when_closer() {
        assert!(points_for_separation(1.0, 1.0) > points_for_separation(10.0, 1.0));
        assert!(points_for_separation(1000.0, 1.0) <= 2);
        assert_eq!(points_for_separation(f64::NAN, 1.0), 24);
        assert_eq!(points_for_separation(0.0, 0.0), 24);
    }
}
