//! The job document as plain serde types, for its published JSON Schema (`components/schemas`
//! of `/api/v1/openapi.json`) and for clients that want typed access to a document.
//!
//! [`parse`](super::parse) reads the same JSON by hand, so that it reports every error at once
//! with its JSON path; these types describe the shape it accepts. Two tests keep them together
//! (`tests/schema.rs`): every object of the schema lists exactly the fields that the parser
//! allows at that place, and every example scene validates against the schema and deserialises
//! into [`Document`]. What a schema cannot say (the limits of a server's configuration, a
//! parallelogram's corners, a power-of-two resolution, unique names, some light in the scene)
//! is checked by the parser alone, as `docs/job-document.md` lists.

use serde::Deserialize;
use utoipa::openapi::schema::{
    AdditionalProperties, ArrayBuilder, KnownFormat, ObjectBuilder, OneOfBuilder, Schema,
    SchemaFormat, Type,
};
use utoipa::openapi::RefOr;
use utoipa::{PartialSchema, ToSchema};

/// A job document: `scene` is required, `solver` and `output` optional (never `null`).
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(as = JobDocument)]
pub struct Document {
    pub scene: Scene,
    #[serde(default)]
    #[schema(nullable = false)]
    pub solver: Option<Solver>,
    #[serde(default)]
    #[schema(nullable = false)]
    pub output: Option<Output>,
}

/// The scene: which equation (`kind`) and what it is solved over.
#[derive(Debug, Clone, Deserialize)]
#[serde(transparent)]
pub struct Scene(pub SceneKinds);

/// [`SceneKinds`]' schema, with unknown fields refused in each kind as the parser does
/// (the derive leaves a tagged enum's variants open).
impl PartialSchema for Scene {
    fn schema() -> RefOr<Schema> {
        let mut schema = <SceneKinds as PartialSchema>::schema();
        if let RefOr::T(Schema::OneOf(one)) = &mut schema {
            for kind in &mut one.items {
                if let RefOr::T(Schema::Object(o)) = kind {
                    o.additional_properties = Some(Box::new(AdditionalProperties::FreeForm(false)));
                }
            }
        }
        schema
    }
}

impl ToSchema for Scene {
    fn schemas(schemas: &mut Vec<(String, RefOr<Schema>)>) {
        <SceneKinds as ToSchema>::schemas(schemas);
    }
}

/// The three kinds of scene, told apart by `kind`.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(tag = "kind", deny_unknown_fields)]
pub enum SceneKinds {
    /// 2D: B(x) = E(x) + ρ(x) ∫ cosθx cosθy / (2r) V(x,y) B(y) dy over segments; B in W/m.
    #[serde(rename = "flatland")]
    Flatland {
        #[serde(default)]
        #[schema(nullable = false)]
        name: Option<String>,
        /// 1 to `max_surfaces` segments.
        #[schema(min_items = 1)]
        surfaces: Vec<Segment>,
    },
    /// 3D: the same with cosθx cosθy / (π r²) over parallelograms, triangles and meshes; B in
    /// W/m².
    #[serde(rename = "3d")]
    ThreeD {
        #[serde(default)]
        #[schema(nullable = false)]
        name: Option<String>,
        /// 1 to `max_surfaces` surfaces, with at most `max_triangles` triangles in all.
        #[schema(min_items = 1)]
        surfaces: Vec<Quad>,
    },
    /// B(x) = E(x) + ∫_a^b K(x,y) B(y) dy, for checking the numerics.
    #[serde(rename = "fredholm")]
    Fredholm {
        #[serde(default)]
        #[schema(nullable = false)]
        name: Option<String>,
        /// `[a, b]` with a < b.
        domain: Pair,
        /// K(x, y) as an expression in `x` and `y`: numbers, `pi`, `+ - * / ^`, parentheses,
        /// `sin cos tan exp ln sqrt abs`.
        kernel: String,
        /// E(x) as an expression in `x`.
        source: String,
        /// The exact solution in `x`; error metrics are then measured against it.
        #[serde(default)]
        #[schema(nullable = false)]
        exact: Option<String>,
    },
}

/// A flatland surface: p(s) = a + s(b − a), front normal (b − a) turned +90°.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Segment {
    pub name: SurfaceName,
    /// `[[x0, y0], [x1, y1]]`, of non-zero length.
    #[schema(min_items = 2, max_items = 2)]
    pub segment: [Pair; 2],
    pub reflectance: Reflectance,
    #[serde(default)]
    #[schema(nullable = false)]
    pub emission: Option<Emission>,
    /// `[s0, s1]`, 0 ≤ s0 < s1 ≤ 1: the emission applies only there.
    #[serde(default)]
    #[schema(nullable = false)]
    pub emission_region: Option<UnitInterval>,
}

