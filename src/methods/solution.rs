//! What every method answers: the [`Solution`] (B over each surface as piecewise polynomials,
//! the operator's statistics, the iterations) from which [`crate::job`] assembles the result,
//! and the [`JobError`] kinds by which a solve fails.

use crate::math::field::Field;
use crate::methods::compress::MagnitudePicture;
use crate::methods::solve::{SolveError, Solved};
use crate::progress::Cancelled;
use crate::result::HierarchyStats;
use std::collections::BTreeMap;

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum JobError {
    #[error("cancelled")]
    Cancelled,
    /// The iteration stopped contracting ([`SolveError::Diverged`]).
    #[error("the iteration diverged at sweep {iteration}: {reason}")]
    Diverged { iteration: usize, reason: String },
    /// A method asked for a kind of scene it does not solve (the document's validation
    /// refuses these first; a library caller may still ask).
    #[error("the {method} method does not solve {scene} scenes")]
    Unsupported {
        method: &'static str,
        scene: &'static str,
    },
    /// The problem outgrew the memory the solver allows itself: the refinement asked for more
    /// than `links` links of polynomial order `order`.
    #[error(
        "the hierarchy needs more than {links} links of order {order}; raise solver.epsilon \
         or lower solver.order or solver.resolution"
    )]
    TooLarge { links: usize, order: usize },
    /// The refinement's frontier outgrew the memory the solver allows itself: one level asked
    /// to judge more than `pairs` pairs of elements and clusters at once.
    #[error(
        "the refinement would judge more than {pairs} pairs at once; raise solver.epsilon \
         or solver.min_element_size"
    )]
    TooManyPairs { pairs: usize },
}

impl From<Cancelled> for JobError {
    fn from(_: Cancelled) -> Self {
        JobError::Cancelled
    }
}

impl From<SolveError> for JobError {
    fn from(e: SolveError) -> Self {
        match e {
            SolveError::Cancelled => JobError::Cancelled,
            SolveError::Diverged { iteration, reason } => JobError::Diverged { iteration, reason },
        }
    }
}

/// What a method produces; the result is assembled from it.
#[derive(Debug, Clone)]
pub struct Solution {
    pub fields: Vec<Field>,
    /// B as the images show it, where that differs from `fields`: on an element that a
    /// solid partly covers, the polynomial of its exposed part up to the outline
    /// ([`crate::three_d::cover`]), where `fields` holds the element's projection.
    pub(crate) shown: Option<Vec<Field>>,
    pub(crate) emission: Vec<Field>,
    pub(crate) irradiance: Vec<Field>,
    pub(crate) basis_size: usize,
    pub matrix_entries: usize,
    pub kept_entries: usize,
    pub(crate) cut: f64,
    /// Sampled sorted magnitudes of the matrix: (rank, magnitude), decreasing.
    pub(crate) magnitudes: Vec<(usize, f64)>,
    pub(crate) picture: Option<MagnitudePicture>,
    pub(crate) solved: Solved,
    /// Eq. (5) and the surface pairs it left out.
    pub(crate) kernel_error: Option<f64>,
    pub(crate) left_out: Vec<(usize, usize)>,
    /// Set when eq. (5) was sampled rather than integrated.
    pub(crate) kernel_error_sampling: Option<crate::result::KernelErrorSampling>,
    pub(crate) hierarchy: Option<HierarchyStats>,
    pub(crate) timings: BTreeMap<String, f64>,
    /// Σ K_ij² of the kept entries per (row surface, column surface), `S × S`, for eq. (5).
    pub(crate) kept_squares: Vec<f64>,
    /// Kernel evaluations the matrix (or the links) took, where they are counted.
    pub(crate) kernel_evaluations: Option<u64>,
}
