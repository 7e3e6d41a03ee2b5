//! The job queue: a bounded channel of accepted jobs, a dispatcher that hands each to one of
//! `workers` rayon pools when one is free, and the live status of every job.
//!
//! Why this shape: the async runtime must never block on a solve, so solves run on rayon
//! pools, one per worker slot, each with a thread per core. A job's parallel loops run on its
//! own pool: with one shared pool a second job waited in the pool's queue behind the first
//! one's parallel work (and a thread waiting inside a parallel loop could start it on its
//! stack), so `workers` jobs did not run at once. The channel's capacity
//! is `queue_capacity`, and a full channel is answered 429. The status of a job lives in a
//! `tokio::sync::watch` channel: handlers read it, SSE streams follow it, and the solver thread
//! writes it without an async context.
//!
//! Every state change is written to the [`Store`] before it is visible, so that after a crash
//! or a restart finished jobs are still served and queued or running jobs run again.
//!
//! With a shared database (`--database`) the queue is the database's instead ([`shared`]):
//! processes claim jobs from it under a lease, and every job's status is read from it.

use super::config::Config;
use super::metrics::{Metrics, StateLabel};
use super::problem::Problem;
use super::store::{embedded::Embedded, Record, Store, StoreError};
use crate::job::{JobError, Outcome};
use crate::progress::{Phase, Progress};
use crate::scene::Job;
use axum::http::StatusCode;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use sha2::{Digest, Sha256};
use std::collections::{BTreeMap, HashMap};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicU8, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};
use tokio::sync::{mpsc, watch, Notify};
use tokio_util::sync::CancellationToken;
use utoipa::ToSchema;

mod shared;

/// What solves a job: [`crate::job::run`] in production; tests substitute their own.
pub type SolveFn = Arc<dyn Fn(&Job, &dyn Progress) -> Result<Outcome, JobError> + Send + Sync>;

/// The state of a job.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum JobState {
    Queued,
    Running,
    Succeeded,
    Failed,
    Cancelled,
}

impl JobState {
    pub fn is_final(self) -> bool {
        matches!(
            self,
            JobState::Succeeded | JobState::Failed | JobState::Cancelled
        )
    }
    pub(super) fn as_str(self) -> &'static str {
        match self {
            JobState::Queued => "queued",
            JobState::Running => "running",
            JobState::Succeeded => "succeeded",
            JobState::Failed => "failed",
            JobState::Cancelled => "cancelled",
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ProgressInfo {
    /// `queued`, `projection`, `transform`, `refinement`, `solve`, `reference`, `metrics`,
    /// `render`, `done`.
    pub phase: String,
    /// 0 to 1 within the phase.
    pub fraction: f64,
}

/// Where a job's outputs are (present from the start; 409 until the job has succeeded).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Links {
    #[serde(rename = "self")]
    pub(super) this: String,
    events: String,
    result: String,
    image: String,
    sparsity: String,
    coefficients: String,
    /// Surface name → its image.
    pub surfaces: BTreeMap<String, String>,
    /// 3d: the solved scene as binary glTF (`scene.glb`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    model: Option<String>,
}

impl Links {
    fn new(id: &str, surfaces: &[String], three_d: bool) -> Links {
        let base = format!("/api/v1/jobs/{id}");
        Links {
            this: base.clone(),
            events: format!("{base}/events"),
            result: format!("{base}/result"),
            image: format!("{base}/image.png"),
            sparsity: format!("{base}/sparsity.png"),
            coefficients: format!("{base}/coefficients.png"),
            surfaces: surfaces
                .iter()
                .map(|s| {
                    (
                        s.clone(),
                        format!("{base}/surfaces/{}.png", encode_segment(s)),
                    )
                })
                .collect(),
            model: three_d.then(|| format!("{base}/scene.glb")),
        }
    }
}

/// Percent-encodes a surface name for a URL path segment (unreserved characters stay).
fn encode_segment(name: &str) -> String {
    name.bytes()
        .map(|b| match b {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'_' | b'.' | b'~' => {
                (b as char).to_string()
            }
            _ => format!("%{b:02X}"),
        })
        .collect()
}

/// The failure of a job, as a problem document.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct JobFailure {
    #[serde(rename = "type")]
    pub kind: String,
    title: String,
    status: u16,
    pub detail: String,
}

impl JobFailure {
    fn new(kind: &str, title: &str, status: StatusCode, detail: impl Into<String>) -> JobFailure {
        JobFailure {
            kind: format!("/problems/{kind}"),
            title: title.into(),
            status: status.as_u16(),
            detail: detail.into(),
        }
    }

    pub(super) fn to_problem(&self) -> Problem {
        let mut p = Problem::new(
            StatusCode::from_u16(self.status).unwrap_or(StatusCode::INTERNAL_SERVER_ERROR),
            self.detail.clone(),
        );
        p.kind = self.kind.clone();
        p.title = self.title.clone();
        p
    }
}

