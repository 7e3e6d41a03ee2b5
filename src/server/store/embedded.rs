//! The embedded store: job records and files kept on disk under `data_dir`, in one redb
//! database (`data_dir/wavrad.redb`); no external server, one process. Four tables: `jobs`
//! (id → the job's [`Record`] as JSON), `files` (`id/name` → bytes: `result.json` and the
//! images), `leases` (id → `owner` and the lease's end, for jobs taken by [`Store::claim`])
//! and `sizes` (id → the bytes of its record and of its files, and when it finished), kept
//! with every write so that [`Store::evict`] need not read the files. A database written
//! before `sizes` existed gets it filled in when it is opened.
//!
//! redb caches the pages it reads and writes; its cache is given a size
//! (`Embedded::open_with_cache`, `--store-cache-bytes`): its default, 1 GiB, let the
//! resident memory grow with every image read.
//!
//! Every write is one transaction, committed durably before the caller goes on (except
//! [`Store::put_job_lazily`]), so that a job answered 202 survives a crash: a finished job's
//! record and all its files appear together or not at all.

use super::{claimable, claimed, Counts, Inserted, Record, Store, StoreError};
use crate::server::queue::{now_ms, JobState, JobStatus};
use redb::{Database, ReadableTable, ReadableTableMetadata, TableDefinition, WriteTransaction};
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::time::Duration;

const JOBS: TableDefinition<&str, &[u8]> = TableDefinition::new("jobs");
const FILES: TableDefinition<&str, &[u8]> = TableDefinition::new("files");
const LEASES: TableDefinition<&str, &[u8]> = TableDefinition::new("leases");
/// id → (bytes of the record, bytes of the files, `finished_ms` of a finished job or
/// [`UNFINISHED`]).
const SIZES: TableDefinition<&str, (u64, u64, u64)> = TableDefinition::new("sizes");
const UNFINISHED: u64 = u64::MAX;

fn dberr<E: Into<redb::Error>>(e: E) -> StoreError {
    StoreError::Db(Box::new(e.into()))
}

#[derive(Serialize, Deserialize)]
struct Lease {
    owner: String,
    until_ms: u64,
}

pub struct Embedded {
    db: Database,
}

impl Embedded {
    /// The page cache of [`Embedded::open`] (the default of `--store-cache-bytes`).
    const DEFAULT_CACHE_BYTES: usize = 4 << 20;

    /// Opens (or creates) the database under `dir`, with a page cache of
    /// [`Self::DEFAULT_CACHE_BYTES`].
    pub fn open(dir: &Path) -> Result<Embedded, StoreError> {
        Self::open_with_cache(dir, Self::DEFAULT_CACHE_BYTES)
    }

    /// Opens (or creates) the database under `dir`; redb caches at most `cache_bytes` of its
    /// pages in memory.
    pub(crate) fn open_with_cache(dir: &Path, cache_bytes: usize) -> Result<Embedded, StoreError> {
        std::fs::create_dir_all(dir)?;
        let db = Database::builder()
            .set_cache_size(cache_bytes)
            .create(dir.join("wavrad.redb"))
            .map_err(dberr)?;
        let txn = db.begin_write().map_err(dberr)?;
        txn.open_table(JOBS).map_err(dberr)?;
        txn.open_table(FILES).map_err(dberr)?;
        txn.open_table(LEASES).map_err(dberr)?;
        txn.open_table(SIZES).map_err(dberr)?;
        Self::fill_in_sizes(&txn)?;
        txn.commit().map_err(dberr)?;
        Ok(Embedded { db })
    }

