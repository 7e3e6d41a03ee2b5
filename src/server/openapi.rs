//! The OpenAPI 3 document of the API, generated from the handlers' annotations and the
//! transfer types (utoipa), served at `/api/v1/openapi.json`.

use super::problem::{PathError, Problem};
use super::queue::{JobFailure, JobState, JobStatus, Links, ProgressInfo};
use super::routes;
use serde::Serialize;
use utoipa::{OpenApi, ToSchema};

/// A job document (`spec/scene.md`): `scene` is required, `solver` and `output` optional.
#[derive(Serialize, ToSchema)]
pub struct JobDocument {
    #[schema(value_type = Object)]
    pub scene: serde_json::Value,
    #[schema(value_type = Option<Object>)]
    pub solver: Option<serde_json::Value>,
    #[schema(value_type = Option<Object>)]
    pub output: Option<serde_json::Value>,
}

/// The result of a job (`spec/scene.md`, "What a finished job yields").
#[derive(Serialize, ToSchema)]
pub struct ResultDocument {
    pub scene: Option<String>,
    pub kind: String,
    #[schema(value_type = Object)]
    pub solver: serde_json::Value,
    #[schema(value_type = Vec<Object>)]
    pub surfaces: Vec<serde_json::Value>,
    #[schema(value_type = Object)]
    pub coefficients: serde_json::Value,
    #[schema(value_type = Object)]
    pub metrics: serde_json::Value,
    #[schema(value_type = Object)]
    pub timings_ms: serde_json::Value,
}

#[derive(OpenApi)]
#[openapi(
    info(title = "wavrad", description = "Wavelet radiosity render service"),
    paths(
        routes::create_job,
        routes::list_jobs,
        routes::job_status,
        routes::delete_job,
        routes::job_events,
        routes::job_result,
        routes::job_artifact,
        routes::job_surface,
        routes::render_now,
        routes::openapi,
        routes::healthz,
        routes::readyz,
        routes::metrics,
        routes::index,
    ),
    components(schemas(
        JobDocument,
        ResultDocument,
        JobStatus,
        JobState,
        ProgressInfo,
        Links,
        JobFailure,
        Problem,
        PathError
    ))
)]
pub struct ApiDoc;

pub fn document() -> utoipa::openapi::OpenApi {
    ApiDoc::openapi()
}