/// The status of a job, as `GET /api/v1/jobs/{id}` answers it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct JobStatus {
    /// The content hash of the document (same document, same id).
    pub id: String,
    pub state: JobState,
    /// The scene's name, when it has one.
    scene: Option<String>,
    /// `flatland`, `3d` or `fredholm`.
    pub(super) kind: String,
    /// Milliseconds since the Unix epoch.
    pub(super) created_ms: u64,
    pub started_ms: Option<u64>,
    pub finished_ms: Option<u64>,
    pub progress: ProgressInfo,
    /// When failed: why.
    pub error: Option<JobFailure>,
    pub links: Links,
}

/// Why a running solve is asked to stop.
const GO_ON: u8 = 0;
const CANCEL: u8 = 1;
const SHUTDOWN: u8 = 2;
/// With a shared database: the job is no longer this process's (deleted, or its lease lost).
const LOST: u8 = 3;

/// One job known to the server.
pub struct Entry {
    pub id: String,
    /// What the job needs until it has run (`None` for jobs that had finished before this
    /// start). Taken by [`Queue::run`]: a finished job keeps only its status in memory; its
    /// document is in the store.
    pending: Mutex<Option<Pending>>,
    status: watch::Sender<JobStatus>,
    stop: AtomicU8,
    /// With a shared database: when the lease was last renewed (ms since the epoch).
    renewed_ms: AtomicU64,
    /// With a shared database, once this process's solve of the job has written its result:
    /// the files it wrote (on the solve's entry and on those that followed it), so that a
    /// synchronous render answers from them rather than read back what was just written
    /// ([`Entry::written_file`]).
    written: OnceLock<Files>,
}

/// A finished job's files as its solve made them: (name, bytes).
type Files = Arc<[(String, Vec<u8>)]>;

/// A job not yet run: its document (written to the store with the result) and the validated
/// job. The Cornell box's take about 35 kB of memory, which every finished job used to keep.
struct Pending {
    document: Value,
    job: Job,
}

impl Entry {
    pub fn status(&self) -> JobStatus {
        self.status.borrow().clone()
    }

    pub fn subscribe(&self) -> watch::Receiver<JobStatus> {
        self.status.subscribe()
    }

    /// A file of the job as this process's solve wrote it to the store (with a shared
    /// database); `None` when this entry has no files: read it from the store
    /// ([`Queue::file`]).
    pub(super) fn written_file(&self, name: &str) -> Option<Vec<u8>> {
        let files = self.written.get()?;
        files
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, b)| b.clone())
    }
}

/// The content hash of a document: SHA-256 of its canonical JSON (object keys sorted, no
/// whitespace), first 128 bits in hex.
pub fn job_id(document: &Value) -> String {
    fn canonical(v: &Value, out: &mut String) {
        match v {
            Value::Object(map) => {
                let mut keys: Vec<&String> = map.keys().collect();
                keys.sort();
                out.push('{');
                for (i, k) in keys.into_iter().enumerate() {
                    if i > 0 {
                        out.push(',');
                    }
                    out.push_str(&Value::String(k.clone()).to_string());
                    out.push(':');
                    canonical(&map[k], out);
                }
                out.push('}');
            }
            Value::Array(items) => {
                out.push('[');
                for (i, item) in items.iter().enumerate() {
                    if i > 0 {
                        out.push(',');
                    }
                    canonical(item, out);
                }
                out.push(']');
            }
            other => out.push_str(&other.to_string()),
        }
    }
    let mut text = String::new();
    canonical(document, &mut text);
    let digest = Sha256::digest(text.as_bytes());
    digest[..16].iter().map(|b| format!("{b:02x}")).collect()
}

pub(super) fn now_ms() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64)
}

/// The answer to a submission.
pub enum Submitted {
    /// A new job, queued.
    New(Arc<Entry>),
    /// The same document was already known: its job.
    Existing(Arc<Entry>),
}

struct Inner {
    entries: Mutex<HashMap<String, Arc<Entry>>>,
    sender: mpsc::Sender<Arc<Entry>>,
    store: Arc<dyn Store>,
    /// With a shared database: what the processes share it with.
    shared: Option<shared::Shared>,
    /// One pool per worker slot.
    pools: Vec<rayon::ThreadPool>,
    solve: SolveFn,
    config: Config,
    metrics: Arc<Metrics>,
    draining: AtomicBool,
    running: AtomicUsize,
    idle: Notify,
    /// When the store was last brought under `max_store_bytes` (ms since the epoch).
    last_eviction: AtomicU64,
    /// An eviction is on its way (waiting for [`EVICTION_GAP_MS`] to pass, or about to run).
    eviction_pending: AtomicBool,
}

