//! Prometheus metrics: jobs by state, queue depth, solve seconds, HTTP requests by route and
//! status. One registry per server (not a global recorder), so that servers in one process —
//! tests — count apart.

use axum::extract::{MatchedPath, Request, State};
use axum::middleware::Next;
use axum::response::Response;
use prometheus_client::encoding::EncodeLabelSet;
use prometheus_client::metrics::counter::Counter;
use prometheus_client::metrics::family::Family;
use prometheus_client::metrics::gauge::Gauge;
use prometheus_client::metrics::histogram::{exponential_buckets, Histogram};
use prometheus_client::registry::Registry;
use std::sync::Arc;

#[derive(Debug, Clone, Hash, PartialEq, Eq, EncodeLabelSet)]
pub(super) struct StateLabel {
    pub(super) state: String,
}

#[derive(Debug, Clone, Hash, PartialEq, Eq, EncodeLabelSet)]
struct HttpLabel {
    method: String,
    route: String,
    status: u16,
}

pub(super) struct Metrics {
    registry: Registry,
    pub(super) jobs: Family<StateLabel, Gauge>,
    pub(super) queue_depth: Gauge,
    pub(super) solve_seconds: Histogram,
    http: Family<HttpLabel, Counter>,
}

impl Default for Metrics {
    fn default() -> Self {
        let mut registry = Registry::default();
        let jobs = Family::<StateLabel, Gauge>::default();
        let queue_depth = Gauge::default();
        let solve_seconds = Histogram::new(exponential_buckets(0.005, 2.0, 16));
        let http = Family::<HttpLabel, Counter>::default();
        registry.register(
            "wavrad_jobs",
            "Jobs known to the server, by state",
            jobs.clone(),
        );
        registry.register(
            "wavrad_queue_depth",
            "Jobs waiting for a worker",
            queue_depth.clone(),
        );
        registry.register(
            "wavrad_solve_seconds",
            "Time from the start of a solve to its end, images included",
            solve_seconds.clone(),
        );
        registry.register(
            "wavrad_http_requests",
            "HTTP requests by route and status",
            http.clone(),
        );
        Metrics {
            registry,
            jobs,
            queue_depth,
            solve_seconds,
            http,
        }
    }
}

impl Metrics {
    /// The Prometheus text exposition.
    pub(super) fn encode(&self) -> String {
        let mut out = String::new();
        prometheus_client::encoding::text::encode(&mut out, &self.registry)
            .expect("writing to a String cannot fail");
        out
    }
}

/// Middleware (a route layer, so that the matched route is known): counts every answer.
pub(super) async fn count_requests(
    State(metrics): State<Arc<Metrics>>,
    req: Request,
    next: Next,
) -> Response {
    let route = req
        .extensions()
        .get::<MatchedPath>()
        .map_or_else(|| "unmatched".to_string(), |p| p.as_str().to_string());
    let method = req.method().to_string();
    let res = next.run(req).await;
    metrics
        .http
        .get_or_create(&HttpLabel {
            method,
            route,
            status: res.status().as_u16(),
        })
        .inc();
    res
}
