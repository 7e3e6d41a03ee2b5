//! The mathematics every kind of scene shares: Gauss–Legendre quadrature, the piecewise
//! polynomial spaces and their two bases (the slides' scaling functions and Alpert's
//! multiwavelets), B as piecewise polynomials over a surface, and on triangles the orthonormal
//! polynomials of total degree ≤ m with their four-way split and quadrature ([`triangle`]).

pub mod basis;
pub mod field;
pub mod quadrature;
pub mod triangle;
