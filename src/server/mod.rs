//! The render service: the HTTP API of `docs/api.md` over the numerical core.
//!
//! [`app`] builds the router (tested with `oneshot`), [`run`] serves it on a listener until a
//! shutdown signal. Only this module knows HTTP, tokio or transfer types; the core stays pure.
//!
//! Architecture invariant: a handler never solves — solves run on the rayon pool of
//! [`queue::Queue`], and handlers wait on watch channels, never on threads.

mod config;
mod metrics;
pub mod openapi;
mod problem;
pub mod queue;
mod routes;
pub mod store;

use axum::error_handling::HandleErrorLayer;
use axum::http::StatusCode;
use axum::response::IntoResponse;
use axum::Router;
pub use config::Config;
use metrics::Metrics;
use problem::Problem;
use queue::{Queue, SolveFn};
use std::future::{Future, IntoFuture};
use std::sync::Arc;
use std::time::Duration;
use tokio::net::TcpListener;
use tokio_util::sync::CancellationToken;
use tower::ServiceBuilder;
use tower_http::limit::RequestBodyLimitLayer;
use tower_http::trace::TraceLayer;

/// What every handler shares.
#[derive(Clone)]
pub struct AppState {
    pub config: Arc<Config>,
    pub queue: Queue,
    metrics: Arc<Metrics>,
    /// Cancelled when the server shuts down (ends SSE streams).
    shutdown: CancellationToken,
}

impl AppState {
    /// Opens the store, restores its jobs and starts the queue. Needs a tokio runtime.
    pub fn start(
        config: Config,
        solve: SolveFn,
        shutdown: CancellationToken,
    ) -> Result<AppState, store::StoreError> {
        let metrics = Arc::new(Metrics::default());
        let queue = Queue::start(config.clone(), solve, metrics.clone(), shutdown.clone())?;
        Ok(AppState {
            config: Arc::new(config),
            queue,
            metrics,
            shutdown,
        })
    }

    /// [`AppState::start`], or with `config.database` the queue of that PostgreSQL database,
    /// connected (and its schema migrated) first. Needs a multi-threaded tokio runtime.
    async fn open(
        config: Config,
        solve: SolveFn,
        shutdown: CancellationToken,
    ) -> Result<AppState, store::StoreError> {
        let Some(url) = config.database.clone() else {
            return AppState::start(config, solve, shutdown);
        };
        config
            .check()
            .map_err(|e| store::StoreError::Io(std::io::Error::other(e)))?;
        let store = store::postgres::Postgres::connect(&url, config.database_pool).await?;
        let metrics = Arc::new(Metrics::default());
        let queue = Queue::start_shared(
            config.clone(),
            solve,
            metrics.clone(),
            shutdown.clone(),
            Arc::new(store),
        )?;
        Ok(AppState {
            config: Arc::new(config),
            queue,
            metrics,
            shutdown,
        })
    }
}

/// The router with every layer: tracing, problem documents for every error, load shedding in
/// front of a global concurrency limit (which would otherwise queue), a request time-out and
/// the body limit; the probes (`/healthz`, `/readyz`, `/metrics`) skip the limits.
pub fn app(state: AppState) -> Router {
    let config = state.config.clone();
    let limits = ServiceBuilder::new()
        .layer(HandleErrorLayer::new(|e: tower::BoxError| async move {
            overloaded(e)
        }))
        .load_shed()
        .layer(tower::limit::GlobalConcurrencyLimitLayer::new(
            config.max_concurrent_requests,
        ))
        .timeout(config.request_timeout());
    let max_body = config.max_body_bytes;
    routes::router(state.clone())
        .layer(RequestBodyLimitLayer::new(max_body))
        .layer(axum::middleware::map_response(move |res| async move {
            problem::body_limit(res, max_body)
        }))
        .merge(routes::import_router(state.clone()))
        .layer(limits)
        .merge(routes::probes(state))
        .layer(axum::middleware::map_response(problem::problem_everywhere))
        .layer(TraceLayer::new_for_http())
}

