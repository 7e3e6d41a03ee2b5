//! 3D scenes: the radiosity equation on parallelograms with the kernel of the slides' eq. (3).
//! [`geometry`] parametrises the surfaces and their pieces, [`bvh`] and [`visibility`] give the
//! visibility term, [`cover`] the part of a surface that a solid stands on, [`transfer`]
//! integrates the Galerkin block between two pieces, `congruence` shares it between equal
//! pairs, [`projection`] assembles the projection method's matrix and [`hierarchy`] solves by
//! hierarchical wavelet radiosity, with the [`rules`] that bound what its estimate does not see.

pub mod bvh;
pub mod cluster;
mod congruence;
pub mod cover;
pub mod geometry;
pub(crate) mod hierarchy;
pub mod projection;
pub mod rules;
mod steps;
pub mod transfer;
pub mod visibility;
