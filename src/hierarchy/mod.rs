//! Hierarchical wavelet radiosity (Gortler, Schröder, Cohen and Hanrahan 1993; Hanrahan,
//! Salzman and Aupperle 1991): elements, links, the refinement oracle and push-pull, per kind
//! of scene.

pub mod flatland;
pub mod three_d;
