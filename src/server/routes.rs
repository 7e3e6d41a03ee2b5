//! The handlers of `docs/api.md`, one per route, and the reading of a job document from a
//! request (content type → size → UTF-8 → JSON → document), each failure its own status.

use super::problem::Problem;
use super::queue::{Entry, JobState, JobStatus, Submitted};
use super::AppState;
use crate::scene::Job;
use axum::body::Body;
use axum::extract::{Path, Query, Request, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::get;
use axum::{Json, Router};
use futures_util::StreamExt;
use serde::Deserialize;
use serde_json::Value;
use sha2::{Digest, Sha256};
use std::convert::Infallible;
use std::sync::Arc;

pub(super) fn router(state: AppState) -> Router {
    let router = Router::new()
        .route("/api/v1/jobs", get(list_jobs).post(create_job))
        .route("/api/v1/jobs/{id}", get(job_status).delete(delete_job))
        .route("/api/v1/jobs/{id}/events", get(job_events))
        .route("/api/v1/jobs/{id}/result", get(job_result))
        .route("/api/v1/jobs/{id}/scene.glb", get(job_model))
        .route("/api/v1/jobs/{id}/{artifact}", get(job_artifact))
        .route("/api/v1/jobs/{id}/surfaces/{file}", get(job_surface))
        .route("/api/v1/render", axum::routing::post(render_now))
        .route("/api/v1/openapi.json", get(openapi))
        .route("/", get(index))
        .route("/static/{file}", get(static_file))
        .route("/static/vendor/three/{*path}", get(vendored))
        // browsers ask for it whatever the page says
        .route(
            "/favicon.ico",
            get(|| static_file(Path("favicon.svg".to_string()))),
        )
        .route("/scenes/{file}", get(scene_file));
    counted(router, &state)
        .fallback(|| async { Problem::new(StatusCode::NOT_FOUND, "no such route") })
        .with_state(state)
}

/// `POST /api/v1/import`: outside the body limit of the job routes, since a model may be
/// larger than a document; it reads at most `max_import_bytes` itself.
pub(super) fn import_router(state: AppState) -> Router {
    let router = Router::new().route(
        "/api/v1/import",
        axum::routing::post(import_model).layer(axum::extract::DefaultBodyLimit::disable()),
    );
    counted(router, &state).with_state(state)
}

/// The probes and the metrics: answered outside the request limits, so that a busy server
/// still says it is alive.
pub(super) fn probes(state: AppState) -> Router {
    let router = Router::new()
        .route("/healthz", get(healthz))
        .route("/readyz", get(readyz))
        .route("/metrics", get(metrics));
    counted(router, &state).with_state(state)
}

/// The routes of `router`, counted in the request metrics.
fn counted(router: Router<AppState>, state: &AppState) -> Router<AppState> {
    router.route_layer(axum::middleware::from_fn_with_state(
        state.metrics.clone(),
        super::metrics::count_requests,
    ))
}

/// Reads and validates a job document: 415 unless the content type is JSON, 413 past
/// `max_body_bytes`, 400 unless UTF-8 JSON, 422 with every path at fault.
async fn read_document(
    state: &AppState,
    headers: &HeaderMap,
    body: Body,
) -> Result<(Value, Job), Problem> {
    let content_type = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("");
    let mime = content_type
        .split(';')
        .next()
        .unwrap_or("")
        .trim()
        .to_ascii_lowercase();
    if !(mime == "application/json"
        || (mime.starts_with("application/") && mime.ends_with("+json")))
    {
        return Err(Problem::new(
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            format!("send the job document as application/json (got {content_type:?})"),
        ));
    }
    let limit = state.config.max_body_bytes;
    let bytes = axum::body::to_bytes(body, limit).await.map_err(|e| {
        let text = format!("{e} {:?}", std::error::Error::source(&e));
        if text.to_ascii_lowercase().contains("length limit") {
            Problem::new(
                StatusCode::PAYLOAD_TOO_LARGE,
                crate::server::problem::too_large("max_body_bytes", limit),
            )
        } else {
            Problem::new(
                StatusCode::BAD_REQUEST,
                format!("could not read the body: {e}"),
            )
        }
    })?;
    let text = std::str::from_utf8(&bytes).map_err(|e| {
        Problem::new(
            StatusCode::BAD_REQUEST,
            format!("the body is not UTF-8: {e}"),
        )
    })?;
    let value: Value = serde_json::from_str(text).map_err(|e| {
        // JSON nested deeper than the parser follows (128 levels) is still JSON: it is an
        // invalid document, since none of its fields nests that deep
        if e.to_string().starts_with("recursion limit exceeded") {
            return Problem::invalid(&crate::scene::DocumentErrors(vec![
                crate::scene::FieldError {
                    path: String::new(),
                    message: format!(
                        "nested deeper than 128 levels ({e}); a job document nests 6 levels at most"
                    ),
                },
            ]));
        }
        Problem::new(
            StatusCode::BAD_REQUEST,
            format!("the body is not JSON: {e}"),
        )
        .with_type("not-json", "Not JSON")
    })?;
    let job = crate::scene::parse_text(text, &value, &state.config.limits())
        .map_err(|e| Problem::invalid(&e))?;
    Ok((value, job))
}

async fn blocking<T: Send + 'static>(f: impl FnOnce() -> T + Send + 'static) -> T {
    tokio::task::spawn_blocking(f)
        .await
        .expect("a blocking task panicked")
}

