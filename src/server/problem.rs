//! Errors as RFC 9457 problem documents (`application/problem+json`), and the middleware that
//! turns every other error answer (body limits, unknown routes, time-outs, load shedding) into
//! one, so that a client only ever sees one error format.

use crate::scene::{DocumentErrors, FieldError};
use axum::body::Body;
use axum::http::{header, HeaderValue, Response, StatusCode};
use axum::response::IntoResponse;
use serde::Serialize;
use utoipa::ToSchema;

const PROBLEM_JSON: &str = "application/problem+json";

/// One error of a document: the JSON pointer at fault and what is wrong there.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub(super) struct PathError {
    pub(super) path: String,
    pub(super) message: String,
    /// For a model that cannot be imported: the file at fault (the model, its MTL, …).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) file: Option<String>,
    /// For an OBJ or MTL file: the line at fault, from 1.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) line: Option<usize>,
}

impl From<&FieldError> for PathError {
    fn from(e: &FieldError) -> Self {
        PathError {
            path: e.path.clone(),
            message: e.message.clone(),
            file: None,
            line: None,
        }
    }
}

/// An RFC 9457 problem document.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct Problem {
    #[serde(rename = "type")]
    pub(super) kind: String,
    pub(super) title: String,
    pub(super) status: u16,
    detail: String,
    /// For an invalid document: every JSON path at fault.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub(super) errors: Vec<PathError>,
    /// Seconds after which to try again (429 and 503).
    #[serde(skip)]
    retry_after: Option<u32>,
    /// Where the thing the problem is about goes on (a render that became a job).
    #[serde(skip)]
    location: Option<Box<HeaderValue>>,
}

impl Problem {
    pub(super) fn new(status: StatusCode, detail: impl Into<String>) -> Problem {
        let title = status.canonical_reason().unwrap_or("Error").to_string();
        Problem {
            kind: format!("/problems/{}", slug(&title)),
            title,
            status: status.as_u16(),
            detail: detail.into(),
            errors: Vec::new(),
            retry_after: None,
            location: None,
        }
    }

    pub(super) fn invalid(errors: &DocumentErrors) -> Problem {
        let mut p = Problem::new(
            StatusCode::UNPROCESSABLE_ENTITY,
            format!("the job document has {} error(s)", errors.0.len()),
        );
        p.kind = "/problems/invalid-document".into();
        p.title = "Invalid job document".into();
        p.errors = errors.0.iter().map(PathError::from).collect();
        p
    }

    /// A model that cannot be imported (422): where, as a JSON pointer into a glTF file or a
    /// line of an OBJ or MTL file, in `errors`.
    pub(super) fn invalid_model(error: &crate::import::ImportError) -> Problem {
        let mut p = Problem::new(StatusCode::UNPROCESSABLE_ENTITY, error.to_string());
        p.kind = "/problems/invalid-model".into();
        p.title = "Invalid model".into();
        p.errors = vec![PathError {
            path: error.pointer().to_string(),
            message: error.message.clone(),
            file: Some(error.file.clone()),
            line: error.line(),
        }];
        p
    }

    pub(super) fn not_found(what: &str) -> Problem {
        Problem::new(StatusCode::NOT_FOUND, format!("no {what}"))
    }

    pub(super) fn with_type(mut self, kind: &str, title: &str) -> Problem {
        self.kind = format!("/problems/{kind}");
        self.title = title.into();
        self
    }

    pub(super) fn location(mut self, uri: String) -> Problem {
        self.location = HeaderValue::from_str(&uri).ok().map(Box::new);
        self
    }

    pub(super) fn retry_after(mut self, seconds: u64) -> Problem {
        self.retry_after = Some(u32::try_from(seconds).unwrap_or(u32::MAX));
        self
    }

    fn status(&self) -> StatusCode {
        StatusCode::from_u16(self.status).unwrap_or(StatusCode::INTERNAL_SERVER_ERROR)
    }
}

fn slug(title: &str) -> String {
    title
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() {
                c.to_ascii_lowercase()
            } else {
                '-'
            }
        })
        .collect()
}

impl IntoResponse for Problem {
    fn into_response(self) -> axum::response::Response {
        let body = serde_json::to_vec(&self).expect("a problem serialises");
        let mut res = Response::new(Body::from(body));
        *res.status_mut() = self.status();
        res.headers_mut()
            .insert(header::CONTENT_TYPE, HeaderValue::from_static(PROBLEM_JSON));
        if let Some(s) = self.retry_after {
            res.headers_mut()
                .insert(header::RETRY_AFTER, HeaderValue::from(s));
        }
        if let Some(v) = self.location {
            res.headers_mut().insert(header::LOCATION, *v);
        }
        res
    }
}

/// Whether an answer is already a problem document.
fn is_problem(res: &axum::response::Response) -> bool {
    res.headers()
        .get(header::CONTENT_TYPE)
        .is_some_and(|v| v.as_bytes().starts_with(PROBLEM_JSON.as_bytes()))
}

/// The body limit's own 413 (a request whose `Content-Length` is over the limit is refused
/// before its handler runs, in plain text) as the handlers answer it: a problem that names the
/// limit and how to raise it.
pub(super) fn body_limit(res: axum::response::Response, limit: usize) -> axum::response::Response {
    if res.status() != StatusCode::PAYLOAD_TOO_LARGE || is_problem(&res) {
        return res;
    }
    Problem::new(
        StatusCode::PAYLOAD_TOO_LARGE,
        too_large("max_body_bytes", limit),
    )
    .into_response()
}

/// What a 413 says: the limit (`setting`, as `wavrad serve` names it with dashes), and how to
/// raise it.
pub(super) fn too_large(setting: &str, limit: usize) -> String {
    format!(
        "the body is larger than {setting} ({limit} bytes); a server started with \
         `wavrad serve --{} N` (or WAVRAD_{}) takes more",
        setting.replace('_', "-"),
        setting.to_ascii_uppercase()
    )
}

/// Middleware: an error answer (4xx, 5xx) that is not already a problem document becomes one,
/// keeping its status and its `Retry-After`, and its text as `detail`.
pub(super) async fn problem_everywhere(res: axum::response::Response) -> axum::response::Response {
    let status = res.status();
    if !(status.is_client_error() || status.is_server_error()) || is_problem(&res) {
        return res;
    }
    let retry = res.headers().get(header::RETRY_AFTER).cloned();
    let text = axum::body::to_bytes(res.into_body(), 64 * 1024)
        .await
        .map(|b| String::from_utf8_lossy(&b).trim().to_string())
        .unwrap_or_default();
    let detail = if text.is_empty() {
        status.canonical_reason().unwrap_or("error").to_string()
    } else {
        text
    };
    let mut res = Problem::new(status, detail).into_response();
    if let Some(r) = retry {
        res.headers_mut().insert(header::RETRY_AFTER, r);
    } else if status == StatusCode::SERVICE_UNAVAILABLE || status == StatusCode::TOO_MANY_REQUESTS {
        res.headers_mut()
            .insert(header::RETRY_AFTER, HeaderValue::from(1));
    }
    res
}