/// The least time between two evictions after finished jobs. Measuring the store is a query
/// over every job in PostgreSQL (about 10 ms with a hundred jobs), which after every job held
/// the worker from the next one: a ~50 ms job took 22 % longer through PostgreSQL than through
/// the embedded store (`benches/README.md`). So the store may pass its limit by what one
/// second of jobs adds: an eviction asked for sooner runs when the second has passed.
const EVICTION_GAP_MS: u64 = 1000;

/// The job queue (cheap to clone: a handle).
#[derive(Clone)]
pub struct Queue {
    inner: Arc<Inner>,
}

impl Queue {
    /// Opens the store under `config.data_dir`, restores its jobs (queued and running ones are
    /// queued again) and starts the dispatcher. Needs a tokio runtime.
    pub(super) fn start(
        config: Config,
        solve: SolveFn,
        metrics: Arc<Metrics>,
        shutdown: CancellationToken,
    ) -> Result<Queue, StoreError> {
        let cache = usize::try_from(config.store_cache_bytes).unwrap_or(usize::MAX);
        let store = Arc::new(Embedded::open_with_cache(&config.data_dir, cache)?);
        let (queue, receiver) = Queue::build(config, solve, metrics, store, None)?;
        let requeue = queue.restore()?;
        tokio::spawn(dispatch(queue.clone(), receiver, shutdown.clone()));
        let sender = queue.inner.sender.clone();
        tokio::spawn(async move {
            for entry in requeue {
                if sender.send(entry).await.is_err() {
                    break;
                }
            }
        });
        tokio::spawn(janitor(queue.clone(), shutdown));
        Ok(queue)
    }

    /// The queue of a store shared with other processes ([`shared`]): jobs are claimed from
    /// `store` under a lease, statuses read from it. Needs a multi-threaded tokio runtime.
    pub(super) fn start_shared(
        config: Config,
        solve: SolveFn,
        metrics: Arc<Metrics>,
        shutdown: CancellationToken,
        store: Arc<dyn Store>,
    ) -> Result<Queue, StoreError> {
        let shared = shared::Shared::new(&config);
        let (queue, _) = Queue::build(config, solve, metrics, store, Some(shared))?;
        shared::spawn(&queue, shutdown);
        Ok(queue)
    }