async fn entry(state: &AppState, id: &str) -> Result<Arc<Entry>, Problem> {
    state
        .queue
        .find(id)
        .await?
        .ok_or_else(|| Problem::not_found(&format!("job {id}")))
}

async fn submit(
    state: &AppState,
    document: Value,
    job: Job,
    durable: bool,
) -> Result<Submitted, Problem> {
    let queue = state.queue.clone();
    blocking(move || queue.submit(document, job, durable)).await
}

/// Queue a job document.
#[utoipa::path(post, path = "/api/v1/jobs", tag = "jobs",
    request_body(content = super::openapi::JobDocument, content_type = "application/json"),
    responses(
        (status = 202, description = "queued", body = JobStatus, headers(("Location" = String, description = "the job"))),
        (status = 200, description = "the same document was already submitted: its job", body = JobStatus),
        (status = 400, description = "not JSON or not UTF-8", body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "body too large", body = Problem, content_type = "application/problem+json"),
        (status = 415, description = "not application/json", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "invalid document, every path at fault", body = Problem, content_type = "application/problem+json"),
        (status = 429, description = "queue full (Retry-After)", body = Problem, content_type = "application/problem+json"),
    ))]
async fn create_job(
    State(state): State<AppState>,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, Problem> {
    let (document, job) = read_document(&state, &headers, body).await?;
    let (status, entry) = match submit(&state, document, job, true).await? {
        Submitted::New(e) => (StatusCode::ACCEPTED, e),
        Submitted::Existing(e) if e.status().state.is_final() => (StatusCode::OK, e),
        Submitted::Existing(e) => (StatusCode::ACCEPTED, e),
    };
    let job = entry.status();
    let location = HeaderValue::from_str(&job.links.this).expect("ids are hex");
    Ok((status, [(header::LOCATION, location)], Json(job)).into_response())
}

/// The most jobs one list answers; a larger `limit` is capped to it.
const MAX_LIST: u64 = 1000;

#[derive(Debug, Deserialize, utoipa::IntoParams)]
#[into_params(parameter_in = Query)]
struct ListQuery {
    /// At most this many: a whole number from 0 to 1000, default 50. A larger number is
    /// answered with at most 1000 jobs and says so in the `Limit-Capped` and `Link` headers.
    #[param(value_type = Option<u64>, minimum = 0)]
    limit: Option<String>,
}

/// Recent jobs, newest first.
#[utoipa::path(get, path = "/api/v1/jobs", tag = "jobs", params(ListQuery),
    responses(
        (status = 200, body = Vec<JobStatus>, headers(
            ("Limit-Capped" = String, description = "only when `limit` was above 1000: the limit asked for and the one applied, e.g. `2000; applied=1000`"),
            ("Link" = String, description = "only when `limit` was capped: the list's own URI with the limit applied, `rel=\"self\"`"),
        )),
        (status = 400, description = "`limit` is not a whole number from 0 up", body = Problem, content_type = "application/problem+json"),
    ))]
async fn list_jobs(
    State(state): State<AppState>,
    Query(q): Query<ListQuery>,
) -> Result<Response, Problem> {
    let asked = match q.limit.as_deref() {
        None => 50,
        Some(text) => text.trim().parse::<u64>().map_err(|_| {
            Problem::new(
                StatusCode::BAD_REQUEST,
                format!(
                    "limit is a whole number from 0 to {MAX_LIST} (default 50; a larger one is capped to {MAX_LIST}); found \"{text}\""
                ),
            )
            .with_type("invalid-parameter", "Invalid query parameter")
        })?,
    };
    let applied = asked.min(MAX_LIST);
    let list = Json(state.queue.recent(applied as usize).await?);
    if asked > applied {
        let capped = format!("{asked}; applied={applied}");
        let link = format!("</api/v1/jobs?limit={applied}>; rel=\"self\"");
        let headers = [
            (
                header::HeaderName::from_static("limit-capped"),
                HeaderValue::from_str(&capped).expect("ASCII"),
            ),
            (header::LINK, HeaderValue::from_str(&link).expect("ASCII")),
        ];
        return Ok((headers, list).into_response());
    }
    Ok(list.into_response())
}

/// A job's status.
#[utoipa::path(get, path = "/api/v1/jobs/{id}", tag = "jobs", params(("id" = String, Path)),
    responses((status = 200, body = JobStatus), (status = 404, body = Problem, content_type = "application/problem+json")))]
async fn job_status(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Json<JobStatus>, Problem> {
    Ok(Json(entry(&state, &id).await?.status()))
}

/// Cancel a job (a running solve stops within a second) and forget it.
#[utoipa::path(delete, path = "/api/v1/jobs/{id}", tag = "jobs", params(("id" = String, Path)),
    responses((status = 204), (status = 404, body = Problem, content_type = "application/problem+json")))]
