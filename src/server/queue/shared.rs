//! The queue of a store shared by several processes (a PostgreSQL database).
//!
//! - **Claiming**: a dispatcher takes a job from the store ([`Store::claim`]) whenever one of
//!   this process's worker slots is free, and looks again every `poll_interval` while there is
//!   nothing (at once after a submission to this process).
//! - **Leases**: every `poll_interval` a heartbeat renews the lease of each job solved here and
//!   writes its status (progress) to the store. A job whose row is gone (deleted through any
//!   process) or no longer this process's is stopped; so is a job whose lease could not be
//!   renewed for a whole `lease` (the database out of reach), since another process may have
//!   taken it by then: no job is solved by two processes at once.
//! - **Following**: the status of a job asked from this process is read from the store; while
//!   someone follows it (SSE, a synchronous render) it is read again every `poll_interval`, and
//!   at once when this process's solve of that job ends. When that solve wrote the job's final
//!   record, the followers take the status and files it wrote instead of reading them back: a
//!   synchronous render taken by the process that solves it is answered as soon as the result
//!   is committed, without two more round trips to the database (the status and the image).
//! - **Results** are written with [`Store::finish`], only while this process owns the job.
//! - **Health**: every `poll_interval` the store is asked for its counts of jobs: `readyz`
//!   answers 503 while that fails, and the queue is full when `queue_capacity` jobs are queued
//!   across all processes.
//! - **Expiry** of old results: [`Store::expire`], one process at a time.

use super::*;
use crate::server::store::{Counts, Inserted};
use tokio::sync::broadcast;

/// The end of a solve here, for the followers of its job ([`follow`]).
#[derive(Clone)]
struct Ended {
    id: String,
    /// The final status and the files, when the solve wrote them to the store; `None`: read
    /// the store.
    written: Option<(JobStatus, Files)>,
}

pub(super) struct Shared {
    /// This process, in the store's `owner` column.
    owner: String,
    lease: Duration,
    poll: Duration,
    /// A job was submitted here: look for work now.
    wake: Notify,
    /// A solve here ended: its job's followers look now.
    ended: broadcast::Sender<Ended>,
    healthy: AtomicBool,
    counts: Mutex<Counts>,
}

impl Shared {
    pub(super) fn new(config: &Config) -> Shared {
        let host = std::env::var("HOSTNAME")
            .ok()
            .or_else(|| std::fs::read_to_string("/etc/hostname").ok())
            .map(|h| h.trim().to_string())
            .filter(|h| !h.is_empty())
            .unwrap_or_else(|| "wavrad".into());
        let nanos = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        Shared {
            owner: format!("{host}:{}:{nanos:08x}", std::process::id()),
            lease: config.lease,
            poll: config.poll_interval,
            wake: Notify::new(),
            // a follower that falls this far behind reads the store instead; a message is
            // dropped (its files with it) once every follower has seen it
            ended: broadcast::channel(16).0,
            healthy: AtomicBool::new(true),
            counts: Mutex::new(Counts::default()),
        }
    }

    pub(super) fn ready(&self, capacity: usize) -> bool {
        self.healthy.load(Ordering::SeqCst) && self.counts().queued < capacity
    }

    pub(super) fn counts(&self) -> Counts {
        *self.counts.lock().expect("counts lock")
    }
}

/// Starts the dispatcher, the heartbeat, the health check and the janitor.
pub(super) fn spawn(queue: &Queue, shutdown: CancellationToken) {
    tokio::spawn(dispatch(queue.clone(), shutdown.clone()));
    tokio::spawn(heartbeat(queue.clone(), shutdown.clone()));
    tokio::spawn(health(queue.clone(), shutdown.clone()));
    tokio::spawn(janitor(queue.clone(), shutdown));
}

impl Queue {
    fn shared(&self) -> &Shared {
        self.inner.shared.as_ref().expect("a shared queue")
    }