    /// Writes the sizes of the jobs that have none (a database from before `sizes`).
    fn fill_in_sizes(txn: &WriteTransaction) -> Result<(), StoreError> {
        let missing: Vec<Record> = {
            let jobs = txn.open_table(JOBS).map_err(dberr)?;
            let sizes = txn.open_table(SIZES).map_err(dberr)?;
            let mut out = Vec::new();
            for row in jobs.iter().map_err(dberr)? {
                let (k, v) = row.map_err(dberr)?;
                if sizes.get(k.value()).map_err(dberr)?.is_none() {
                    out.push(serde_json::from_slice(v.value())?);
                }
            }
            out
        };
        for record in &missing {
            let id = record.id();
            let files = {
                let files = txn.open_table(FILES).map_err(dberr)?;
                let (lo, hi) = (format!("{id}/"), format!("{id}0"));
                let mut n = 0u64;
                for row in files.range(lo.as_str()..hi.as_str()).map_err(dberr)? {
                    n += row.map_err(dberr)?.1.value().len() as u64;
                }
                n
            };
            Self::write_record(txn, record)?;
            Self::add_file_bytes(txn, id, files as i64)?;
        }
        Ok(())
    }

    fn write_record(txn: &WriteTransaction, record: &Record) -> Result<(), StoreError> {
        let bytes = serde_json::to_vec(record)?;
        txn.open_table(JOBS)
            .map_err(dberr)?
            .insert(record.id(), bytes.as_slice())
            .map_err(dberr)?;
        let mut sizes = txn.open_table(SIZES).map_err(dberr)?;
        let files = sizes
            .get(record.id())
            .map_err(dberr)?
            .map_or(0, |v| v.value().1);
        let finished = match record.status.finished_ms {
            Some(t) if record.status.state.is_final() => t.min(UNFINISHED - 1),
            _ => UNFINISHED,
        };
        sizes
            .insert(record.id(), (bytes.len() as u64, files, finished))
            .map_err(dberr)?;
        Ok(())
    }

    /// Adds `delta` to the bytes of a job's files in `sizes`.
    fn add_file_bytes(txn: &WriteTransaction, id: &str, delta: i64) -> Result<(), StoreError> {
        let mut sizes = txn.open_table(SIZES).map_err(dberr)?;
        let (record, files, finished) = sizes
            .get(id)
            .map_err(dberr)?
            .map_or((0, 0, UNFINISHED), |v| v.value());
        let files = files.saturating_add_signed(delta);
        sizes.insert(id, (record, files, finished)).map_err(dberr)?;
        Ok(())
    }

    fn write_files(
        txn: &WriteTransaction,
        id: &str,
        files: &[(String, &[u8])],
    ) -> Result<(), StoreError> {
        if files.is_empty() {
            return Ok(());
        }
        let mut delta = 0i64;
        {
            let mut table = txn.open_table(FILES).map_err(dberr)?;
            for (name, data) in files {
                let old = table
                    .insert(format!("{id}/{name}").as_str(), *data)
                    .map_err(dberr)?
                    .map_or(0, |v| v.value().len());
                delta += data.len() as i64 - old as i64;
            }
        }
        Self::add_file_bytes(txn, id, delta)
    }

    fn read_record(txn: &WriteTransaction, id: &str) -> Result<Option<Record>, StoreError> {
        let jobs = txn.open_table(JOBS).map_err(dberr)?;
        let v = jobs.get(id).map_err(dberr)?;
        Ok(match v {
            Some(v) => Some(serde_json::from_slice(v.value())?),
            None => None,
        })
    }

    fn lease(txn: &WriteTransaction, id: &str) -> Result<Option<Lease>, StoreError> {
        let leases = txn.open_table(LEASES).map_err(dberr)?;
        let v = leases.get(id).map_err(dberr)?;
        Ok(match v {
            Some(v) => Some(serde_json::from_slice(v.value())?),
            None => None,
        })
    }

    fn set_lease(
        txn: &WriteTransaction,
        id: &str,
        lease: Option<&Lease>,
    ) -> Result<(), StoreError> {
        let mut leases = txn.open_table(LEASES).map_err(dberr)?;
        match lease {
            Some(l) => {
                let bytes = serde_json::to_vec(l)?;
                leases.insert(id, bytes.as_slice()).map_err(dberr)?;
            }
            None => {
                leases.remove(id).map_err(dberr)?;
            }
        }
        Ok(())
    }

