//! The operator K of the Galerkin system as the iterations see it: any square matrix whose rows
//! can be dotted with B, sparse ([`crate::methods::compress::Csr`]) or dense
//! ([`crate::methods::projection::Dense`]).

use crate::scene::Rgb;

/// A square matrix the iterations can sweep: sparse after thresholding, or dense when most
/// entries are kept (a dense sweep needs no second copy of the matrix).
pub trait Operator: Sync {
    fn size(&self) -> usize;
    fn diagonal(&self, i: usize) -> f64;
    /// Σ_{j ≠ i} K_ij b_j for three channels.
    fn off_diagonal_dot(&self, i: usize, b: &[Rgb]) -> Rgb;
    /// Σ_j K_ij b_j.
    fn dot(&self, i: usize, b: &[Rgb]) -> Rgb {
        let d = self.diagonal(i);
        let mut acc = self.off_diagonal_dot(i, b);
        for c in 0..3 {
            acc[c] += d * b[i][c];
        }
        acc
    }
}
