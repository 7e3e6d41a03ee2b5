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

// Lints the numerical code trips by design (index loops that mirror the formulas, a scene
// enum whose Fredholm variant carries compiled expressions).
#![allow(
    clippy::needless_range_loop,
    clippy::large_enum_variant,
    clippy::explicit_auto_deref,
    clippy::manual_pattern_char_comparison,
    clippy::type_complexity
)]

pub mod basis;
pub mod compress;
pub mod field;
pub mod geometry;
pub mod job;
pub mod kernel;
pub mod metrics;
pub mod progress;
pub mod projection;
pub mod quadrature;
pub mod render;
pub mod result;
pub mod scene;
pub mod server;
pub mod solve;
pub mod visibility;
