//! The mathematics every kind of scene shares: Gauss–Legendre quadrature, the piecewise
//! polynomial spaces and their two bases (the slides' scaling functions and Alpert's
//! multiwavelets), and B as piecewise polynomials over a surface.

pub mod basis;
pub mod field;
pub mod quadrature;