    /// [`Queue::submit`] with a shared store: one row per id across every process.
    pub(super) fn submit_shared(
        &self,
        document: Value,
        job: Job,
        durable: bool,
    ) -> Result<Submitted, Problem> {
        let inner = &self.inner;
        let id = job_id(&document);
        if inner.draining.load(Ordering::SeqCst) {
            return Err(Problem::new(
                StatusCode::SERVICE_UNAVAILABLE,
                "the server is shutting down",
            )
            .retry_after(5));
        }
        let record = Record {
            document,
            status: new_status(&id, &job),
        };
        match inner
            .store
            .insert(&record, inner.config.queue_capacity, durable)
            .map_err(unavailable)?
        {
            Inserted::New => {
                tracing::info!(%id, "job queued");
                self.shared().wake.notify_one();
                Ok(Submitted::New(self.follow(record)))
            }
            Inserted::Existing(existing) => Ok(Submitted::Existing(
                self.get(&id).unwrap_or_else(|| self.follow(*existing)),
            )),
            Inserted::Full => Err(queue_full(&inner.config)),
        }
    }

    /// [`Queue::delete`] with a shared store: the row goes, and the process solving the job
    /// stops at its next heartbeat.
    pub(super) fn delete_shared(&self, id: &str) -> Result<bool, StoreError> {
        let existed = self.inner.store.remove(id)?;
        if let Some(entry) = self.get(id) {
            entry.stop.store(CANCEL, Ordering::SeqCst);
        }
        if existed {
            tracing::info!(id, "job cancelled and forgotten");
        }
        Ok(existed)
    }