async fn delete_job(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<StatusCode, Problem> {
    let queue = state.queue.clone();
    let key = id.clone();
    match blocking(move || queue.delete(&key)).await {
        Ok(true) => Ok(StatusCode::NO_CONTENT),
        Ok(false) => Err(Problem::not_found(&format!("job {id}"))),
        Err(e) => Err(Problem::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            e.to_string(),
        )),
    }
}

/// The status as Server-Sent Events (`event: status`), one per change, closing when the job
/// ends (or the server shuts down).
#[utoipa::path(get, path = "/api/v1/jobs/{id}/events", tag = "jobs", params(("id" = String, Path)),
    responses((status = 200, description = "text/event-stream of JobStatus events", body = String, content_type = "text/event-stream"),
        (status = 404, body = Problem, content_type = "application/problem+json")))]
async fn job_events(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Response, Problem> {
    let rx = entry(&state, &id).await?.subscribe();
    let stream =
        futures_util::stream::unfold((rx, false, true), |(mut rx, ended, first)| async move {
            if ended || (!first && rx.changed().await.is_err()) {
                return None;
            }
            let status = rx.borrow_and_update().clone();
            let ended = status.state.is_final();
            let event = Event::default()
                .event("status")
                .json_data(&status)
                .expect("a status serialises");
            Some((Ok::<_, Infallible>(event), (rx, ended, false)))
        })
        .take_until(state.shutdown.clone().cancelled_owned());
    Ok(Sse::new(stream)
        .keep_alive(KeepAlive::default())
        .into_response())
}

/// 404 for an unknown job, 409 (with the job's state) until it has succeeded.
async fn finished(state: &AppState, id: &str) -> Result<JobStatus, Problem> {
    let status = entry(state, id).await?.status();
    match status.state {
        JobState::Succeeded => Ok(status),
        JobState::Failed => Err(Problem::new(
            StatusCode::CONFLICT,
            format!(
                "job {id} failed: {}",
                status.error.as_ref().map_or("", |e| e.detail.as_str())
            ),
        )
        .with_type("job-failed", "Job failed")),
        s => Err(Problem::new(
            StatusCode::CONFLICT,
            format!(
                "job {id} is {}; try again when it has succeeded",
                s.as_str()
            ),
        )
        .with_type("not-finished", "Not finished")),
    }
}

async fn stored(state: &AppState, id: &str, name: &str) -> Result<Vec<u8>, Problem> {
    let queue = state.queue.clone();
    let (key, file) = (id.to_string(), name.to_string());
    match blocking(move || queue.file(&key, &file)).await {
        Ok(Some(bytes)) => Ok(bytes),
        Ok(None) => Err(Problem::not_found(&format!("{name} for job {id}"))),
        Err(e) => Err(Problem::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            e.to_string(),
        )),
    }
}

/// A file of the job that `entry` waited for: as this process's solve wrote it, when it was
/// solved here with a shared database ([`Entry::written_file`]: not read back), else from the
/// store.
async fn answer_file(state: &AppState, entry: &Entry, name: &str) -> Result<Vec<u8>, Problem> {
    match entry.written_file(name) {
        Some(bytes) => Ok(bytes),
        None => stored(state, &entry.id, name).await,
    }
}

/// The result JSON of a job.
#[utoipa::path(get, path = "/api/v1/jobs/{id}/result", tag = "results", params(("id" = String, Path)),
    responses((status = 200, body = super::openapi::ResultDocument),
        (status = 404, body = Problem, content_type = "application/problem+json"),
        (status = 409, body = Problem, content_type = "application/problem+json")))]
pub(super) async fn job_result(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Response, Problem> {
    finished(&state, &id).await?;
    let bytes = stored(&state, &id, "result.json").await?;
    Ok(([(header::CONTENT_TYPE, "application/json")], bytes).into_response())
}

/// `image.png`, `sparsity.png` or `coefficients.png` of a job.
#[utoipa::path(get, path = "/api/v1/jobs/{id}/{artifact}", tag = "results",
    params(("id" = String, Path), ("artifact" = String, Path, description = "image.png, sparsity.png or coefficients.png")),
    responses((status = 200, content_type = "image/png", body = super::openapi::Png),
        (status = 304, description = "If-None-Match matched the ETag"),
        (status = 404, body = Problem, content_type = "application/problem+json"),
        (status = 409, body = Problem, content_type = "application/problem+json")))]
async fn job_artifact(
    State(state): State<AppState>,
    Path((id, artifact)): Path<(String, String)>,
    headers: HeaderMap,
) -> Result<Response, Problem> {
    if !matches!(
        artifact.as_str(),
        "image.png" | "sparsity.png" | "coefficients.png"
    ) {
        return Err(Problem::not_found(&format!(
            "artifact {artifact} (image.png, sparsity.png, coefficients.png)"
        )));
    }
    finished(&state, &id).await?;
    let bytes = stored(&state, &id, &artifact).await?;
    Ok(png(bytes, &headers))
}