    fn remove_in(txn: &WriteTransaction, id: &str) -> Result<bool, StoreError> {
        let existed = txn
            .open_table(JOBS)
            .map_err(dberr)?
            .remove(id)
            .map_err(dberr)?
            .is_some();
        txn.open_table(LEASES)
            .map_err(dberr)?
            .remove(id)
            .map_err(dberr)?;
        txn.open_table(SIZES)
            .map_err(dberr)?
            .remove(id)
            .map_err(dberr)?;
        let mut files = txn.open_table(FILES).map_err(dberr)?;
        // '0' follows '/' in ASCII: the range holds exactly the keys "id/…".
        let (lo, hi) = (format!("{id}/"), format!("{id}0"));
        let keys: Vec<String> = files
            .range(lo.as_str()..hi.as_str())
            .map_err(dberr)?
            .map(|r| r.map(|(k, _)| k.value().to_string()))
            .collect::<Result<_, _>>()
            .map_err(dberr)?;
        for k in keys {
            files.remove(k.as_str()).map_err(dberr)?;
        }
        Ok(existed)
    }

    /// Whether `owner` holds a running job's lease now.
    fn holds(txn: &WriteTransaction, owner: &str, id: &str) -> Result<bool, StoreError> {
        let Some(record) = Self::read_record(txn, id)? else {
            return Ok(false);
        };
        if record.status.state != JobState::Running {
            return Ok(false);
        }
        Ok(Self::lease(txn, id)?.is_some_and(|l| l.owner == owner && l.until_ms > now_ms()))
    }
}

impl Store for Embedded {
    fn put_job(&self, record: &Record) -> Result<(), StoreError> {
        self.put_finished(record, &[])
    }

    fn put_job_lazily(&self, record: &Record) -> Result<(), StoreError> {
        let mut txn = self.db.begin_write().map_err(dberr)?;
        txn.set_durability(redb::Durability::None);
        Self::write_record(&txn, record)?;
        txn.commit().map_err(dberr)?;
        Ok(())
    }

    /// A durable commit persists the non-durable ones before it.
    fn sync(&self) -> Result<(), StoreError> {
        let txn = self.db.begin_write().map_err(dberr)?;
        txn.commit().map_err(dberr)?;
        Ok(())
    }

    fn put_finished(&self, record: &Record, files: &[(String, &[u8])]) -> Result<(), StoreError> {
        let txn = self.db.begin_write().map_err(dberr)?;
        Self::write_record(&txn, record)?;
        Self::write_files(&txn, record.id(), files)?;
        txn.commit().map_err(dberr)?;
        Ok(())
    }

    fn jobs(&self) -> Result<Vec<Record>, StoreError> {
        let txn = self.db.begin_read().map_err(dberr)?;
        let table = txn.open_table(JOBS).map_err(dberr)?;
        let mut out = Vec::new();
        for row in table.iter().map_err(dberr)? {
            let (_, v) = row.map_err(dberr)?;
            out.push(serde_json::from_slice(v.value())?);
        }
        Ok(out)
    }

    fn file(&self, id: &str, name: &str) -> Result<Option<Vec<u8>>, StoreError> {
        let txn = self.db.begin_read().map_err(dberr)?;
        let table = txn.open_table(FILES).map_err(dberr)?;
        let v = table.get(format!("{id}/{name}").as_str()).map_err(dberr)?;
        Ok(v.map(|v| v.value().to_vec()))
    }

    fn remove(&self, id: &str) -> Result<bool, StoreError> {
        let txn = self.db.begin_write().map_err(dberr)?;
        let existed = Self::remove_in(&txn, id)?;
        txn.commit().map_err(dberr)?;
        Ok(existed)
    }

