//! The OpenAPI 3 document of the API, generated from the handlers' annotations and the
//! transfer types (utoipa), served at `/api/v1/openapi.json`.

use super::problem::{PathError, Problem};
use super::queue::{JobFailure, JobState, JobStatus, Links, ProgressInfo};
use super::routes;
use utoipa::{OpenApi, ToSchema};

/// The job document (`docs/job-document.md`), from the types that describe what the parser
/// accepts.
pub(super) type JobDocument = crate::scene::schema::Document;

/// A PNG image (binary).
#[derive(ToSchema)]
#[schema(value_type = String, format = Binary)]
#[allow(dead_code)]
pub(super) struct Png(Vec<u8>);

/// Binary glTF 2.0 (GLB).
#[derive(ToSchema)]
#[schema(value_type = String, format = Binary)]
#[allow(dead_code)]
pub(super) struct Glb(Vec<u8>);
/// Binary content (a GLB model).
#[derive(ToSchema)]
#[schema(value_type = String, format = Binary)]
#[allow(dead_code)]
pub(super) struct Binary(Vec<u8>);

/// A model uploaded as `multipart/form-data`: the model (`.obj`, `.gltf` or `.glb`, told by its
/// file name) and the files it refers to by name (an OBJ's MTL, a glTF's `.bin` and images).
#[derive(ToSchema)]
#[allow(dead_code)]
pub(super) struct ModelUpload {
    /// The model file.
    #[schema(value_type = String, format = Binary)]
    model: Vec<u8>,
    /// The files it refers to, each under its own file name.
    #[schema(value_type = Vec<String>)]
    files: Vec<Vec<u8>>,
}

/// The result of a job (`docs/job-document.md`, "What a finished job yields"): the type it is
/// serialised from.
pub(super) type ResultDocument = crate::result::JobResult;

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
        routes::job_model,
        routes::job_surface,
        routes::render_now,
        routes::import_model,
        routes::openapi,
        routes::healthz,
        routes::readyz,
        routes::metrics,
        routes::index,
    ),
    components(schemas(
        JobDocument,
        ResultDocument,
        Png,
        Glb,
        Binary,
        ModelUpload,
        JobStatus,
        JobState,
        ProgressInfo,
        Links,
        JobFailure,
        Problem,
        PathError
    )),
    modifiers(&Shed)
)]
struct ApiDoc;

/// Every route but the probes and `/metrics` sheds load past `max_concurrent_requests`
/// with 503 and `Retry-After` (see `server::mod`): listed once here rather than on each.
struct Shed;

impl utoipa::Modify for Shed {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        use utoipa::openapi::{ContentBuilder, Ref, ResponseBuilder};
        let shed = ResponseBuilder::new()
            .description(
                "too many requests at once (max_concurrent_requests), or the queue is full; \
                 Retry-After says when to try again",
            )
            .content(
                "application/problem+json",
                ContentBuilder::new()
                    .schema(Some(Ref::from_schema_name("Problem")))
                    .build(),
            )
            .build();
        for (path, item) in openapi.paths.paths.iter_mut() {
            if ["/healthz", "/readyz", "/metrics"].contains(&path.as_str()) {
                continue;
            }
            for op in [
                &mut item.get,
                &mut item.post,
                &mut item.delete,
                &mut item.put,
                &mut item.patch,
            ]
            .into_iter()
            .flatten()
            {
                op.responses
                    .responses
                    .entry("503".to_string())
                    .or_insert_with(|| shed.clone().into());
            }
        }
    }
}

pub fn document() -> utoipa::openapi::OpenApi {
    ApiDoc::openapi()
}