/// `scene.glb` of a 3d job: the solved scene as binary glTF with the lighting baked in.
#[utoipa::path(get, path = "/api/v1/jobs/{id}/scene.glb", tag = "results",
    params(("id" = String, Path)),
    responses((status = 200, content_type = "model/gltf-binary", body = super::openapi::Glb,
            description = "the solved surfaces as a crack-free triangle mesh, vertex colours (COLOR_0) the displayed radiance, unlit (KHR_materials_unlit), the exposure in the scene's extras"),
        (status = 304, description = "If-None-Match matched the ETag"),
        (status = 404, description = "no such job, or not a 3d job", body = Problem, content_type = "application/problem+json"),
        (status = 409, body = Problem, content_type = "application/problem+json")))]
async fn job_model(
    State(state): State<AppState>,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> Result<Response, Problem> {
    let status = entry(&state, &id).await?.status();
    if status.kind != "3d" {
        return Err(Problem::not_found(&format!(
            "scene.glb of job {id}: only 3d jobs have one (this one is {})",
            status.kind
        )));
    }
    finished(&state, &id).await?;
    let bytes = stored(&state, &id, "scene.glb").await?;
    Ok(immutable(bytes, "model/gltf-binary", &headers))
}

/// The image of one surface.
#[utoipa::path(get, path = "/api/v1/jobs/{id}/surfaces/{file}", tag = "results",
    params(("id" = String, Path), ("file" = String, Path, description = "<surface name>.png")),
    responses((status = 200, content_type = "image/png", body = super::openapi::Png),
        (status = 304, description = "If-None-Match matched the ETag"),
        (status = 404, body = Problem, content_type = "application/problem+json"),
        (status = 409, body = Problem, content_type = "application/problem+json")))]
async fn job_surface(
    State(state): State<AppState>,
    Path((id, file)): Path<(String, String)>,
    headers: HeaderMap,
) -> Result<Response, Problem> {
    let Some(name) = file.strip_suffix(".png") else {
        return Err(Problem::not_found(&format!(
            "surface image {file} (ask for <name>.png)"
        )));
    };
    let status = entry(&state, &id).await?.status();
    if !status.links.surfaces.contains_key(name) {
        return Err(Problem::not_found(&format!("surface {name} in job {id}")));
    }
    finished(&state, &id).await?;
    let bytes = stored(&state, &id, &format!("surfaces/{name}.png")).await?;
    Ok(png(bytes, &headers))
}

/// A PNG with a strong ETag (its hash) and immutable caching: the same document always gives
/// the same bytes.
fn png(bytes: Vec<u8>, headers: &HeaderMap) -> Response {
    immutable(bytes, "image/png", headers)
}

/// A file of a finished job with a strong ETag (its hash) and immutable caching.
fn immutable(bytes: Vec<u8>, mime: &'static str, headers: &HeaderMap) -> Response {
    let digest = Sha256::digest(&bytes);
    let etag = format!(
        "\"{}\"",
        digest[..16]
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect::<String>()
    );
    let cache = (header::CACHE_CONTROL, "public, max-age=31536000, immutable");
    let matches = headers
        .get(header::IF_NONE_MATCH)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| {
            // weak comparison (RFC 9110 13.1.2): W/"x" matches "x"
            v.split(',')
                .map(|t| t.trim())
                .any(|t| t == "*" || t.strip_prefix("W/").unwrap_or(t) == etag)
        });
    if matches {
        return (
            StatusCode::NOT_MODIFIED,
            [(header::ETAG, etag), (cache.0, cache.1.to_string())],
        )
            .into_response();
    }
    (
        [
            (header::CONTENT_TYPE, mime.to_string()),
            (header::ETAG, etag),
            (cache.0, cache.1.to_string()),
        ],
        bytes,
    )
        .into_response()
}

/// Solve and answer at once: `image/png`, or the result JSON with `Accept: application/json`.
/// The job is an ordinary job (same id for the same document), so its result stays available.
#[utoipa::path(post, path = "/api/v1/render", tag = "jobs",
    request_body(content = super::openapi::JobDocument, content_type = "application/json"),
    responses(
        (status = 200, description = "the image, or the result when Accept ranks application/json above image/png", content(
            (super::openapi::Png = "image/png"),
            (super::openapi::ResultDocument = "application/json")
        )),
        (status = 400, body = Problem, content_type = "application/problem+json"),
        (status = 413, body = Problem, content_type = "application/problem+json"),
        (status = 415, body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "invalid document, or a solve this build does not support", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "the job was cancelled while the client waited", body = Problem, content_type = "application/problem+json"),
        (status = 500, description = "the solve failed", body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "would wait longer than sync_timeout (Location: the job, which goes on), the queue is full, or too many requests at once (max_concurrent_requests); Retry-After", body = Problem, content_type = "application/problem+json"),
        (status = 504, description = "the solve ran past job_timeout", body = Problem, content_type = "application/problem+json"),
    ))]