/// A 3D surface with exactly one of `corners`, `triangle`, `mesh`: the parallelogram
/// p(s,t) = p0 + s(p1 − p0) + t(p3 − p0), front normal (p1 − p0) × (p3 − p0); a triangle
/// (s, t ≥ 0, s + t ≤ 1 of p0 + s(p1 − p0) + t(p2 − p0)); or many triangles sharing one
/// material.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Quad {
    pub name: SurfaceName,
    /// `[p0, p1, p2, p3]`, counter-clockwise seen from the front, p0 + p2 = p1 + p3 within
    /// 1e-6 of the size, of non-zero area.
    #[serde(default)]
    #[schema(nullable = false, min_items = 4, max_items = 4)]
    pub corners: Option<[Point; 4]>,
    /// `[p0, p1, p2]`, counter-clockwise seen from the front, of non-zero area.
    #[serde(default)]
    #[schema(nullable = false, min_items = 3, max_items = 3)]
    pub triangle: Option<[Point; 3]>,
    #[serde(default)]
    #[schema(nullable = false)]
    pub mesh: Option<Mesh>,
    pub reflectance: Reflectance,
    #[serde(default)]
    #[schema(nullable = false)]
    pub emission: Option<Emission>,
    #[serde(default)]
    #[schema(nullable = false)]
    pub emission_region: Option<Region>,
}

/// Triangles that share one reflectance and emission (an object of a model).
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Mesh {
    #[schema(min_items = 1)]
    pub positions: Vec<Point>,
    /// 0-based indices into `positions`, each triangle counter-clockwise seen from its front,
    /// of non-zero area.
    #[schema(min_items = 1)]
    pub triangles: Vec<[u64; 3]>,
}

/// The part of a parallelogram's parameter domain that emits.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Region {
    pub s: UnitInterval,
    pub t: UnitInterval,
}

/// All solver settings are optional.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Solver {
    /// `projection` (the whole Galerkin matrix) or `hierarchical` (wavelet radiosity with
    /// refinement; flatland and 3d only). Default `projection`.
    #[serde(default)]
    #[schema(nullable = false, inline)]
    pub method: Option<Method>,
    /// `scaling` (piecewise Legendre polynomials) or `wavelet` (multiwavelets). Default
    /// `wavelet`.
    #[serde(default)]
    #[schema(nullable = false, inline)]
    pub basis: Option<Basis>,
    /// Polynomial degree, 0 to `max_order` (at most 15). Default 1.
    #[serde(default)]
    #[schema(nullable = false, minimum = 0, maximum = 15)]
    pub order: Option<u64>,
    /// Cells per segment or parallelogram side, 1 to `max_resolution`; a power of two for
    /// `wavelet` and `hierarchical`. Default 8.
    #[serde(default)]
    #[schema(nullable = false, minimum = 1)]
    pub resolution: Option<u64>,
    /// Which kernel-matrix coefficients survive. Default `all`.
    #[serde(default)]
    #[schema(nullable = false)]
    pub keep: Option<Keep>,
    /// `jacobi` or `gauss-seidel`. Default `jacobi`.
    #[serde(default)]
    #[schema(nullable = false, inline)]
    pub iteration: Option<Iteration>,
    /// Stop when the relative change of B between sweeps is below this; in (0, 1). Default 1e-6.
    #[serde(default)]
    #[schema(nullable = false, exclusive_minimum = 0, exclusive_maximum = 1)]
    pub tolerance: Option<f64>,
    /// 1 to 1 000 000. Default 500.
    #[serde(default)]
    #[schema(nullable = false, minimum = 1, maximum = 1000000)]
    pub max_iterations: Option<u64>,
    /// Gauss–Legendre points per cell and dimension, 1 to 64. Default order + 2.
    #[serde(default)]
    #[schema(nullable = false, minimum = 1, maximum = 64)]
    pub quadrature: Option<u64>,
    /// Hierarchical only: the refinement oracle's tolerance, relative to the brightest
    /// emission; in (0, 1). Default 1e-3.
    #[serde(default)]
    #[schema(nullable = false, exclusive_minimum = 0, exclusive_maximum = 1)]
    pub epsilon: Option<f64>,
    /// Hierarchical in 3d only: the smallest element's edge in scene units, the same on every
    /// surface. Default: the diagonal of the scene's bounding box / 64, or the smallest
    /// parallelogram's shorter side (or half its longer side, when less) if that is smaller,
    /// but at least the diagonal / 256; around a gap narrower than that between two
    /// parallelograms that see each other, elements go down to no larger than the gap.
    #[serde(default)]
    #[schema(nullable = false, exclusive_minimum = 0)]
    pub min_element_size: Option<f64>,
}