    fn build(
        config: Config,
        solve: SolveFn,
        metrics: Arc<Metrics>,
        store: Arc<dyn Store>,
        shared: Option<shared::Shared>,
    ) -> Result<(Queue, mpsc::Receiver<Arc<Entry>>), StoreError> {
        let workers = config.worker_threads();
        let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
        let pools = (0..workers)
            .map(|slot| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(cores)
                    .thread_name(move |i| format!("wavrad-solve-{slot}-{i}"))
                    .panic_handler(|_| tracing::error!("a task of the solver pool panicked"))
                    .build()
                    .map_err(|e| StoreError::Io(std::io::Error::other(e)))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let (sender, receiver) = mpsc::channel(config.queue_capacity.max(1));
        let queue = Queue {
            inner: Arc::new(Inner {
                entries: Mutex::new(HashMap::new()),
                sender,
                store,
                shared,
                pools,
                solve,
                config,
                metrics,
                draining: AtomicBool::new(false),
                running: AtomicUsize::new(0),
                idle: Notify::new(),
                last_eviction: AtomicU64::new(0),
                eviction_pending: AtomicBool::new(false),
            }),
        };
        Ok((queue, receiver))
    }

    /// Loads every record: finished ones as they are (unless expired), the others queued.
    fn restore(&self) -> Result<Vec<Arc<Entry>>, StoreError> {
        let inner = &self.inner;
        if inner.config.max_store_bytes > 0 {
            let evicted = inner.store.evict(inner.config.max_store_bytes)?;
            if !evicted.is_empty() {
                tracing::info!(
                    jobs = evicted.len(),
                    "forgotten at start: the store was over max_store_bytes"
                );
            }
        }
        let records: Vec<Record> = inner.store.jobs()?;
        let limits = inner.config.limits();
        let mut requeue = Vec::new();
        let mut entries = inner.entries.lock().expect("entries lock");
        for Record {
            document,
            mut status,
        } in records
        {
            if self.expired(&status) {
                inner.store.remove(&status.id)?;
                continue;
            }
            let mut job = None;
            if !status.state.is_final() {
                match crate::scene::parse_value(&document, &limits) {
                    Ok(j) => {
                        job = Some(j);
                        status.state = JobState::Queued;
                        status.started_ms = None;
                        status.progress = queued();
                    }
                    Err(errors) => {
                        status.state = JobState::Failed;
                        status.finished_ms = Some(now_ms());
                        let p = Problem::invalid(&errors);
                        status.error = Some(JobFailure::new(
                            "invalid-document",
                            "Invalid job document",
                            StatusCode::UNPROCESSABLE_ENTITY,
                            format!("the limits of this server refuse the document: {errors}"),
                        ));
                        tracing::warn!(id = %status.id, errors = p.errors.len(), "a restored job no longer validates");
                    }
                }
                inner.store.put_job(&Record {
                    document: document.clone(),
                    status: status.clone(),
                })?;
            }
            let queued = job.is_some();
            let entry = Arc::new(Entry {
                id: status.id.clone(),
                pending: Mutex::new(job.map(|job| Pending { document, job })),
                stop: AtomicU8::new(GO_ON),
                renewed_ms: AtomicU64::new(0),
                written: OnceLock::new(),
                status: watch::channel(status).0,
            });
            if queued {
                requeue.push(entry.clone());
            }
            entries.insert(entry.id.clone(), entry);
        }
        if !requeue.is_empty() {
            tracing::info!(jobs = requeue.len(), "queued again after a restart");
        }
        requeue.sort_by_key(|e| e.status().created_ms);
        Ok(requeue)
    }

    fn expired(&self, status: &JobStatus) -> bool {
        let ttl = self.inner.config.result_ttl.as_millis() as u64;
        status
            .finished_ms
            .is_some_and(|f| f.saturating_add(ttl) <= now_ms())
    }

    /// Makes the lazily written records durable ([`Store::sync`]): a synchronous render that
    /// answers 503 hands its job over to the client, which a crash must not lose.
    pub(super) fn sync(&self) -> Result<(), Problem> {
        self.inner.store.sync().map_err(internal)
    }

    /// Queues a validated document, or answers the job that already has this document.
    /// `durable`: the job is on disk before this returns (a 202 promises that); otherwise it
    /// is written lazily and becomes durable with the next durable write (at the latest its
    /// own result). Blocks on the store: call from a blocking context.
    pub fn submit(&self, document: Value, job: Job, durable: bool) -> Result<Submitted, Problem> {
        let inner = &self.inner;
        if inner.shared.is_some() {
            return self.submit_shared(document, job, durable);
        }
        let id = job_id(&document);
        let mut entries = inner.entries.lock().expect("entries lock");
        if let Some(e) = entries.get(&id) {
            return Ok(Submitted::Existing(e.clone()));
        }
        if inner.draining.load(Ordering::SeqCst) {
            return Err(Problem::new(
                StatusCode::SERVICE_UNAVAILABLE,
                "the server is shutting down",
            )
            .retry_after(5));
        }
        if inner.sender.capacity() == 0 {
            return Err(queue_full(&inner.config));
        }
        let status = new_status(&id, &job);
        let record = Record {
            document: document.clone(),
            status: status.clone(),
        };
        if durable {
            inner.store.put_job(&record).map_err(internal)?;
        } else {
            inner.store.put_job_lazily(&record).map_err(internal)?;
        }
        let entry = Arc::new(Entry {
            id: id.clone(),
            pending: Mutex::new(Some(Pending { document, job })),
            stop: AtomicU8::new(GO_ON),
            renewed_ms: AtomicU64::new(0),
            written: OnceLock::new(),
            status: watch::channel(status).0,
        });
        if inner.sender.try_send(entry.clone()).is_err() {
            inner.store.remove(&id).map_err(internal)?;
            return Err(queue_full(&inner.config));
        }
        entries.insert(id, entry.clone());
        tracing::info!(id = %entry.id, "job queued");
        Ok(Submitted::New(entry))
    }

    pub fn get(&self, id: &str) -> Option<Arc<Entry>> {
        self.inner
            .entries
            .lock()
            .expect("entries lock")
            .get(id)
            .cloned()
    }

    /// Jobs, newest first.
    /// A job, from whichever process solves it: [`Queue::get`], or with a shared database
    /// the job's record there, its status followed while someone subscribes.
    pub(super) async fn find(&self, id: &str) -> Result<Option<Arc<Entry>>, Problem> {
        if self.inner.shared.is_some() {
            return self.find_shared(id).await;
        }
        Ok(self.get(id))
    }

    /// Jobs, newest first: [`Queue::list`], or with a shared database every process's.
    pub(super) async fn recent(&self, limit: usize) -> Result<Vec<JobStatus>, Problem> {
        if self.inner.shared.is_some() {
            let store = self.inner.store.clone();
            return tokio::task::spawn_blocking(move || store.list(limit))
                .await
                .map_err(|e| Problem::new(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?
                .map_err(unavailable);
        }
        Ok(self.list(limit))
    }

    /// The jobs known to this process (with a shared database: those it is solving), newest
    /// first.
    pub fn list(&self, limit: usize) -> Vec<JobStatus> {
        let mut all: Vec<JobStatus> = self
            .inner
            .entries
            .lock()
            .expect("entries lock")
            .values()
            .map(|e| e.status())
            .collect();
        all.sort_by(|a, b| {
            b.created_ms
                .cmp(&a.created_ms)
                .then_with(|| a.id.cmp(&b.id))
        });
        all.truncate(limit);
        all
    }

    /// Cancels a job (a running solve stops at its next check, well within a second) and
    /// forgets it. `false` when unknown. Blocks on the store.
    pub fn delete(&self, id: &str) -> Result<bool, StoreError> {
        if self.inner.shared.is_some() {
            return self.delete_shared(id);
        }
        let Some(entry) = self.inner.entries.lock().expect("entries lock").remove(id) else {
            return Ok(false);
        };
        entry.stop.store(CANCEL, Ordering::SeqCst);
        entry.status.send_modify(|s| {
            if !s.state.is_final() {
                s.state = JobState::Cancelled;
                s.finished_ms = Some(now_ms());
            }
        });
        self.inner.store.remove(id)?;
        tracing::info!(id, "job cancelled and forgotten");
        Ok(true)
    }

    /// A file of a finished job. Blocks on the store.
    pub fn file(&self, id: &str, name: &str) -> Result<Option<Vec<u8>>, StoreError> {
        self.inner.store.file(id, name)
    }

    /// Whether new jobs are taken (not shutting down, room in the queue).
    pub(super) fn ready(&self) -> bool {
        if let Some(shared) = &self.inner.shared {
            return !self.inner.draining.load(Ordering::SeqCst)
                && shared.ready(self.inner.config.queue_capacity);
        }
        !self.inner.draining.load(Ordering::SeqCst) && self.inner.sender.capacity() > 0
    }

    /// Refreshes the job gauges (called when `/metrics` is read).
    pub(super) fn update_gauges(&self) {
        let mut counts: BTreeMap<&str, i64> = BTreeMap::new();
        for s in [
            JobState::Queued,
            JobState::Running,
            JobState::Succeeded,
            JobState::Failed,
            JobState::Cancelled,
        ] {
            counts.insert(s.as_str(), 0);
        }
        if let Some(shared) = &self.inner.shared {
            let c = shared.counts();
            for (state, n) in [
                (JobState::Queued, c.queued),
                (JobState::Running, c.running),
                (JobState::Succeeded, c.succeeded),
                (JobState::Failed, c.failed),
                (JobState::Cancelled, c.cancelled),
            ] {
                counts.insert(state.as_str(), n as i64);
            }
        } else {
            for e in self.inner.entries.lock().expect("entries lock").values() {
                *counts.entry(e.status.borrow().state.as_str()).or_default() += 1;
            }
        }
        let m = &self.inner.metrics;
        m.queue_depth.set(counts["queued"]);
        for (state, n) in counts {
            m.jobs
                .get_or_create(&StateLabel {
                    state: state.to_string(),
                })
                .set(n);
        }
    }

    /// Stops taking jobs, lets running solves finish for up to `grace`, then stops them and
    /// leaves them queued in the store for the next start. Queued jobs stay queued.
    pub(super) async fn shutdown(&self, grace: Duration) {
        let inner = &self.inner;
        inner.draining.store(true, Ordering::SeqCst);
        let wait_idle = |limit: Duration| async move {
            let deadline = tokio::time::Instant::now() + limit;
            while inner.running.load(Ordering::SeqCst) > 0 {
                let notified = inner.idle.notified();
                if inner.running.load(Ordering::SeqCst) == 0 {
                    break;
                }
                if tokio::time::timeout_at(deadline, notified).await.is_err() {
                    return false;
                }
            }
            true
        };
        if wait_idle(grace).await {
            return;
        }
        tracing::warn!("stopping running solves; they stay queued for the next start");
        for e in inner.entries.lock().expect("entries lock").values() {
            e.stop
                .compare_exchange(GO_ON, SHUTDOWN, Ordering::SeqCst, Ordering::SeqCst)
                .ok();
        }
        wait_idle(Duration::from_secs(5)).await;
    }

    /// Runs one job on the current (pool) thread.
    fn run(&self, entry: Arc<Entry>) {
        let inner = &self.inner;
        let Some(Pending { document, job }) = entry.pending.lock().expect("pending lock").take()
        else {
            return;
        };
        if entry.stop.load(Ordering::SeqCst) != GO_ON || inner.draining.load(Ordering::SeqCst) {
            if inner.shared.is_some() {
                self.finish_shared(&entry, &document, SHUTDOWN, entry.status(), [].into());
            }
            return;
        }
        inner.running.fetch_add(1, Ordering::SeqCst);
        let start = Instant::now();
        entry.status.send_modify(|s| {
            if s.state != JobState::Running {
                // (a job claimed from a shared store is running since its claim)
                s.started_ms = Some(now_ms());
            }
            s.state = JobState::Running;
            s.progress = ProgressInfo {
                phase: "projection".into(),
                fraction: 0.0,
            };
        });
        // Not written to the store: a job that was running at a crash is queued again, exactly
        // like one that was waiting, so `queued` on disk says all there is to say.
        let watch = Watch {
            entry: &entry,
            deadline: start + inner.config.job_timeout,
            timed_out: AtomicBool::new(false),
        };
        let run = catch_unwind(AssertUnwindSafe(|| {
            let outcome = (inner.solve)(&job, &watch)?;
            watch.report(Phase::Render, 0.0);
            let images = crate::render::render_all(&job, &outcome);
            let json = serde_json::to_vec_pretty(&outcome.result).expect("a result serialises");
            Ok::<_, JobError>((json, images))
        }));
        inner
            .metrics
            .solve_seconds
            .observe(start.elapsed().as_secs_f64());
        let stop = entry.stop.load(Ordering::SeqCst);
        // The final status is written to the store before it is published, so that whoever
        // sees `succeeded` can read the result.
        let mut status = entry.status();
        let mut failure = |kind: &str, title: &str, code: StatusCode, detail: String| {
            tracing::warn!(id = %entry.id, %detail, "job failed");
            status.state = JobState::Failed;
            status.finished_ms = Some(now_ms());
            status.error = Some(JobFailure::new(kind, title, code, detail));
        };
        let mut files = Vec::new();
        match run {
            Ok(Ok((json, images))) => {
                files.push(("result.json".to_string(), json));
                files.extend(images.files().into_iter().map(|(n, b)| (n, b.to_vec())));
                status.state = JobState::Succeeded;
                status.finished_ms = Some(now_ms());
                status.progress = ProgressInfo {
                    phase: "done".into(),
                    fraction: 1.0,
                };
                tracing::info!(id = %entry.id, seconds = start.elapsed().as_secs_f64(), "job succeeded");
            }
            Ok(Err(JobError::Cancelled)) if stop == SHUTDOWN || stop == LOST => {
                status.state = JobState::Queued;
                status.started_ms = None;
                status.progress = queued();
            }
            Ok(Err(JobError::Cancelled)) if watch.timed_out.load(Ordering::SeqCst) => failure(
                "timeout",
                "The solve ran too long",
                StatusCode::GATEWAY_TIMEOUT,
                format!(
                    "the solve ran past job_timeout ({:?}) and was stopped",
                    inner.config.job_timeout
                ),
            ),
            Ok(Err(JobError::Cancelled)) => {}
            Ok(Err(e @ JobError::Diverged { .. })) => failure(
                "diverged",
                "The solve failed",
                StatusCode::INTERNAL_SERVER_ERROR,
                e.to_string(),
            ),
            Ok(Err(e @ JobError::Unsupported { .. })) => failure(
                "unsupported",
                "Not supported",
                StatusCode::UNPROCESSABLE_ENTITY,
                e.to_string(),
            ),
            Ok(Err(e @ (JobError::TooLarge { .. } | JobError::TooManyPairs { .. }))) => failure(
                "too-large",
                "The problem is too large",
                StatusCode::UNPROCESSABLE_ENTITY,
                e.to_string(),
            ),
            Err(panic) => {
                let msg = panic
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_else(|| "unknown panic".into());
                failure(
                    "panic",
                    "The solve failed",
                    StatusCode::INTERNAL_SERVER_ERROR,
                    format!("the solver panicked: {msg}"),
                )
            }
        }
        let stop = entry.stop.load(Ordering::SeqCst);
        if inner.shared.is_some() {
            self.finish_shared(&entry, &document, stop, status, files.into());
        } else {
            if stop != CANCEL {
                self.write(&entry, &document, status.clone(), &as_slices(&files));
                entry.status.send_replace(status);
                self.evict();
            }
            drop(files);
        }
        drop((document, job));
        release_memory();
        inner.running.fetch_sub(1, Ordering::SeqCst);
        inner.idle.notify_waiters();
    }

    fn write(&self, entry: &Entry, document: &Value, status: JobStatus, files: &[(String, &[u8])]) {
        let record = Record {
            document: document.clone(),
            status,
        };
        if let Err(e) = self.inner.store.put_finished(&record, files) {
            tracing::error!(id = %entry.id, error = %e, "could not write the job to the store");
        }
        if entry.stop.load(Ordering::SeqCst) == CANCEL {
            // Deleted while this write was under way: forget it again.
            let _ = self.inner.store.remove(&entry.id);
        }
    }

    /// Forgets the oldest finished jobs while the store holds more than `max_store_bytes`
    /// (when it is not 0). They answer as expired ones do: 404, as if never posted.
    ///
    /// Never on the caller's thread, which after a job is its worker's: measuring the store is
    /// a query over every job in PostgreSQL (about 10 ms with a hundred jobs), and run there it
    /// held the job's followers (a synchronous render's answer) and the worker's next job for
    /// as long. On a thread of its own instead, one at a time, at most once per
    /// [`EVICTION_GAP_MS`]: one asked for sooner waits for the gap.
    fn evict(&self) {
        if self.inner.config.max_store_bytes == 0
            || self.inner.eviction_pending.swap(true, Ordering::SeqCst)
        {
            return;
        }
        let next = self.inner.last_eviction.load(Ordering::SeqCst) + EVICTION_GAP_MS;
        let wait = next.saturating_sub(now_ms());
        let q = self.clone();
        std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(wait));
            q.inner.last_eviction.store(now_ms(), Ordering::SeqCst);
            q.inner.eviction_pending.store(false, Ordering::SeqCst);
            q.evict_now();
        });
    }

