//! wavrad: wavelet radiosity.
//!
//! Solves the radiosity integral equation B = E + ρ ∫ K B (Goral et al. 1984; the slides
//! "Application of Wavelets in Computer Graphics: Wavelet Radiosity", eq. (2)) by Galerkin
//! projection onto piecewise Legendre polynomials (eq. (7)–(12)), represented in the scaling basis
//! or in Alpert's multiwavelet basis, whose vanishing moments make the kernel matrix sparse.
//!
//! The pipeline of a job: [`scene`] validates the document → [`projection`] builds the Galerkin
//! matrix with the kernels of [`kernel`] and the rules of [`quadrature`] → [`compress`] turns it
//! into the wavelet basis of [`basis`] and thresholds it → [`solve`] iterates → [`metrics`]
//! measures eq. (5) and (6) → [`job`] gathers the result.

pub mod basis;
pub mod bvh;
pub mod compress;
pub mod field;
pub mod geometry;
pub mod hierarchy;
pub mod job;
pub mod kernel;
pub mod metrics;
pub mod progress;
pub mod projection;
pub mod quadrature;
pub mod render;
pub mod result;
pub mod scene;
pub mod solve;
pub mod space;
pub mod transfer;
pub mod visibility;
pub mod visibility3d;