#[derive(Debug, Clone, Copy, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    Projection,
    Hierarchical,
}

#[derive(Debug, Clone, Copy, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum Basis {
    Scaling,
    Wavelet,
}

#[derive(Debug, Clone, Copy, Deserialize, ToSchema)]
#[serde(rename_all = "kebab-case")]
pub enum Iteration {
    Jacobi,
    GaussSeidel,
}

/// `"all"`, `{"top": N}` (N ≥ 1), `{"fraction": f}` (0 < f ≤ 1) or `{"threshold": t}`
/// (|coefficient| ≥ t, t ≥ 0): exactly one of them.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(untagged)]
pub enum Keep {
    All(KeepAll),
    Top(KeepTop),
    Fraction(KeepFraction),
    Threshold(KeepThreshold),
}

#[derive(Debug, Clone, Copy, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum KeepAll {
    All,
}

#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct KeepTop {
    #[schema(minimum = 1)]
    pub top: u64,
}

#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct KeepFraction {
    #[schema(exclusive_minimum = 0, maximum = 1)]
    pub fraction: f64,
}

#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct KeepThreshold {
    #[schema(minimum = 0)]
    pub threshold: f64,
}

/// All output settings are optional.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Output {
    #[serde(default)]
    #[schema(nullable = false)]
    pub image: Option<Image>,
    /// 3d: where the main image is seen from. Default: framed automatically.
    #[serde(default)]
    #[schema(nullable = false)]
    pub camera: Option<Camera>,
    /// The radiosity table: cell means over `grid` (flatland) or `grid × grid` (3d) cells of
    /// each surface; 1 to 1024. Default 8.
    #[serde(default)]
    #[schema(nullable = false, minimum = 1, maximum = 1024)]
    pub grid: Option<u64>,
    /// What the radiosity error (eq. 6) is measured against.
    #[serde(default)]
    #[schema(nullable = false)]
    pub reference: Option<Reference>,
    /// How many sorted kernel-coefficient magnitudes the result lists, 0 to 100 000.
    /// Default 256.
    #[serde(default)]
    #[schema(nullable = false, minimum = 0, maximum = 100000)]
    pub coefficients: Option<u64>,
    /// 3d: also list B at the positions of `triangle` and `mesh` surfaces. Default false.
    #[serde(default)]
    #[schema(nullable = false)]
    pub vertices: Option<bool>,
}

/// The main PNG. Width × height at most `max_image_pixels`.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Image {
    /// 1 to 16384. Default 512.
    #[serde(default)]
    #[schema(nullable = false, minimum = 1, maximum = 16384)]
    pub width: Option<u64>,
    /// 1 to 16384. Default 512.
    #[serde(default)]
    #[schema(nullable = false, minimum = 1, maximum = 16384)]
    pub height: Option<u64>,
    #[serde(default)]
    #[schema(nullable = false)]
    pub exposure: Option<Exposure>,
    /// 3d: the elements as solved, not smoothly interpolated. Default false.
    #[serde(default)]
    #[schema(nullable = false)]
    pub raw: Option<bool>,
    /// 3d: the elements' outlines drawn over the image. Default false.
    #[serde(default)]
    #[schema(nullable = false)]
    pub mesh: Option<bool>,
}

/// `"auto"` or the radiance (a number > 0) that maps to white. Default `"auto"`.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(untagged)]
pub enum Exposure {
    Auto(AutoExposure),
    White(WhiteExposure),
}

#[derive(Debug, Clone, Copy, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum AutoExposure {
    Auto,
}

/// The radiance that maps to white, > 0.
#[derive(Debug, Clone, Copy, Deserialize)]
pub struct WhiteExposure(pub f64);

impl PartialSchema for WhiteExposure {
    fn schema() -> RefOr<Schema> {
        ObjectBuilder::new()
            .schema_type(Type::Number)
            .exclusive_minimum(Some(0.0))
            .description(Some("the radiance that maps to white"))
            .into()
    }
}
impl ToSchema for WhiteExposure {}

/// 3d camera. `up` defaults to +y (+z when looking along y); `fov_deg` to 40.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Camera {
    pub eye: Point,
    /// Not equal to `eye`.
    pub look_at: Point,
    /// Not zero, not along the viewing direction.
    #[serde(default)]
    #[schema(nullable = false)]
    pub up: Option<Point>,
    /// Vertical field of view in degrees, in (0, 180).
    #[serde(default)]
    #[schema(nullable = false, exclusive_minimum = 0, exclusive_maximum = 180)]
    pub fov_deg: Option<f64>,
}

