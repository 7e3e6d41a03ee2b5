//! The job document of `docs/job-document.md`, in two stages: [`parse`] walks the raw JSON value and
//! collects every error with its JSON path, and returns the validated types below, in which every
//! default of the spec is applied and every invariant holds.

mod expr;
mod parse;
mod repeated;
pub mod schema;
mod walk;

pub(crate) use expr::Expr;
pub use parse::{parse_document, parse_text, parse_value};
pub(crate) use repeated::repeated_keys;

use serde::Serialize;

/// One error of a document: the JSON pointer of the value at fault and what is wrong with it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct FieldError {
    pub path: String,
    pub message: String,
}

impl std::fmt::Display for FieldError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let path = if self.path.is_empty() {
            "/"
        } else {
            &self.path
        };
        write!(f, "{path}: {}", self.message)
    }
}

/// Every error of a document, in document order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DocumentErrors(pub Vec<FieldError>);

impl std::fmt::Display for DocumentErrors {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for (i, e) in self.0.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            write!(f, "{e}")?;
        }
        Ok(())
    }
}

impl std::error::Error for DocumentErrors {}

/// Limits that a document must respect (the server's configuration; generous defaults for the
/// library and the command line).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    pub max_surfaces: usize,
    /// Triangles in a 3D scene, of `triangle` and `mesh` surfaces together.
    pub max_triangles: usize,
    pub max_order: usize,
    pub max_resolution: usize,
    /// The projection matrix is `basis_size²` dense entries of 8 bytes, and thresholding may add
    /// a sparse copy of up to a third of them (12 bytes each): 12 · basis_size² bytes at peak.
    pub max_basis_functions: usize,
    pub max_image_pixels: usize,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_surfaces: 256,
            max_triangles: 1 << 20,
            max_order: 8,
            max_resolution: 1024,
            // At most 12 bytes per matrix entry at peak (the dense matrix, and a sparse copy of at
            // most a third of it): 9459² × 12 bytes ≈ 1 GiB.
            max_basis_functions: 9459,
            max_image_pixels: 4096 * 4096,
        }
    }
}

/// An RGB triple: reflectance or emission per channel.
pub(crate) type Rgb = [f64; 3];

/// A validated job document.
#[derive(Debug, Clone, PartialEq)]
pub struct Job {
    pub scene: Scene,
    pub solver: Solver,
    pub output: Output,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    pub name: Option<String>,
    pub kind: SceneKind,
}

#[derive(Debug, Clone, PartialEq)]
pub enum SceneKind {
    Flatland(Vec<Segment>),
    ThreeD(ThreeD),
    Fredholm(Fredholm),
}

impl SceneKind {
    pub fn name(&self) -> &'static str {
        match self {
            SceneKind::Flatland(_) => "flatland",
            SceneKind::ThreeD(_) => "3d",
            SceneKind::Fredholm(_) => "fredholm",
        }
    }
}

/// Optical properties shared by flatland and 3D surfaces.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Material {
    pub(crate) reflectance: Rgb,
    pub(crate) emission: Rgb,
}

/// A flatland surface: p(s) = a + s(b − a), front normal (b − a) turned +90°.
#[derive(Debug, Clone, PartialEq)]
pub struct Segment {
    pub(crate) name: String,
    pub(crate) a: [f64; 2],
    pub(crate) b: [f64; 2],
    pub(crate) material: Material,
    /// `[s0, s1]` with 0 ≤ s0 < s1 ≤ 1; `[0, 1]` when the document has none.
    pub(crate) emission_region: [f64; 2],
}

/// A 3D scene: the document's surfaces, and the patches the solver works on — one per
/// parallelogram or triangle surface, one per triangle of a mesh, in document order. It
/// dereferences to the patches.
#[derive(Debug, Clone, PartialEq)]
pub struct ThreeD {
    pub surfaces: Vec<Surface3>,
    pub(crate) patches: Vec<Quad>,
}

impl std::ops::Deref for ThreeD {
    type Target = [Quad];
    fn deref(&self) -> &[Quad] {
        &self.patches
    }
}

impl ThreeD {
    /// The document surface of each patch.
    pub(crate) fn owners(&self) -> Vec<usize> {
        let mut out = vec![0; self.patches.len()];
        for (i, s) in self.surfaces.iter().enumerate() {
            out[s.patches.clone()].fill(i);
        }
        out
    }

    /// Whether every surface is a parallelogram.
    pub(crate) fn parallelograms_only(&self) -> bool {
        self.surfaces
            .iter()
            .all(|s| matches!(s.shape, Shape3::Parallelogram))
    }
}

/// A surface of a 3D document and the patches it became.
#[derive(Debug, Clone, PartialEq)]
pub struct Surface3 {
    pub name: String,
    pub shape: Shape3,
    pub(crate) patches: std::ops::Range<usize>,
}

#[derive(Debug, Clone, PartialEq)]
pub enum Shape3 {
    Parallelogram,
    /// Its corners, as the one patch holds them.
    Triangle,
    /// Positions and triangles as the document gives them; patch `i` is triangle `i`.
    Mesh {
        positions: Vec<[f64; 3]>,
        triangles: Vec<[usize; 3]>,
    },
}

/// A patch of a 3D surface. A parallelogram: p(s,t) = p0 + s(p1 − p0) + t(p3 − p0), front normal
/// (p1 − p0) × (p3 − p0). A triangle (`triangle`) is the half s + t ≤ 1 of the same map: its
/// corners are p0, p1, p3 and `corners[2]` = p1 + p3 − p0 completes the parallelogram.
#[derive(Debug, Clone, PartialEq)]
pub struct Quad {
    pub name: String,
    pub corners: [[f64; 3]; 4],
    pub(crate) material: Material,
    /// `([s0, s1], [t0, t1])`; the whole surface when the document has none.
    pub(crate) emission_region: ([f64; 2], [f64; 2]),
    pub(crate) triangle: bool,
}