    fn evict_now(&self) {
        let max = self.inner.config.max_store_bytes;
        match self.inner.store.evict(max) {
            Ok(ids) if !ids.is_empty() => {
                let mut entries = self.inner.entries.lock().expect("entries lock");
                for id in &ids {
                    // a job that is posted again and queued under the same id keeps its entry
                    if entries
                        .get(id)
                        .is_some_and(|e| e.status.borrow().state.is_final())
                    {
                        entries.remove(id);
                    }
                }
                drop(entries);
                tracing::info!(
                    jobs = ids.len(),
                    max_store_bytes = max,
                    "forgotten: the store was over max_store_bytes"
                );
            }
            Ok(_) => {}
            Err(e) => tracing::error!(error = %e, "could not forget old jobs"),
        }
    }

    /// Forgets finished jobs older than `result_ttl`.
    fn expire(&self) {
        let expired: Vec<String> = self
            .inner
            .entries
            .lock()
            .expect("entries lock")
            .values()
            .filter(|e| self.expired(&e.status.borrow()))
            .map(|e| e.id.clone())
            .collect();
        for id in expired {
            self.inner.entries.lock().expect("entries lock").remove(&id);
            if let Err(e) = self.inner.store.remove(&id) {
                tracing::error!(%id, error = %e, "could not expire a job");
            }
        }
    }
}

