//! The result of a finished job (`docs/job-document.md`, "What a finished job yields"), as serialised.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct JobResult {
    /// The scene's name, when it has one.
    pub(crate) scene: Option<String>,
    pub(crate) kind: String,
    /// The solver settings in effect, every default applied.
    pub solver: SolverEcho,
    pub surfaces: Vec<SurfaceResult>,
    pub coefficients: Coefficients,
    pub metrics: Metrics,
    /// Milliseconds per phase (the only part of a result that varies between runs).
    pub timings_ms: std::collections::BTreeMap<String, f64>,
    /// Hierarchical method only: the size of the link structure.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub hierarchical: Option<HierarchyStats>,
    /// Geometry that the format allows but that cannot be physically right (surfaces that
    /// cross or overlap): the solve ran all the same. Empty when there is none.
    #[serde(default)]
    pub(crate) warnings: Vec<Warning>,
}

/// Something about the scene that the solve went ahead with but the author should know.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Warning {
    /// The JSON paths of the surfaces involved (`/scene/surfaces/3`).
    pub paths: Vec<String>,
    pub message: String,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct SolverEcho {
    pub(crate) method: String,
    pub(crate) basis: String,
    pub(crate) order: usize,
    pub(crate) resolution: usize,
    /// `"all"`, `{"top": N}`, `{"fraction": f}` or `{"threshold": t}`.
    #[schema(value_type = Value)]
    pub(crate) keep: serde_json::Value,
    pub iteration: String,
    pub(crate) tolerance: f64,
    pub(crate) max_iterations: usize,
    pub(crate) quadrature: usize,
    pub(crate) epsilon: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct SurfaceResult {
    pub name: String,
    /// Mean of B over the surface, per channel.
    pub mean: [f64; 3],
    /// Cell means on the output grid: `grid` cells (flatland, fredholm) or `grid × grid`
    /// (3d, rows by t then s).
    pub cells: Vec<[f64; 3]>,
    /// With `output.vertices`, for a `triangle` or `mesh` surface: B at each of its positions,
    /// averaged over the triangles that meet there.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vertices: Option<Vec<[f64; 3]>>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Coefficients {
    /// Unknowns of the linear system (per channel).
    pub basis_size: usize,
    /// Entries of the kernel matrix (basis_size², or the link coefficients of the hierarchy).
    pub matrix_entries: usize,
    /// Non-zero entries kept after thresholding.
    pub kept_entries: usize,
    /// The fraction of matrix entries that are zero after thresholding: 1 − kept / entries.
    pub sparsity_ratio: f64,
    /// The smallest magnitude kept (0 when everything is kept).
    pub cut: f64,
    /// Magnitudes of the matrix entries sorted in decreasing order, sampled evenly in rank.
    pub sorted_magnitudes: Vec<f64>,
    /// The rank (0-based, in the whole sorted list) of each sampled magnitude.
    pub sorted_ranks: Vec<usize>,
}

/// How eq. (5) was sampled.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct KernelErrorSampling {
    /// Pairs of points drawn, each uniform by area over the scene.
    pub point_pairs: usize,
    /// The standard error of `kernel_relative_error` (a ratio of two sample means).
    pub standard_error: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Metrics {
    /// Eq. (5) over the pairs of surfaces that do not touch.
    pub kernel_relative_error: Option<f64>,
    /// The pairs of surfaces left out of eq. (5) because they touch.
    pub kernel_pairs_left_out: Vec<[String; 2]>,
    /// On scenes with triangles, and hierarchical ones of more than 32 surfaces, eq. (5) is
    /// sampled at random pairs of points rather than integrated over every pair of surfaces:
    /// how, and its standard error.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kernel_error_sampling: Option<KernelErrorSampling>,
    /// Eq. (6), when a reference is set.
    pub radiosity_relative_error: Option<f64>,
    /// What eq. (6) was measured against: "exact" or "order m, resolution n".
    pub(crate) reference: Option<String>,
    pub iterations: usize,
    pub(crate) converged: bool,
    /// ‖E + ρKB − B‖ / ‖B‖ after the last sweep.
    pub(crate) final_residual: f64,
    /// The relative change of B at each sweep.
    pub(crate) residual_history: Vec<f64>,
    /// Evaluations of the kernel K(x, y) that the matrix or the links took (in 3D a
    /// closed-form point-to-polygon form factor counts as one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kernel_evaluations: Option<u64>,
    pub energy: EnergyBalance,
}

/// Power per channel: emitted, absorbed (∫ (1 − ρ) H over the surfaces, H the irradiance) and
/// their ratio, which is 1 in a closed scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct EnergyBalance {
    pub(crate) emitted: [f64; 3],
    pub(crate) absorbed: [f64; 3],
    /// absorbed / emitted.
    pub balance: [f64; 3],
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct HierarchyStats {
    pub elements: usize,
    pub leaves: usize,
    pub links: usize,
    pub levels: usize,
    pub refinements: usize,
    pub rays: u64,
    /// 3d: the smallest element edge the refinement could go down to, in scene units: the
    /// document's `min_element_size` or its default from the scene's size.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(crate) min_element_size: Option<f64>,
}
