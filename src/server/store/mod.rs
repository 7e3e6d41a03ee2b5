//! Where jobs, their status and their files are kept: one interface, [`Store`], with two
//! implementations.
//!
//! - [`embedded::Embedded`]: an embedded redb database under `data_dir`; one process, no other
//!   server (the default).
//! - [`postgres::Postgres`]: a PostgreSQL database shared by any number of processes
//!   (`--database postgres://…`). Jobs are claimed with `FOR UPDATE SKIP LOCKED` under a lease
//!   that the solving process renews; a job whose lease has run out is claimed again.
//!
//! The calls block (disk or network I/O): async code runs them with `spawn_blocking`. Both
//! implementations pass the same suite (`tests/store.rs`).
//!
//! The queue operations ([`Store::claim`], [`Store::renew`], [`Store::finish`],
//! [`Store::release`]) take an owner (one per process) and a lease: a job is `running` under
//! one owner until its lease runs out; [`Store::finish`] writes the final record and the files
//! only while the caller still owns the job, so that a result is written once.

pub mod embedded;
pub mod postgres;

use super::queue::{JobState, JobStatus};
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::time::Duration;

#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error("store: {0}")]
    Db(Box<redb::Error>),
    #[error("database: {0}")]
    Postgres(String),
    #[error("store: a record does not parse: {0}")]
    Json(#[from] serde_json::Error),
    #[error("store: {0}")]
    Io(#[from] std::io::Error),
}

/// What the store keeps per job: the document as it was posted and its status.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Record {
    pub document: Value,
    pub status: JobStatus,
}

impl Record {
    fn id(&self) -> &str {
        &self.status.id
    }
}

/// The answer of [`Store::insert`].
#[derive(Debug, Clone, PartialEq)]
pub enum Inserted {
    /// A new job, queued.
    New,
    /// A job with this id was already there: its record.
    Existing(Box<Record>),
    /// `capacity` jobs are already queued.
    Full,
}

/// Jobs by state.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counts {
    pub queued: usize,
    pub running: usize,
    pub(super) succeeded: usize,
    pub failed: usize,
    pub(super) cancelled: usize,
}

impl Counts {
    fn add(&mut self, state: JobState) {
        match state {
            JobState::Queued => self.queued += 1,
            JobState::Running => self.running += 1,
            JobState::Succeeded => self.succeeded += 1,
            JobState::Failed => self.failed += 1,
            JobState::Cancelled => self.cancelled += 1,
        }
    }
}

/// A job store. See the module documentation.
pub trait Store: Send + Sync {
    /// Writes a job's record (durably, before returning).
    fn put_job(&self, record: &Record) -> Result<(), StoreError>;
    /// Writes a job's record; it may become durable only with the next durable write.
    fn put_job_lazily(&self, record: &Record) -> Result<(), StoreError>;
    /// Makes every write so far durable.
    fn sync(&self) -> Result<(), StoreError>;
    /// Writes a job's record and its files together: both appear or neither.
    fn put_finished(&self, record: &Record, files: &[(String, &[u8])]) -> Result<(), StoreError>;
    /// Every job record.
    fn jobs(&self) -> Result<Vec<Record>, StoreError>;
    /// One file of a job.
    fn file(&self, id: &str, name: &str) -> Result<Option<Vec<u8>>, StoreError>;
    /// Forgets a job, its record and every file; `false` when there was none.
    fn remove(&self, id: &str) -> Result<bool, StoreError>;

    /// Adds a queued job unless one with its id is there; `Full` when `capacity` jobs are
    /// queued already. `durable`: on disk before it returns (otherwise with the next durable
    /// write, as [`Store::put_job_lazily`]).
    fn insert(
        &self,
        record: &Record,
        capacity: usize,
        durable: bool,
    ) -> Result<Inserted, StoreError>;
    /// One job's record.
    fn job(&self, id: &str) -> Result<Option<Record>, StoreError>;
    /// Statuses, newest first (then by id), at most `limit`.
    fn list(&self, limit: usize) -> Result<Vec<JobStatus>, StoreError>;
    /// Jobs by state.
    fn counts(&self) -> Result<Counts, StoreError>;
    /// Takes the oldest job that is queued, or running under a lease that has run out, for
    /// `owner` until `lease` from now: its record, now `running` (`started_ms` set, progress
    /// at the start of the projection). At most one caller gets a given job.
    fn claim(&self, owner: &str, lease: Duration) -> Result<Option<Record>, StoreError>;
    /// Claims, renewals and releases need not wait for the disk: lost in a crash of the
    /// store, they leave a job queued or its lease shorter, which the queue survives.
    ///
    /// Extends `owner`'s lease on a running job and writes its status (progress). `false`
    /// when the job is gone or no longer `owner`'s: the caller must stop solving it.
    fn renew(&self, owner: &str, lease: Duration, status: &JobStatus) -> Result<bool, StoreError>;
    /// Writes a claimed job's final record and its files, only while `owner` still holds it;
    /// `false` (nothing written) otherwise.
    fn finish(
        &self,
        owner: &str,
        record: &Record,
        files: &[(String, &[u8])],
    ) -> Result<bool, StoreError>;
    /// Gives a claimed job back (queued, no owner), e.g. at shutdown.
    fn release(&self, owner: &str, id: &str) -> Result<(), StoreError>;
    /// Forgets the jobs that finished at or before `before_ms`; how many. With a shared
    /// database one process at a time does it.
    fn expire(&self, before_ms: u64) -> Result<usize, StoreError>;
    /// The bytes kept for every job: its document and status as stored and the bytes of its
    /// files (the database's own overhead, pages, indexes and free space, is not counted).
    fn stored_bytes(&self) -> Result<u64, StoreError>;
    /// Forgets finished jobs (succeeded, failed or cancelled), the one that finished first
    /// first (then by id), until at most `max_bytes` are kept ([`Store::stored_bytes`]) or
    /// no finished job is left; their ids. Queued and running jobs are never forgotten.
    /// With a shared database one process at a time does it.
    fn evict(&self, max_bytes: u64) -> Result<Vec<String>, StoreError>;
    /// Whether the store answers.
    fn ping(&self) -> Result<(), StoreError>;
}

/// Which of `jobs` (id, bytes, finished at, for finished jobs only) to forget so that
/// `total` bytes come down to `max_bytes`: the first finished first, then by id.
fn to_evict(mut jobs: Vec<(String, u64, u64)>, total: u64, max_bytes: u64) -> Vec<String> {
    jobs.sort_by(|a, b| (a.2, &a.0).cmp(&(b.2, &b.0)));
    let mut total = total;
    let mut out = Vec::new();
    for (id, bytes, _) in jobs {
        if total <= max_bytes {
            break;
        }
        total = total.saturating_sub(bytes);
        out.push(id);
    }
    out
}

/// The status of a job as [`Store::claim`] leaves it: running, at the start.
fn claimed(status: &mut JobStatus, now_ms: u64) {
    status.state = JobState::Running;
    status.started_ms = Some(now_ms);
    status.finished_ms = None;
    status.error = None;
    status.progress = super::queue::ProgressInfo {
        phase: "projection".into(),
        fraction: 0.0,
    };
}

/// `true` for a record that [`Store::claim`] may take at `now_ms` given its lease's end.
fn claimable(state: JobState, lease_until_ms: Option<u64>, now_ms: u64) -> bool {
    match state {
        JobState::Queued => true,
        JobState::Running => lease_until_ms.is_none_or(|t| t <= now_ms),
        _ => false,
    }
}