/// Files as the store takes them.
fn as_slices(files: &[(String, Vec<u8>)]) -> Vec<(String, &[u8])> {
    files
        .iter()
        .map(|(n, b)| (n.clone(), b.as_slice()))
        .collect()
}

/// Gives the memory a finished solve freed back to the system.
///
/// A solve allocates on every thread of its pool (the Cornell box: tens of MB of links,
/// blocks and images). glibc's malloc keeps what a thread frees in that thread's arena (up to
/// eight arenas per core) and gives pages back to the system only from the top of an arena,
/// so the free memory of every finished solve stayed resident, scattered over the arenas: the
/// resident memory grew with the jobs (see "Memory and disk" in `benches/README.md`).
/// `malloc_trim(0)` returns the whole free pages inside every arena (glibc ≥ 2.8); it costs
/// about a millisecond per solve. The free top of a thread's arena it leaves alone: that one
/// goes back on `free` once it is larger than the trim threshold ([`tune_malloc`]). Other
/// allocators return memory on their own.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn release_memory() {
    // SAFETY: malloc_trim has no preconditions; it only releases free memory.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// Gives the memory a finished solve freed back to the system (nothing to do here).
#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn release_memory() {}

/// Fixes glibc's malloc thresholds, once at start (`wavrad serve`).
///
/// Left alone, glibc raises its mmap threshold to the size of each large mmapped block that
/// is freed (up to 32 MiB) and its trim threshold to twice that. A solve of the Cornell box
/// frees mmapped blocks of many MB (up to 25 MB at once), so after the first job the trim
/// threshold was tens of MB: the free top of each thread's arena (which `malloc_trim` does
/// not touch outside the main arena) stayed resident up to that size, up to 30 MB per arena;
/// glibc's own statistics showed 50–170 MB taken from the system against 2–8 MB in use, and
/// the resident memory was 60–90 MB after 10 to 100 Cornell boxes. Setting the
/// thresholds turns the adjustment off: blocks of 4 MiB and more are mmapped and unmapped on
/// `free`, and an arena's free top beyond 128 KiB (glibc's default) goes back to the system.
/// The Cornell box solves as fast as before (about 4 s a job in the soak either way). The
/// measurements are in "Memory and disk", `benches/README.md`.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
pub fn tune_malloc() {
    // SAFETY: mallopt only sets parameters of the allocator; any values are allowed.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 4 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 128 << 10);
    }
}