async fn render_now(
    State(state): State<AppState>,
    headers: HeaderMap,
    request: Request,
) -> Result<Response, Problem> {
    let (document, job) = read_document(&state, &headers, request.into_body()).await?;
    // The client waits for the answer: no need to wait for the disk before solving.
    let entry = match submit(&state, document, job, false).await {
        Ok(Submitted::New(e) | Submitted::Existing(e)) => e,
        Err(p) if p.status == 429 => {
            let mut p = p;
            p.status = 503;
            p.title = "Service Unavailable".into();
            return Err(p);
        }
        Err(p) => return Err(p),
    };
    let limit = state.config.sync_timeout;
    let Some(status) = wait_final(&entry, limit).await else {
        // from here the job is the client's to follow by its id: on disk before the answer
        let queue = state.queue.clone();
        blocking(move || queue.sync()).await?;
        return Err(Problem::new(
            StatusCode::SERVICE_UNAVAILABLE,
            format!(
                "the solve takes longer than sync_timeout ({limit:?}); it goes on as job {}",
                entry.id
            ),
        )
        .with_type("sync-timeout", "Too slow to answer at once")
        .location(format!("/api/v1/jobs/{}", entry.id))
        .retry_after(limit.as_secs().max(1)));
    };
    match status.state {
        JobState::Succeeded => {}
        JobState::Failed => {
            return Err(status
                .error
                .map(|e| e.to_problem())
                .unwrap_or_else(|| Problem::new(StatusCode::INTERNAL_SERVER_ERROR, "failed")))
        }
        _ => return Err(Problem::new(StatusCode::CONFLICT, "the job was cancelled")),
    }
    let wants_json = headers
        .get(header::ACCEPT)
        .and_then(|v| v.to_str().ok())
        .is_some_and(prefers_json);
    let location = (header::CONTENT_LOCATION, status.links.this.clone());
    if wants_json {
        let bytes = answer_file(&state, &entry, "result.json").await?;
        Ok((
            [
                (header::CONTENT_TYPE, "application/json".to_string()),
                location,
            ],
            bytes,
        )
            .into_response())
    } else {
        let bytes = answer_file(&state, &entry, "image.png").await?;
        let mut res = png(bytes, &HeaderMap::new());
        res.headers_mut().insert(
            location.0,
            HeaderValue::from_str(&location.1).expect("ids are hex"),
        );
        Ok(res)
    }
}

/// Whether an `Accept` header asks for the result JSON rather than the PNG (RFC 9110 §12.5.1):
/// each type gets the quality of the most specific range that matches it (`*/*`, `image/*`,
/// `image/png`; q = 1 unless given), and JSON wins only with the higher one, so that the PNG
/// stays the default, as `docs/api.md` has it. Written out because only these two types are
/// offered; a negotiation crate would bring a media-type parser for that.
fn prefers_json(accept: &str) -> bool {
    let quality = |kind: &str, sub: &str| {
        let mut best: Option<(u8, f64)> = None;
        for range in accept.split(',') {
            let mut parts = range.split(';').map(str::trim);
            let Some((k, s)) = parts.next().and_then(|m| m.split_once('/')) else {
                continue;
            };
            let (k, s) = (k.to_ascii_lowercase(), s.to_ascii_lowercase());
            let specificity = match (k.as_str(), s.as_str()) {
                ("*", "*") => 0,
                (k2, "*") if k2 == kind => 1,
                (k2, s2) if k2 == kind && s2 == sub => 2,
                _ => continue,
            };
            let q = parts
                .filter_map(|p| p.split_once('='))
                .find(|(name, _)| name.trim().eq_ignore_ascii_case("q"))
                .and_then(|(_, v)| v.trim().parse::<f64>().ok())
                .unwrap_or(1.0)
                .clamp(0.0, 1.0);
            if best.is_none_or(|(b, _)| specificity > b) {
                best = Some((specificity, q));
            }
        }
        best.map_or(0.0, |(_, q)| q)
    };
    quality("application", "json") > quality("image", "png")
}

/// The job's final status, or `None` past `limit`.
async fn wait_final(entry: &Entry, limit: std::time::Duration) -> Option<JobStatus> {
    let mut rx = entry.subscribe();
    let waited = tokio::time::timeout(limit, rx.wait_for(|s| s.state.is_final())).await;
    match waited {
        Ok(Ok(s)) => Some(s.clone()),
        // The sender is gone: the job was forgotten; its last status says why.
        Ok(Err(_)) => Some(entry.status()),
        Err(_) => None,
    }
}

/// This API as OpenAPI 3.
#[utoipa::path(get, path = "/api/v1/openapi.json", tag = "operations", responses((status = 200, description = "OpenAPI 3 document")))]
async fn openapi() -> Json<utoipa::openapi::OpenApi> {
    Json(super::openapi::document())
}

/// Alive.
#[utoipa::path(get, path = "/healthz", tag = "operations", responses((status = 200, description = "ok")))]
async fn healthz() -> &'static str {
    "ok\n"
}

/// Ready to take jobs (not shutting down, room in the queue).
#[utoipa::path(get, path = "/readyz", tag = "operations",
    responses((status = 200, description = "ready"), (status = 503, body = Problem, content_type = "application/problem+json")))]