/// `"exact"` (a fredholm scene with `exact`) or a finer solve of the same scene.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(untagged)]
pub enum Reference {
    Exact(ExactReference),
    Finer(FinerReference),
}

#[derive(Debug, Clone, Copy, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum ExactReference {
    Exact,
}

/// At least as fine as the solve and not the same: order ≥ the solve's, resolution ≥ the
/// solve's.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct FinerReference {
    #[schema(minimum = 0, maximum = 15)]
    pub order: u64,
    #[schema(minimum = 1)]
    pub resolution: u64,
}

/// A number or `[r, g, b]`: the value of each channel.
fn channels(lo: f64, hi: f64, hi_exclusive: bool, what: &str) -> RefOr<Schema> {
    let number = || {
        let b = ObjectBuilder::new()
            .schema_type(Type::Number)
            .minimum(Some(lo));
        if hi_exclusive {
            b.exclusive_maximum(Some(hi))
        } else {
            b.maximum(Some(hi))
        }
    };
    OneOfBuilder::new()
        .description(Some(what))
        .item(number())
        .item(
            ArrayBuilder::new()
                .items(number())
                .min_items(Some(3))
                .max_items(Some(3)),
        )
        .into()
}

/// ρ: a number for the three channels or `[r, g, b]`, each in [0, 1).
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum Reflectance {
    Grey(f64),
    Rgb([f64; 3]),
}

impl PartialSchema for Reflectance {
    fn schema() -> RefOr<Schema> {
        channels(
            0.0,
            1.0,
            true,
            "reflectance ρ: a number for the three channels or [r, g, b], each in [0, 1)",
        )
    }
}
impl ToSchema for Reflectance {}

/// E: a number for the three channels or `[r, g, b]`, each from 0 to 1e12. Default 0.
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum Emission {
    Grey(f64),
    Rgb([f64; 3]),
}

impl PartialSchema for Emission {
    fn schema() -> RefOr<Schema> {
        channels(
            0.0,
            1e12,
            false,
            "emission E: a number for the three channels or [r, g, b], each from 0 to 1e12",
        )
    }
}
impl ToSchema for Emission {}

fn numbers(n: usize, what: &str) -> RefOr<Schema> {
    ArrayBuilder::new()
        .description(Some(what))
        .items(
            ObjectBuilder::new()
                .schema_type(Type::Number)
                .format(Some(SchemaFormat::KnownFormat(KnownFormat::Double))),
        )
        .min_items(Some(n))
        .max_items(Some(n))
        .into()
}

/// `[x, y]`.
#[derive(Debug, Clone, Copy, Deserialize)]
pub struct Pair(pub [f64; 2]);

impl PartialSchema for Pair {
    fn schema() -> RefOr<Schema> {
        numbers(2, "two numbers")
    }
}
impl ToSchema for Pair {}

/// `[x, y, z]`.
#[derive(Debug, Clone, Copy, Deserialize)]
pub struct Point(pub [f64; 3]);

impl PartialSchema for Point {
    fn schema() -> RefOr<Schema> {
        numbers(3, "a point or vector [x, y, z]")
    }
}
impl ToSchema for Point {}

/// `[s0, s1]` with 0 ≤ s0 < s1 ≤ 1.
#[derive(Debug, Clone, Copy, Deserialize)]
pub struct UnitInterval(pub [f64; 2]);

impl PartialSchema for UnitInterval {
    fn schema() -> RefOr<Schema> {
        ArrayBuilder::new()
            .description(Some("[s0, s1] with 0 ≤ s0 < s1 ≤ 1"))
            .items(
                ObjectBuilder::new()
                    .schema_type(Type::Number)
                    .minimum(Some(0.0))
                    .maximum(Some(1.0)),
            )
            .min_items(Some(2))
            .max_items(Some(2))
            .into()
    }
}
impl ToSchema for UnitInterval {}

/// A surface's name: 1 to 128 bytes, unique in the scene, no slash, backslash or control
/// character (it names the file `surfaces/<name>.png`).
#[derive(Debug, Clone, Deserialize)]
pub struct SurfaceName(pub String);

impl PartialSchema for SurfaceName {
    fn schema() -> RefOr<Schema> {
        ObjectBuilder::new()
            .schema_type(Type::String)
            .description(Some(
                "1 to 128 bytes, unique in the scene, no slash, backslash or control character",
            ))
            .min_length(Some(1))
            .max_length(Some(128))
            .pattern(Some(r"^[^/\\]+$"))
            .into()
    }
}
impl ToSchema for SurfaceName {}