/// Fixes glibc's malloc thresholds (nothing to do here).
#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn tune_malloc() {}

/// The status of a job just accepted.
fn new_status(id: &str, job: &Job) -> JobStatus {
    JobStatus {
        id: id.to_string(),
        state: JobState::Queued,
        scene: job.scene.name.clone(),
        kind: job.scene.kind.name().to_string(),
        created_ms: now_ms(),
        started_ms: None,
        finished_ms: None,
        progress: queued(),
        error: None,
        links: Links::new(
            id,
            &job.surface_names(),
            matches!(job.scene.kind, crate::scene::SceneKind::ThreeD(_)),
        ),
    }
}

fn queued() -> ProgressInfo {
    ProgressInfo {
        phase: "queued".into(),
        fraction: 0.0,
    }
}

fn queue_full(config: &Config) -> Problem {
    Problem::new(
        StatusCode::TOO_MANY_REQUESTS,
        format!(
            "the queue is full ({} jobs waiting); try again later",
            config.queue_capacity
        ),
    )
    .with_type("queue-full", "Queue full")
    .retry_after(5)
}

/// A store that does not answer (a shared database out of reach): 503, try again.
fn unavailable(e: StoreError) -> Problem {
    tracing::error!(error = %e, "store failure");
    Problem::new(
        StatusCode::SERVICE_UNAVAILABLE,
        "the job store is out of reach; try again shortly",
    )
    .with_type("store-unavailable", "Store unavailable")
    .retry_after(2)
}