async fn readyz(State(state): State<AppState>) -> Result<&'static str, Problem> {
    if state.queue.ready() && !state.shutdown.is_cancelled() {
        Ok("ready\n")
    } else {
        Err(Problem::new(
            StatusCode::SERVICE_UNAVAILABLE,
            "not taking jobs (queue full, job store out of reach, or shutting down)",
        )
        .retry_after(5))
    }
}

/// Prometheus text exposition.
#[utoipa::path(get, path = "/metrics", tag = "operations", responses((status = 200, description = "Prometheus metrics in the OpenMetrics text format", body = String, content_type = "application/openmetrics-text; version=1.0.0; charset=utf-8")))]
async fn metrics(State(state): State<AppState>) -> Response {
    state.queue.update_gauges();
    (
        [(
            header::CONTENT_TYPE,
            "application/openmetrics-text; version=1.0.0; charset=utf-8",
        )],
        state.metrics.encode(),
    )
        .into_response()
}

/// The web page.
#[utoipa::path(get, path = "/", tag = "operations", responses((status = 200, body = String, content_type = "text/html", description = "the web page")))]
/// The page, with this server's limits in its form.
async fn index(State(state): State<AppState>) -> Html<String> {
    Html(
        include_str!("../../static/index.html")
            .replace("{{max_order}}", &state.config.max_order.to_string()),
    )
}

