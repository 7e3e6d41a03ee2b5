//! wavrad: wavelet radiosity.
//!
//! Solves the radiosity integral equation B = E + ρ ∫ K B (Goral et al. 1984; the slides
//! "Application of Wavelets in Computer Graphics: Wavelet Radiosity", eq. (2)) by Galerkin
//! projection onto piecewise Legendre polynomials (eq. (7)–(12)), represented in the scaling basis
//! or in Alpert's multiwavelet basis, whose vanishing moments make the kernel matrix sparse.
//!
//! The pipeline of a job: [`scene`] validates the document → [`methods::projection`] builds the
//! Galerkin system (flatland's kernels in [`flatland::kernel`], the rules of
//! [`math::quadrature`]) → [`methods::compress`] turns it into the wavelet basis of
//! [`math::basis`] and thresholds it → [`methods::solve`] iterates → [`metrics`] measures eq.
//! (5) and (6) → [`job`] gathers the result.
//!
//! 3D scenes ([`three_d`]): [`three_d::geometry`] parametrises the parallelograms and
//! triangles, [`three_d::bvh`] and [`three_d::visibility`] give the visibility term of eq. (3),
//! [`three_d::cover`] finds where a solid covers a surface, [`three_d::transfer`] integrates the
//! Galerkin blocks between pieces of them, [`three_d::projection`] assembles the projection
//! method's matrix, [`three_d::hierarchy`] solves by hierarchical wavelet radiosity (Gortler et
//! al. 1993; Hanrahan et al. 1991) over the clusters of [`three_d::cluster`], and
//! [`render::camera`] makes the images. `ARCHITECTURE.md` has the whole map.

// Numerical loops index several arrays by the same subscript, as the papers' formulas do.
#![allow(clippy::needless_range_loop)]
// A `pub` item is one reachable from outside the crate; the rest is `pub(crate)` or narrower.
#![warn(unreachable_pub)]

pub mod flatland;
mod fredholm;
pub mod import;
pub mod job;
pub mod math;
pub mod methods;
pub mod metrics;
pub mod progress;
pub mod render;
pub mod result;
pub mod scene;
pub mod server;
pub mod three_d;
pub mod warnings;