fn internal(e: StoreError) -> Problem {
    tracing::error!(error = %e, "store failure");
    Problem::new(StatusCode::INTERNAL_SERVER_ERROR, "the job store failed")
}

/// Hands queued jobs to the pools, one per free worker slot. A slot is taken before a job
/// is received, so that waiting jobs stay in the bounded channel and count against its
/// capacity.
async fn dispatch(
    queue: Queue,
    mut receiver: mpsc::Receiver<Arc<Entry>>,
    shutdown: CancellationToken,
) {
    let workers = queue.inner.pools.len();
    let (free, mut slots) = mpsc::channel::<usize>(workers);
    for slot in 0..workers {
        free.try_send(slot).expect("room for every slot");
    }
    loop {
        let slot = tokio::select! {
            _ = shutdown.cancelled() => return,
            s = slots.recv() => s.expect("the dispatcher holds a sender"),
        };
        let entry = loop {
            let entry = tokio::select! {
                _ = shutdown.cancelled() => return,
                e = receiver.recv() => match e { Some(e) => e, None => return },
            };
            if entry.stop.load(Ordering::SeqCst) == GO_ON {
                break entry;
            }
        };
        let (q, free) = (queue.clone(), free.clone());
        queue.inner.pools[slot].spawn(move || {
            q.run(entry);
            // a pool thread is outside the async runtime: a blocking send is allowed, and
            // never waits (the channel has room for every slot)
            let _ = free.blocking_send(slot);
        });
    }
}

/// Expires old results now and then, and keeps the store within `max_store_bytes`.
async fn janitor(queue: Queue, shutdown: CancellationToken) {
    let every = (queue.inner.config.result_ttl / 4)
        .clamp(Duration::from_millis(200), Duration::from_secs(60));
    let mut tick = tokio::time::interval(every);
    loop {
        tokio::select! {
            _ = shutdown.cancelled() => return,
            _ = tick.tick() => {
                let q = queue.clone();
                let _ = tokio::task::spawn_blocking(move || {
                    q.expire();
                    q.evict();
                })
                .await;
            }
        }
    }
}

/// The [`Progress`] of one running job: updates its status, stops on cancel, shutdown or
/// `job_timeout`.
struct Watch<'a> {
    entry: &'a Entry,
    deadline: Instant,
    timed_out: AtomicBool,
}

impl Progress for Watch<'_> {
    fn report(&self, phase: Phase, fraction: f64) {
        let fraction = if fraction.is_finite() {
            fraction.clamp(0.0, 1.0)
        } else {
            0.0
        };
        self.entry.status.send_if_modified(|s| {
            let p = &mut s.progress;
            let changed = p.phase != phase.as_str()
                || (fraction - p.fraction).abs() >= 0.01
                || (fraction == 1.0 && p.fraction != 1.0);
            if changed {
                *p = ProgressInfo {
                    phase: phase.as_str().into(),
                    fraction,
                };
            }
            changed
        });
    }

    fn cancelled(&self) -> bool {
        if self.entry.stop.load(Ordering::SeqCst) != GO_ON {
            return true;
        }
        if Instant::now() > self.deadline {
            self.timed_out.store(true, Ordering::SeqCst);
            return true;
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_ignore_key_order_and_whitespace() {
        let a: Value = serde_json::from_str(
            r#"{"scene": {"kind": "fredholm", "domain": [0, 1]}, "solver": {}}"#,
        )
        .unwrap();
        let b: Value =
            serde_json::from_str(r#"{"solver":{},"scene":{"domain":[0,1],"kind":"fredholm"}}"#)
                .unwrap();
        let c: Value =
            serde_json::from_str(r#"{"solver":{},"scene":{"domain":[0,2],"kind":"fredholm"}}"#)
                .unwrap();
        assert_eq!(job_id(&a), job_id(&b));
        assert_ne!(job_id(&a), job_id(&c));
        assert_eq!(job_id(&a).len(), 32);
    }
}