    pub(super) async fn find_shared(&self, id: &str) -> Result<Option<Arc<Entry>>, Problem> {
        if let Some(e) = self.get(id) {
            return Ok(Some(e));
        }
        let store = self.inner.store.clone();
        let key = id.to_string();
        let record = tokio::task::spawn_blocking(move || store.job(&key))
            .await
            .map_err(|e| Problem::new(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?
            .map_err(unavailable)?;
        Ok(record.map(|r| self.follow(r)))
    }

    /// An entry for a job of the store, its status read again while someone subscribes.
    fn follow(&self, record: Record) -> Arc<Entry> {
        let final_ = record.status.state.is_final();
        let entry = Arc::new(Entry {
            id: record.status.id.clone(),
            pending: Mutex::new(None),
            stop: AtomicU8::new(GO_ON),
            renewed_ms: AtomicU64::new(0),
            written: OnceLock::new(),
            status: watch::channel(record.status).0,
        });
        if !final_ {
            // subscribed now, not when the task first runs: a solve that ends in between is
            // not missed
            let ended = self.shared().ended.subscribe();
            tokio::spawn(follow(self.clone(), entry.clone(), ended));
        }
        entry
    }

    /// The end of a solve with a shared store: the result written while this process still
    /// owns the job (retried for up to a lease while the store is out of reach), or the job
    /// given back at shutdown.
    pub(super) fn finish_shared(
        &self,
        entry: &Entry,
        document: &Value,
        stop: u8,
        status: JobStatus,
        files: Files,
    ) {
        let inner = &self.inner;
        let shared = self.shared();
        let mut written = None;
        match stop {
            CANCEL | LOST => {
                tracing::info!(id = %entry.id, "the solve stopped: the job is no longer this process's");
            }
            SHUTDOWN => {
                if let Err(e) = inner.store.release(&shared.owner, &entry.id) {
                    tracing::warn!(id = %entry.id, error = %e, "could not give the job back; its lease will run out");
                }
            }
            _ => {
                let record = Record {
                    document: document.clone(),
                    status: status.clone(),
                };
                let deadline = Instant::now() + shared.lease;
                let slices = as_slices(&files);
                loop {
                    match inner.store.finish(&shared.owner, &record, &slices) {
                        Ok(true) => {
                            if status.state.is_final() {
                                let _ = entry.written.set(files.clone());
                                written = Some((status.clone(), files));
                            }
                            entry.status.send_replace(status);
                            self.evict();
                            break;
                        }
                        Ok(false) => {
                            tracing::warn!(id = %entry.id, "the job was deleted or taken over while it was solved here; result dropped");
                            break;
                        }
                        Err(e) if Instant::now() < deadline => {
                            tracing::warn!(id = %entry.id, error = %e, "could not write the result; trying again");
                            std::thread::sleep(shared.poll);
                        }
                        Err(e) => {
                            tracing::error!(id = %entry.id, error = %e, "could not write the result; the job will run again elsewhere");
                            break;
                        }
                    }
                }
            }
        }
        inner
            .entries
            .lock()
            .expect("entries lock")
            .remove(&entry.id);
        // (an error only when nobody follows)
        let _ = shared.ended.send(Ended {
            id: entry.id.clone(),
            written,
        });
    }
}

/// Claims jobs for the free worker slots and hands each to its slot's pool.
async fn dispatch(queue: Queue, shutdown: CancellationToken) {
    let inner = queue.inner.clone();
    let shared = queue.shared();
    let workers = inner.pools.len();
    let (free, mut slots) = mpsc::channel::<usize>(workers);
    for slot in 0..workers {
        free.try_send(slot).expect("room for every slot");
    }
    loop {
        let slot = tokio::select! {
            _ = shutdown.cancelled() => return,
            s = slots.recv() => s.expect("the dispatcher holds a sender"),
        };
        let record = loop {
            if inner.draining.load(Ordering::SeqCst) {
                return;
            }
            let store = inner.store.clone();
            let owner = shared.owner.clone();
            let lease = shared.lease;
            let claimed = tokio::task::spawn_blocking(move || store.claim(&owner, lease)).await;
            let wait = match claimed {
                Ok(Ok(Some(record))) => break record,
                Ok(Ok(None)) => true,
                Ok(Err(e)) => {
                    tracing::warn!(error = %e, "could not look for jobs");
                    true
                }
                Err(_) => true,
            };
            if wait {
                tokio::select! {
                    _ = shutdown.cancelled() => return,
                    _ = shared.wake.notified() => {}
                    _ = tokio::time::sleep(shared.poll) => {}
                }
            }
        };
        let id = record.status.id.clone();
        let job = match crate::scene::parse_value(&record.document, &inner.config.limits()) {
            Ok(job) => job,
            Err(errors) => {
                // another process took it; this one's limits refuse it: the job fails
                let mut status = record.status.clone();
                status.state = JobState::Failed;
                status.finished_ms = Some(now_ms());
                status.error = Some(JobFailure::new(
                    "invalid-document",
                    "Invalid job document",
                    StatusCode::UNPROCESSABLE_ENTITY,
                    format!("the limits of this server refuse the document: {errors}"),
                ));
                let failed = Record {
                    document: record.document,
                    status,
                };
                let (store, owner) = (inner.store.clone(), shared.owner.clone());
                let _ =
                    tokio::task::spawn_blocking(move || store.finish(&owner, &failed, &[])).await;
                let _ = free.try_send(slot);
                continue;
            }
        };
        tracing::info!(%id, "job claimed");
        let entry = Arc::new(Entry {
            id: id.clone(),
            pending: Mutex::new(Some(Pending {
                document: record.document,
                job,
            })),
            stop: AtomicU8::new(GO_ON),
            renewed_ms: AtomicU64::new(now_ms()),
            written: OnceLock::new(),
            status: watch::channel(record.status).0,
        });
        inner
            .entries
            .lock()
            .expect("entries lock")
            .insert(id, entry.clone());
        let (q, free) = (queue.clone(), free.clone());
        inner.pools[slot].spawn(move || {
            q.run(entry);
            let _ = free.blocking_send(slot);
        });
    }
}

/// Renews the leases of the jobs solved here and writes their progress.
async fn heartbeat(queue: Queue, shutdown: CancellationToken) {
    let poll = queue.shared().poll;
    let mut tick = tokio::time::interval(poll);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        tokio::select! {
            _ = shutdown.cancelled() => return,
            _ = tick.tick() => {}
        }
        let running: Vec<Arc<Entry>> = queue
            .inner
            .entries
            .lock()
            .expect("entries lock")
            .values()
            .cloned()
            .collect();
        if running.is_empty() {
            continue;
        }
        let q = queue.clone();
        let _ = tokio::task::spawn_blocking(move || {
            let shared = q.shared();
            for entry in running {
                if entry.stop.load(Ordering::SeqCst) != GO_ON {
                    continue;
                }
                let status = entry.status();
                if status.state != JobState::Running {
                    continue;
                }
                match q.inner.store.renew(&shared.owner, shared.lease, &status) {
                    Ok(true) => entry.renewed_ms.store(now_ms(), Ordering::SeqCst),
                    Ok(false) => {
                        tracing::info!(id = %entry.id, "the job was deleted or taken over; stopping its solve");
                        entry
                            .stop
                            .compare_exchange(GO_ON, LOST, Ordering::SeqCst, Ordering::SeqCst)
                            .ok();
                    }
                    Err(e) => {
                        let since = now_ms().saturating_sub(entry.renewed_ms.load(Ordering::SeqCst));
                        if since >= shared.lease.as_millis() as u64 {
                            tracing::warn!(id = %entry.id, error = %e, "the lease could not be renewed in time; stopping the solve");
                            entry
                                .stop
                                .compare_exchange(GO_ON, LOST, Ordering::SeqCst, Ordering::SeqCst)
                                .ok();
                        } else {
                            tracing::warn!(id = %entry.id, error = %e, "could not renew the lease");
                        }
                    }
                }
            }
        })
        .await;
    }
}

/// Reads a followed job's status from the store while someone subscribes, until it ends; at
/// once when a solve of the job here ends, and not at all when that solve wrote the job's
/// final status (committed before it is sent: whoever sees it can read the result), which is
/// taken with the files as they were written.
async fn follow(queue: Queue, entry: Arc<Entry>, mut ended: broadcast::Receiver<Ended>) {
    let shared = queue.shared();
    let mut next = tokio::time::Instant::now() + shared.poll;
    loop {
        tokio::select! {
            _ = tokio::time::sleep_until(next) => {}
            e = ended.recv() => match e {
                Ok(e) if e.id != entry.id => continue,
                Ok(Ended { written: Some((status, files)), .. }) => {
                    // the files first: whoever sees the status may ask for them
                    let _ = entry.written.set(files);
                    entry.status.send_replace(status);
                    return;
                }
                Ok(_) | Err(broadcast::error::RecvError::Lagged(_)) => {}
                Err(broadcast::error::RecvError::Closed) => return,
            },
        }
        // the next look a poll from now (the ends of other jobs, above, leave it as it was)
        next = tokio::time::Instant::now() + shared.poll;
        if entry.status.receiver_count() == 0 {
            return;
        }
        let store = queue.inner.store.clone();
        let id = entry.id.clone();
        match tokio::task::spawn_blocking(move || store.job(&id)).await {
            Ok(Ok(Some(record))) => {
                let ended = record.status.state.is_final();
                entry.status.send_if_modified(|s| {
                    let changed = *s != record.status;
                    if changed {
                        *s = record.status;
                    }
                    changed
                });
                if ended {
                    return;
                }
            }
            Ok(Ok(None)) => {
                // deleted: followers see it cancelled
                entry.status.send_modify(|s| {
                    s.state = JobState::Cancelled;
                    s.finished_ms = Some(now_ms());
                });
                return;
            }
            Ok(Err(e)) => tracing::debug!(error = %e, "could not read a followed job"),
            Err(_) => return,
        }
    }
}

/// Asks the store for its counts: health and the shared queue's depth.
async fn health(queue: Queue, shutdown: CancellationToken) {
    let shared = queue.shared();
    let mut tick = tokio::time::interval(shared.poll);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        tokio::select! {
            _ = shutdown.cancelled() => return,
            _ = tick.tick() => {}
        }
        let store = queue.inner.store.clone();
        match tokio::task::spawn_blocking(move || store.counts()).await {
            Ok(Ok(counts)) => {
                *shared.counts.lock().expect("counts lock") = counts;
                if !shared.healthy.swap(true, Ordering::SeqCst) {
                    tracing::info!("the job store answers again");
                }
            }
            Ok(Err(e)) => {
                if shared.healthy.swap(false, Ordering::SeqCst) {
                    tracing::error!(error = %e, "the job store is out of reach");
                }
            }
            Err(_) => {}
        }
    }
}

/// Forgets finished jobs older than `result_ttl`, and the oldest finished ones beyond
/// `max_store_bytes` (the store lets one process at a time).
async fn janitor(queue: Queue, shutdown: CancellationToken) {
    let ttl = queue.inner.config.result_ttl;
    let every = (ttl / 4).clamp(Duration::from_millis(200), Duration::from_secs(60));
    let mut tick = tokio::time::interval(every);
    loop {
        tokio::select! {
            _ = shutdown.cancelled() => return,
            _ = tick.tick() => {}
        }
        let store = queue.inner.store.clone();
        let before = now_ms().saturating_sub(ttl.as_millis() as u64);
        match tokio::task::spawn_blocking(move || store.expire(before)).await {
            Ok(Ok(n)) if n > 0 => tracing::info!(jobs = n, "expired"),
            Ok(Err(e)) => tracing::warn!(error = %e, "could not expire old jobs"),
            _ => {}
        }
        queue.evict();
    }
}