async fn static_file(Path(file): Path<String>) -> Result<Response, Problem> {
    let (body, mime) = match file.as_str() {
        "app.js" => (
            include_str!("../../static/app.js"),
            "text/javascript; charset=utf-8",
        ),
        "style.css" => (
            include_str!("../../static/style.css"),
            "text/css; charset=utf-8",
        ),
        "view3d.js" => (
            include_str!("../../static/view3d.js"),
            "text/javascript; charset=utf-8",
        ),
        "favicon.svg" => (include_str!("../../static/favicon.svg"), "image/svg+xml"),
        _ => return Err(Problem::not_found(&format!("static file {file}"))),
    };
    Ok((
        [
            (header::CONTENT_TYPE, mime),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        body,
    )
        .into_response())
}

/// three.js as vendored in `static/vendor/three/` (its README says which files and version),
/// embedded: the page's 3D view needs nothing from elsewhere.
const VENDORED: [(&str, &str); 7] = [
    (
        "build/three.module.min.js",
        include_str!("../../static/vendor/three/build/three.module.min.js"),
    ),
    (
        "build/three.core.min.js",
        include_str!("../../static/vendor/three/build/three.core.min.js"),
    ),
    (
        "examples/jsm/loaders/GLTFLoader.js",
        include_str!("../../static/vendor/three/examples/jsm/loaders/GLTFLoader.js"),
    ),
    (
        "examples/jsm/utils/BufferGeometryUtils.js",
        include_str!("../../static/vendor/three/examples/jsm/utils/BufferGeometryUtils.js"),
    ),
    (
        "examples/jsm/utils/SkeletonUtils.js",
        include_str!("../../static/vendor/three/examples/jsm/utils/SkeletonUtils.js"),
    ),
    (
        "examples/jsm/controls/OrbitControls.js",
        include_str!("../../static/vendor/three/examples/jsm/controls/OrbitControls.js"),
    ),
    ("LICENSE", include_str!("../../static/vendor/three/LICENSE")),
];

/// A vendored three.js file; they change only with the binary, so they are cached for a day.
async fn vendored(Path(path): Path<String>) -> Result<Response, Problem> {
    let Some((name, body)) = VENDORED.iter().find(|(n, _)| *n == path) else {
        return Err(Problem::not_found(&format!(
            "static file vendor/three/{path}"
        )));
    };
    let mime = if name.ends_with(".js") {
        "text/javascript; charset=utf-8"
    } else {
        "text/plain; charset=utf-8"
    };
    Ok((
        [
            (header::CONTENT_TYPE, mime),
            (header::CACHE_CONTROL, "public, max-age=86400"),
        ],
        *body,
    )
        .into_response())
}

/// The example scenes shipped in `scenes/`, embedded.
const SCENES: [(&str, &str); 8] = [
    (
        "flatland-parallel",
        include_str!("../../scenes/flatland-parallel.json"),
    ),
    (
        "flatland-perpendicular",
        include_str!("../../scenes/flatland-perpendicular.json"),
    ),
    (
        "flatland-occluded",
        include_str!("../../scenes/flatland-occluded.json"),
    ),
    (
        "flatland-room",
        include_str!("../../scenes/flatland-room.json"),
    ),
    (
        "fredholm-degenerate",
        include_str!("../../scenes/fredholm-degenerate.json"),
    ),
    ("plates-3d", include_str!("../../scenes/plates-3d.json")),
    ("cornell-box", include_str!("../../scenes/cornell-box.json")),
    (
        "tetrahedron-mesh",
        include_str!("../../scenes/tetrahedron-mesh.json"),
    ),
];

async fn scene_file(Path(file): Path<String>) -> Result<Response, Problem> {
    if file == "index.json" {
        let names: Vec<&str> = SCENES.iter().map(|(n, _)| *n).collect();
        return Ok(Json(names).into_response());
    }
    let name = file.strip_suffix(".json").unwrap_or(&file);
    let (_, text) = SCENES
        .iter()
        .find(|(n, _)| *n == name)
        .ok_or_else(|| Problem::not_found(&format!("example scene {name}")))?;
    Ok(([(header::CONTENT_TYPE, "application/json")], *text).into_response())
}

#[cfg(test)]
mod negotiation {
    use super::prefers_json;

    #[test]
    fn the_png_is_the_default_and_json_wins_only_with_a_higher_quality() {
        for (accept, json) in [
            ("application/json", true),
            ("Application/JSON", true),
            ("image/png", false),
            ("*/*", false),
            ("text/html", false),
            ("application/json, image/png", false),
            ("image/png;q=0.5, application/json", true),
            ("application/json;q=0.9, image/png", false),
            ("application/json;q=0, */*", false),
            ("image/*;q=0.1, application/*", true),
            ("image/png;q=0, image/*", false),
            ("application/json; charset=utf-8; q=0.8, */*;q=0.5", true),
            ("*/*;q=0.2, application/json;q=0.1", false),
            ("garbage, application/json;q=oops", true),
        ] {
            assert_eq!(prefers_json(accept), json, "{accept}");
        }
    }
}

/// A request body read whole, at most `limit` bytes (else 413, naming `setting`).
async fn read_body(body: Body, limit: usize, setting: &str) -> Result<axum::body::Bytes, Problem> {
    axum::body::to_bytes(body, limit).await.map_err(|e| {
        let text = format!("{e} {:?}", std::error::Error::source(&e));
        if text.to_ascii_lowercase().contains("length limit") {
            Problem::new(
                StatusCode::PAYLOAD_TOO_LARGE,
                crate::server::problem::too_large(setting, limit),
            )
        } else {
            Problem::new(
                StatusCode::BAD_REQUEST,
                format!("could not read the body: {e}"),
            )
        }
    })
}

/// A model file of an upload: its name and bytes.
struct Upload {
    name: String,
    bytes: Vec<u8>,
    content_type: Option<String>,
}

/// The parts of a `multipart/form-data` upload, each with its file name (or field name).
async fn multipart_parts(
    parts: axum::http::request::Parts,
    bytes: axum::body::Bytes,
) -> Result<Vec<Upload>, Problem> {
    use axum::extract::FromRequest;
    let bad = |e: axum::extract::multipart::MultipartError| {
        Problem::new(
            StatusCode::BAD_REQUEST,
            format!(
                "the multipart/form-data body cannot be read: {}",
                e.body_text()
            ),
        )
    };
    let request = Request::from_parts(parts, Body::from(bytes));
    let mut multipart = axum::extract::Multipart::from_request(request, &())
        .await
        .map_err(|e| Problem::new(StatusCode::BAD_REQUEST, e.body_text()))?;
    let mut out = Vec::new();
    while let Some(field) = multipart.next_field().await.map_err(bad)? {
        let name = field
            .file_name()
            .or(field.name())
            .unwrap_or_default()
            .to_string();
        let content_type = field.content_type().map(str::to_string);
        let bytes = field.bytes().await.map_err(bad)?.to_vec();
        out.push(Upload {
            name,
            bytes,
            content_type,
        });
    }
    Ok(out)
}

/// A `Warning` header value (RFC 9111 §5.5 form, code 299): the text quoted, with what a
/// header cannot carry (quotes, backslashes, anything not visible ASCII) escaped.
fn warning_header(text: &str) -> HeaderValue {
    let mut quoted = String::with_capacity(text.len() + 16);
    for c in text.chars() {
        match c {
            '"' | '\\' => {
                quoted.push('\\');
                quoted.push(c);
            }
            ' '..='~' => quoted.push(c),
            c => quoted.push_str(&format!("\\u{{{:x}}}", c as u32)),
        }
    }
    HeaderValue::from_str(&format!("299 wavrad \"{quoted}\"")).expect("visible ASCII")
}

/// Turn a model into a job document.
///
/// The body is the model itself (`model/obj`, `model/gltf+json`, `model/gltf-binary`), or a
/// `multipart/form-data` upload of the model (the part whose file name ends in `.obj`, `.gltf`
/// or `.glb`) with the files it refers to (an OBJ's `mtllib`, a glTF's buffers and images), each
/// found by its file name. The answer is the document with one `mesh` surface per object and
/// material; what the import changed (a reflectance clamped below 1, triangles of zero area
/// dropped, a missing material or light, …) comes in `Warning` headers, one per warning, so that
/// the document stays one that the job routes accept as it is.
#[utoipa::path(post, path = "/api/v1/import", tag = "import",
    request_body(description = "the model, or a multipart/form-data upload of the model with the files it refers to", content(
        (String = "model/obj"),
        (String = "model/gltf+json"),
        (super::openapi::Binary = "model/gltf-binary"),
        (super::openapi::ModelUpload = "multipart/form-data"),
    )),
    responses(
        (status = 200, description = "the job document", body = super::openapi::JobDocument, headers(
            ("Warning" = String, description = "one per warning, `299 wavrad \"text\"`: a reflectance clamped to 0.99, triangles of zero area dropped, no emission in the model, a material or file missing, …"),
        )),
        (status = 400, description = "a multipart body that cannot be read", body = Problem, content_type = "application/problem+json"),
        (status = 413, description = "larger than max_import_bytes", body = Problem, content_type = "application/problem+json"),
        (status = 415, description = "not a model type or multipart/form-data", body = Problem, content_type = "application/problem+json"),
        (status = 422, description = "a broken model: `errors` says the file and where (`line` of an OBJ or MTL, `path`: a JSON pointer into the glTF)", body = Problem, content_type = "application/problem+json"),
    ))]
