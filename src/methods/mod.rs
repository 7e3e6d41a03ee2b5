//! The methods that solve the Galerkin system of any kind of scene: the whole matrix
//! ([`projection`]), its wavelet transform and thresholding ([`compress`]), the iterations
//! ([`solve`]) on any `operator`, their acceleration by [`extrapolation`], and the `solution`
//! every method answers.
//! Hierarchical wavelet radiosity lives with its kind of scene (`crate::flatland::hierarchy`,
//! [`crate::three_d::hierarchy`]): its elements and links are made of that kind's geometry.

pub mod compress;
pub(crate) mod extrapolation;
mod operator;
pub mod projection;
pub(crate) mod solution;
pub mod solve;