fn overloaded(e: tower::BoxError) -> axum::response::Response {
    if e.is::<tower::load_shed::error::Overloaded>() {
        Problem::new(
            StatusCode::SERVICE_UNAVAILABLE,
            "too many requests at once; try again shortly",
        )
        .with_type("overloaded", "Overloaded")
        .retry_after(1)
        .into_response()
    } else if e.is::<tower::timeout::error::Elapsed>() {
        Problem::new(StatusCode::SERVICE_UNAVAILABLE, "the request took too long")
            .with_type("timeout", "Request time-out")
            .retry_after(1)
            .into_response()
    } else {
        Problem::new(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()).into_response()
    }
}

/// Serves until `shutdown` resolves, then stops taking requests and jobs, ends SSE streams,
/// lets running solves finish for `shutdown_grace` (then leaves them queued in the store) and
/// returns. Connections still open after a further five seconds are dropped.
pub async fn run(
    listener: TcpListener,
    config: Config,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    let token = CancellationToken::new();
    let grace = config.shutdown_grace;
    let state = AppState::open(
        config,
        Arc::new(|job, progress| crate::job::run(job, progress)),
        token.clone(),
    )
    .await
    .map_err(std::io::Error::other)?;
    run_with(listener, state, shutdown, grace).await
}

/// [`run`] with a prepared state (tests substitute the solver).
pub async fn run_with(
    listener: TcpListener,
    state: AppState,
    shutdown: impl Future<Output = ()> + Send + 'static,
    grace: Duration,
) -> std::io::Result<()> {
    let token = state.shutdown.clone();
    let queue = state.queue.clone();
    tracing::info!(addr = %listener.local_addr()?, "listening");
    let signal = token.clone();
    tokio::spawn(async move {
        shutdown.await;
        signal.cancel();
    });
    let mut server = tokio::spawn(
        // No Nagle delay: a PNG answer goes out in one flight.
        axum::serve(
            axum::serve::ListenerExt::tap_io(listener, |tcp| {
                let _ = tcp.set_nodelay(true);
            }),
            app(state),
        )
        .with_graceful_shutdown(token.clone().cancelled_owned())
        .into_future(),
    );
    // the server's future ends at once when no connection is open, so both arms can be the
    // first to see the signal: both drain the queue the same way
    tokio::select! {
        _ = token.cancelled() => {}
        ended = &mut server => {
            token.cancel();
            drain(&queue, grace).await;
            return ended.map_err(std::io::Error::other)?;
        }
    }
    drain(&queue, grace).await;
    match tokio::time::timeout(Duration::from_secs(5), server).await {
        Ok(Ok(result)) => result,
        Ok(Err(join)) => Err(std::io::Error::other(join)),
        Err(_) => {
            tracing::warn!("connections still open after the deadline; closing");
            Ok(())
        }
    }
}

/// Stops the queue on shutdown and says so: what was running and queued, and after the grace
/// period, what became of the running jobs.
async fn drain(queue: &queue::Queue, grace: Duration) {
    let jobs = queue.list(usize::MAX);
    let running: Vec<String> = jobs
        .iter()
        .filter(|s| s.state == queue::JobState::Running)
        .map(|s| s.id.clone())
        .collect();
    let queued = jobs
        .iter()
        .filter(|s| s.state == queue::JobState::Queued)
        .count();
    tracing::info!(
        running = running.len(),
        queued,
        grace_seconds = grace.as_secs_f64(),
        "shutting down: no new requests or jobs are taken; running solves may finish within the grace period, queued jobs stay queued for the next start"
    );
    queue.shutdown(grace).await;
    let (mut finished, mut stopped) = (0, 0);
    for id in &running {
        match queue.get(id).map(|e| e.status().state) {
            Some(s) if s.is_final() => finished += 1,
            _ => stopped += 1,
        }
    }
    tracing::info!(
        finished,
        stopped,
        queued,
        "shut down: {finished} running job(s) finished, {stopped} stopped and left queued for the next start, {queued} queued job(s) kept"
    );
}