async fn import_model(
    State(state): State<AppState>,
    request: Request,
) -> Result<Response, Problem> {
    use crate::import::{Format, Model};
    let (parts, body) = request.into_parts();
    let content_type = parts
        .headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("")
        .to_string();
    let mime = content_type
        .split(';')
        .next()
        .unwrap_or("")
        .trim()
        .to_ascii_lowercase();
    let format = Format::from_media_type(&mime);
    if format.is_none() && mime != "multipart/form-data" {
        return Err(Problem::new(
            StatusCode::UNSUPPORTED_MEDIA_TYPE,
            format!("send the model as model/obj, model/gltf+json, model/gltf-binary or multipart/form-data (got {content_type:?})"),
        ));
    }
    let limit = state.config.max_import_bytes;
    let too_large = parts
        .headers
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok())
        .is_some_and(|n| n > limit as u64);
    if too_large {
        return Err(Problem::new(
            StatusCode::PAYLOAD_TOO_LARGE,
            format!("the body is larger than max_import_bytes ({limit} bytes)"),
        ));
    }
    let bytes = read_body(body, limit, "max_import_bytes").await?;
    let (model, others) = match format {
        Some(format) => {
            let ext = match format {
                Format::Obj => "obj",
                Format::Gltf => "gltf",
                Format::Glb => "glb",
            };
            let model = Upload {
                name: format!("model.{ext}"),
                bytes: bytes.to_vec(),
                content_type: None,
            };
            (model, Vec::new())
        }
        None => {
            let mut uploads = multipart_parts(parts, bytes).await?;
            let is_model = |u: &Upload| {
                Format::from_file_name(&u.name).is_some()
                    || u.content_type
                        .as_deref()
                        .is_some_and(|t| Format::from_media_type(t).is_some())
            };
            let Some(at) = uploads.iter().position(is_model) else {
                let mut p = Problem::new(
                    StatusCode::UNPROCESSABLE_ENTITY,
                    "the upload has no model: send a part whose file name ends in .obj, .gltf or .glb",
                )
                .with_type("invalid-model", "Invalid model");
                p.errors = vec![super::problem::PathError {
                    path: String::new(),
                    message: "no .obj, .gltf or .glb part".into(),
                    file: None,
                    line: None,
                }];
                return Err(p);
            };
            let model = uploads.remove(at);
            (model, uploads)
        }
    };
    let format = Format::from_file_name(&model.name)
        .or_else(|| {
            model
                .content_type
                .as_deref()
                .and_then(Format::from_media_type)
        })
        .expect("the model part has a format");
    let limits = state.config.limits();
    let max_body = state.config.max_body_bytes;
    let imported = blocking(move || {
        let files = |name: &str| -> Option<Vec<u8>> {
            let base = |n: &str| n.rsplit(['/', '\\']).next().unwrap_or(n).to_string();
            others
                .iter()
                .find(|u| u.name == name)
                .or_else(|| others.iter().find(|u| base(&u.name) == base(name)))
                .map(|u| u.bytes.clone())
        };
        let model = Model {
            file: &model.name,
            format,
            bytes: &model.bytes,
        };
        crate::import::import(model, &files, &limits).map(|imported| {
            let text = serde_json::to_vec(&imported.document).expect("a document serialises");
            (imported, text)
        })
    })
    .await
    .map_err(|e| Problem::invalid_model(&e))?;
    let (imported, text) = imported;
    let mut warnings = imported.warnings;
    if text.len() > max_body {
        warnings.push(format!(
            "the document is {} bytes, more than this server's max_body_bytes ({max_body}): it cannot be submitted here as it is",
            text.len()
        ));
    }
    let mut res = ([(header::CONTENT_TYPE, "application/json")], text).into_response();
    for w in &warnings {
        res.headers_mut().append(header::WARNING, warning_header(w));
    }
    Ok(res)
}

#[cfg(test)]
mod warning_headers {
    #[test]
    fn quotes_and_non_ascii_are_escaped() {
        let v = super::warning_header("surface \"é\" clamped");
        assert_eq!(
            v.to_str().unwrap(),
            r#"299 wavrad "surface \"\u{e9}\" clamped""#
        );
    }
}