    fn insert(
        &self,
        record: &Record,
        capacity: usize,
        durable: bool,
    ) -> Result<Inserted, StoreError> {
        let mut txn = self.db.begin_write().map_err(dberr)?;
        if !durable {
            txn.set_durability(redb::Durability::None);
        }
        if let Some(existing) = Self::read_record(&txn, record.id())? {
            return Ok(Inserted::Existing(Box::new(existing)));
        }
        let queued = {
            let jobs = txn.open_table(JOBS).map_err(dberr)?;
            let mut n = 0;
            for row in jobs.iter().map_err(dberr)? {
                let (_, v) = row.map_err(dberr)?;
                let r: Record = serde_json::from_slice(v.value())?;
                n += usize::from(r.status.state == JobState::Queued);
            }
            n
        };
        if queued >= capacity {
            return Ok(Inserted::Full);
        }
        Self::write_record(&txn, record)?;
        txn.commit().map_err(dberr)?;
        Ok(Inserted::New)
    }

    fn job(&self, id: &str) -> Result<Option<Record>, StoreError> {
        let txn = self.db.begin_read().map_err(dberr)?;
        let table = txn.open_table(JOBS).map_err(dberr)?;
        let v = table.get(id).map_err(dberr)?;
        Ok(match v {
            Some(v) => Some(serde_json::from_slice(v.value())?),
            None => None,
        })
    }

    fn list(&self, limit: usize) -> Result<Vec<JobStatus>, StoreError> {
        let mut all: Vec<JobStatus> = self.jobs()?.into_iter().map(|r| r.status).collect();
        all.sort_by(|a, b| {
            b.created_ms
                .cmp(&a.created_ms)
                .then_with(|| a.id.cmp(&b.id))
        });
        all.truncate(limit);
        Ok(all)
    }

    fn counts(&self) -> Result<Counts, StoreError> {
        let mut counts = Counts::default();
        for r in self.jobs()? {
            counts.add(r.status.state);
        }
        Ok(counts)
    }

    fn claim(&self, owner: &str, lease: Duration) -> Result<Option<Record>, StoreError> {
        // one write transaction at a time: nobody else claims in between
        let txn = self.db.begin_write().map_err(dberr)?;
        let now = now_ms();
        let mut best: Option<Record> = None;
        {
            let jobs = txn.open_table(JOBS).map_err(dberr)?;
            let leases = txn.open_table(LEASES).map_err(dberr)?;
            for row in jobs.iter().map_err(dberr)? {
                let (k, v) = row.map_err(dberr)?;
                let r: Record = serde_json::from_slice(v.value())?;
                let until = match leases.get(k.value()).map_err(dberr)? {
                    Some(l) => Some(serde_json::from_slice::<Lease>(l.value())?.until_ms),
                    None => None,
                };
                if claimable(r.status.state, until, now)
                    && best.as_ref().is_none_or(|b| {
                        (r.status.created_ms, r.id()) < (b.status.created_ms, b.id())
                    })
                {
                    best = Some(r);
                }
            }
        }
        let Some(mut record) = best else {
            return Ok(None);
        };
        claimed(&mut record.status, now);
        Self::write_record(&txn, &record)?;
        let until_ms = now.saturating_add(lease.as_millis() as u64);
        Self::set_lease(
            &txn,
            record.id(),
            Some(&Lease {
                owner: owner.into(),
                until_ms,
            }),
        )?;
        txn.commit().map_err(dberr)?;
        Ok(Some(record))
    }

    fn renew(&self, owner: &str, lease: Duration, status: &JobStatus) -> Result<bool, StoreError> {
        let txn = self.db.begin_write().map_err(dberr)?;
        if !Self::holds(&txn, owner, &status.id)? {
            return Ok(false);
        }
        let Some(mut record) = Self::read_record(&txn, &status.id)? else {
            return Ok(false);
        };
        record.status = status.clone();
        Self::write_record(&txn, &record)?;
        let until_ms = now_ms().saturating_add(lease.as_millis() as u64);
        Self::set_lease(
            &txn,
            &status.id,
            Some(&Lease {
                owner: owner.into(),
                until_ms,
            }),
        )?;
        txn.commit().map_err(dberr)?;
        Ok(true)
    }

