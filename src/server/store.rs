//! Job records and results kept on disk under `data_dir`, in one embedded redb database
//! (`data_dir/wavrad.redb`): no external server. Two tables: `jobs` (id → the job's record as
//! JSON) and `files` (`id/name` → bytes: `result.json` and the PNGs).
//!
//! Every write is one transaction, committed durably before the caller goes on, so that a job
//! answered 202 survives a crash: a finished job's record and all its files appear together or
//! not at all. The calls block (disk I/O): async code runs them with `spawn_blocking`.

use redb::{Database, ReadableTable, TableDefinition};
use serde::{de::DeserializeOwned, Serialize};
use std::path::Path;

const JOBS: TableDefinition<&str, &[u8]> = TableDefinition::new("jobs");
const FILES: TableDefinition<&str, &[u8]> = TableDefinition::new("files");

#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error("store: {0}")]
    Db(Box<redb::Error>),
    #[error("store: a record does not parse: {0}")]
    Json(#[from] serde_json::Error),
    #[error("store: {0}")]
    Io(#[from] std::io::Error),
}

fn dberr<E: Into<redb::Error>>(e: E) -> StoreError {
    StoreError::Db(Box::new(e.into()))
}

pub struct Store {
    db: Database,
}

impl Store {
    /// Opens (or creates) the database under `dir`.
    pub fn open(dir: &Path) -> Result<Store, StoreError> {
        std::fs::create_dir_all(dir)?;
        let db = Database::create(dir.join("wavrad.redb")).map_err(dberr)?;
        let txn = db.begin_write().map_err(dberr)?;
        txn.open_table(JOBS).map_err(dberr)?;
        txn.open_table(FILES).map_err(dberr)?;
        txn.commit().map_err(dberr)?;
        Ok(Store { db })
    }

    /// Writes a job's record.
    pub fn put_job<T: Serialize>(&self, id: &str, record: &T) -> Result<(), StoreError> {
        self.put_finished(id, record, &[])
    }

    /// Writes a job's record without waiting for the disk: it becomes durable with the next
    /// durable commit (for jobs whose client waits for the answer anyway).
    pub fn put_job_lazily<T: Serialize>(&self, id: &str, record: &T) -> Result<(), StoreError> {
        let bytes = serde_json::to_vec(record)?;
        let mut txn = self.db.begin_write().map_err(dberr)?;
        txn.set_durability(redb::Durability::None);
        txn.open_table(JOBS)
            .map_err(dberr)?
            .insert(id, bytes.as_slice())
            .map_err(dberr)?;
        txn.commit().map_err(dberr)?;
        Ok(())
    }

    /// Makes every write so far durable: the lazily written records among them are on disk
    /// when this returns (a durable commit persists the non-durable ones before it).
    pub fn sync(&self) -> Result<(), StoreError> {
        let txn = self.db.begin_write().map_err(dberr)?;
        txn.commit().map_err(dberr)?;
        Ok(())
    }

    /// Writes a job's record and its files in one transaction.
    pub fn put_finished<T: Serialize>(
        &self,
        id: &str,
        record: &T,
        files: &[(String, &[u8])],
    ) -> Result<(), StoreError> {
        let bytes = serde_json::to_vec(record)?;
        let txn = self.db.begin_write().map_err(dberr)?;
        {
            let mut jobs = txn.open_table(JOBS).map_err(dberr)?;
            jobs.insert(id, bytes.as_slice()).map_err(dberr)?;
            let mut table = txn.open_table(FILES).map_err(dberr)?;
            for (name, data) in files {
                table
                    .insert(format!("{id}/{name}").as_str(), *data)
                    .map_err(dberr)?;
            }
        }
        txn.commit().map_err(dberr)?;
        Ok(())
    }

    /// Every job record.
    pub fn jobs<T: DeserializeOwned>(&self) -> Result<Vec<T>, StoreError> {
        let txn = self.db.begin_read().map_err(dberr)?;
        let table = txn.open_table(JOBS).map_err(dberr)?;
        let mut out = Vec::new();
        for row in table.iter().map_err(dberr)? {
            let (_, v) = row.map_err(dberr)?;
            out.push(serde_json::from_slice(v.value())?);
        }
        Ok(out)
    }

    /// One file of a job.
    pub fn file(&self, id: &str, name: &str) -> Result<Option<Vec<u8>>, StoreError> {
        let txn = self.db.begin_read().map_err(dberr)?;
        let table = txn.open_table(FILES).map_err(dberr)?;
        let v = table.get(format!("{id}/{name}").as_str()).map_err(dberr)?;
        Ok(v.map(|v| v.value().to_vec()))
    }

    /// Forgets a job: its record and every file.
    pub fn remove(&self, id: &str) -> Result<(), StoreError> {
        let txn = self.db.begin_write().map_err(dberr)?;
        {
            let mut jobs = txn.open_table(JOBS).map_err(dberr)?;
            jobs.remove(id).map_err(dberr)?;
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
        }
        txn.commit().map_err(dberr)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_and_files_round_trip_and_are_removed_together() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(dir.path()).unwrap();
        store
            .put_finished(
                "a",
                &serde_json::json!({"n": 1}),
                &[("x.png".into(), b"png".as_slice())],
            )
            .unwrap();
        store.put_job("ab", &serde_json::json!({"n": 2})).unwrap();
        store
            .put_finished(
                "ab",
                &serde_json::json!({"n": 2}),
                &[("y".into(), b"y".as_slice())],
            )
            .unwrap();
        assert_eq!(store.jobs::<serde_json::Value>().unwrap().len(), 2);
        assert_eq!(
            store.file("a", "x.png").unwrap().as_deref(),
            Some(b"png".as_slice())
        );
        store.remove("a").unwrap();
        assert_eq!(store.file("a", "x.png").unwrap(), None);
        assert_eq!(
            store.file("ab", "y").unwrap().as_deref(),
            Some(b"y".as_slice())
        );
        drop(store);
        let store = Store::open(dir.path()).unwrap();
        assert_eq!(
            store.jobs::<serde_json::Value>().unwrap(),
            vec![serde_json::json!({"n": 2})]
        );
    }
}
