//! The piecewise-polynomial spaces of the projection method and their two bases.
//!
//! - `legendre`: the scaling basis, orthonormal shifted Legendre polynomials of degree ≤ m on
//!   each of n cells of [0, 1] (the slides' "choice of a finite dimensional space").
//! - `multiwavelet`: the same space in Alpert's multiwavelet basis ("A class of bases in L²
//!   for the sparse representation of integral operators", SIAM J. Math. Anal. 24, 1993, §2–3):
//!   k = m + 1 wavelets per cell with k (and more) vanishing moments; Haar for m = 0.
//! - [`transform`]: the fast O(N) transform between the two, one two-scale step per level.

pub(crate) mod legendre;
mod multiwavelet;
pub mod transform;

pub(crate) use legendre::legendre;
pub use multiwavelet::Filters;