impl Quad {
    /// The patch of triangle (p0, p1, p2).
    fn triangle(name: String, p: [[f64; 3]; 3], material: Material) -> Quad {
        let far = [0, 1, 2].map(|c| p[1][c] + p[2][c] - p[0][c]);
        Quad {
            name,
            corners: [p[0], p[1], far, p[2]],
            material,
            emission_region: ([0.0, 1.0], [0.0, 1.0]),
            triangle: true,
        }
    }

    /// Its corners as a polygon, counter-clockwise seen from the front: four, or the triangle's
    /// three.
    fn polygon(&self) -> Vec<[f64; 3]> {
        if self.triangle {
            vec![self.corners[0], self.corners[1], self.corners[3]]
        } else {
            self.corners.to_vec()
        }
    }
}

/// `B(x) = E(x) + ∫_a^b K(x,y) B(y) dy`.
#[derive(Debug, Clone, PartialEq)]
pub struct Fredholm {
    pub(crate) domain: [f64; 2],
    pub(crate) kernel: Expr,
    pub(crate) source: Expr,
    pub(crate) exact: Option<Expr>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub(crate) enum Method {
    Projection,
    Hierarchical,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub(crate) enum BasisKind {
    Scaling,
    Wavelet,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Keep {
    All,
    Top(usize),
    Fraction(f64),
    Threshold(f64),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Iteration {
    Jacobi,
    GaussSeidel,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Solver {
    pub(crate) method: Method,
    pub(crate) basis: BasisKind,
    pub order: usize,
    pub resolution: usize,
    /// Whether the document gave `resolution`: for the hierarchical method in 3D it is then a
    /// cap on top of [`Solver::min_element_size`], else the elements are sized by that alone.
    pub(crate) resolution_given: bool,
    pub(crate) keep: Keep,
    pub(crate) iteration: Iteration,
    pub(crate) tolerance: f64,
    pub(crate) max_iterations: usize,
    /// Gauss–Legendre points per cell and dimension.
    pub(crate) quadrature: usize,
    pub(crate) epsilon: f64,
    /// The hierarchical method's smallest element edge in scene units; `None`: chosen from the
    /// scene's size (`three_d::hierarchy::sizing`).
    pub(crate) min_element_size: Option<f64>,
}

impl Default for Solver {
    fn default() -> Self {
        Solver {
            method: Method::Projection,
            basis: BasisKind::Wavelet,
            order: 1,
            resolution: 8,
            resolution_given: false,
            keep: Keep::All,
            iteration: Iteration::Jacobi,
            tolerance: 1e-6,
            max_iterations: 500,
            quadrature: 3,
            epsilon: 1e-3,
            min_element_size: None,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Exposure {
    Auto,
    /// The radiance that maps to white.
    White(f64),
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageSpec {
    pub width: u32,
    pub height: u32,
    pub(crate) exposure: Exposure,
    /// 3d: show the elements as solved (flat at order 0) instead of smoothly interpolated.
    pub raw: bool,
    /// 3d: draw the outlines of the elements over the image.
    pub mesh: bool,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    pub eye: [f64; 3],
    pub(crate) look_at: [f64; 3],
    pub(crate) up: [f64; 3],
    pub(crate) fov_deg: f64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Reference {
    Exact,
    Finer { order: usize, resolution: usize },
}

#[derive(Debug, Clone, PartialEq)]
pub struct Output {
    pub image: ImageSpec,
    /// `None`: framed automatically.
    pub camera: Option<Camera>,
    pub(crate) grid: usize,
    pub(crate) reference: Option<Reference>,
    pub(crate) coefficients: usize,
    /// List B at the positions of `triangle` and `mesh` surfaces.
    pub(crate) vertices: bool,
}

impl Default for Output {
    fn default() -> Self {
        Output {
            image: ImageSpec {
                width: 512,
                height: 512,
                exposure: Exposure::Auto,
                raw: false,
                mesh: false,
            },
            camera: None,
            grid: 8,
            reference: None,
            coefficients: 256,
            vertices: false,
        }
    }
}

impl Job {
    /// Number of surfaces (1 for `fredholm`, whose domain is one "surface").
    fn surface_count(&self) -> usize {
        match &self.scene.kind {
            SceneKind::Flatland(s) => s.len(),
            SceneKind::ThreeD(q) => q.surfaces.len(),
            SceneKind::Fredholm(_) => 1,
        }
    }

    /// Names of the surfaces in document order (`"domain"` for `fredholm`).
    pub fn surface_names(&self) -> Vec<String> {
        match &self.scene.kind {
            SceneKind::Flatland(s) => s.iter().map(|s| s.name.clone()).collect(),
            SceneKind::ThreeD(q) => q.surfaces.iter().map(|s| s.name.clone()).collect(),
            SceneKind::Fredholm(_) => vec!["domain".to_string()],
        }
    }

    /// Basis functions per surface of the projection method: `n (m+1)` in 1D, `(n (m+1))²` on a quad.
    fn basis_per_surface(&self) -> usize {
        let per_side = self.solver.resolution * (self.solver.order + 1);
        match self.scene.kind {
            SceneKind::ThreeD(_) => per_side * per_side,
            _ => per_side,
        }
    }

    /// Size of the projection method's linear system.
    pub fn basis_size(&self) -> usize {
        self.surface_count() * self.basis_per_surface()
    }
}