    fn finish(
        &self,
        owner: &str,
        record: &Record,
        files: &[(String, &[u8])],
    ) -> Result<bool, StoreError> {
        let txn = self.db.begin_write().map_err(dberr)?;
        if !Self::holds(&txn, owner, record.id())? {
            return Ok(false);
        }
        Self::write_record(&txn, record)?;
        Self::write_files(&txn, record.id(), files)?;
        Self::set_lease(&txn, record.id(), None)?;
        txn.commit().map_err(dberr)?;
        Ok(true)
    }

    fn release(&self, owner: &str, id: &str) -> Result<(), StoreError> {
        let txn = self.db.begin_write().map_err(dberr)?;
        if Self::lease(&txn, id)?.is_none_or(|l| l.owner != owner) {
            return Ok(());
        }
        if let Some(mut record) = Self::read_record(&txn, id)? {
            if record.status.state == JobState::Running {
                record.status.state = JobState::Queued;
                record.status.started_ms = None;
                record.status.progress = crate::server::queue::ProgressInfo {
                    phase: "queued".into(),
                    fraction: 0.0,
                };
                Self::write_record(&txn, &record)?;
            }
        }
        Self::set_lease(&txn, id, None)?;
        txn.commit().map_err(dberr)?;
        Ok(())
    }

    fn expire(&self, before_ms: u64) -> Result<usize, StoreError> {
        let old: Vec<String> = self
            .jobs()?
            .into_iter()
            .filter(|r| r.status.finished_ms.is_some_and(|f| f <= before_ms))
            .map(|r| r.status.id)
            .collect();
        let txn = self.db.begin_write().map_err(dberr)?;
        let mut n = 0;
        for id in &old {
            // finished jobs stay finished: the record read above is still the one to expire
            n += usize::from(Self::remove_in(&txn, id)?);
        }
        txn.commit().map_err(dberr)?;
        Ok(n)
    }

    fn stored_bytes(&self) -> Result<u64, StoreError> {
        let txn = self.db.begin_read().map_err(dberr)?;
        let sizes = txn.open_table(SIZES).map_err(dberr)?;
        let mut total = 0u64;
        for row in sizes.iter().map_err(dberr)? {
            let (record, files, _) = row.map_err(dberr)?.1.value();
            total = total.saturating_add(record).saturating_add(files);
        }
        Ok(total)
    }

    /// Committed without waiting for the disk: an eviction lost in a crash is done again.
    fn evict(&self, max_bytes: u64) -> Result<Vec<String>, StoreError> {
        let mut txn = self.db.begin_write().map_err(dberr)?;
        txn.set_durability(redb::Durability::None);
        let (total, finished) = {
            let sizes = txn.open_table(SIZES).map_err(dberr)?;
            let mut total = 0u64;
            let mut finished = Vec::new();
            for row in sizes.iter().map_err(dberr)? {
                let (k, v) = row.map_err(dberr)?;
                let (record, files, at) = v.value();
                let bytes = record.saturating_add(files);
                total = total.saturating_add(bytes);
                if at != UNFINISHED {
                    finished.push((k.value().to_string(), bytes, at));
                }
            }
            (total, finished)
        };
        let ids = super::to_evict(finished, total, max_bytes);
        if ids.is_empty() {
            return Ok(ids);
        }
        for id in &ids {
            Self::remove_in(&txn, id)?;
        }
        txn.commit().map_err(dberr)?;
        Ok(ids)
    }

    fn ping(&self) -> Result<(), StoreError> {
        let txn = self.db.begin_read().map_err(dberr)?;
        txn.open_table(JOBS).map_err(dberr)?.len().map_err(dberr)?;
        Ok(())
    }
}
