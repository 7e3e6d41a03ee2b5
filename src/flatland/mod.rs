//! Flatland: the radiosity equation on segments in the plane, with the kernel of the slides'
//! eq. (4), exact visibility as parameter intervals, the Galerkin matrix of the projection
//! method and the binary-tree hierarchy of hierarchical wavelet radiosity.

pub mod geometry;
pub(crate) mod hierarchy;
pub mod kernel;
pub mod projection;
mod visibility;
