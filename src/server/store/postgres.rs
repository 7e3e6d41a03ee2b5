//! The PostgreSQL store: jobs, their status and their files in one database that any number
//! of `wavrad serve` processes share (`--database postgres://…`), through a pool of
//! `tokio-postgres` connections (`deadpool-postgres`).
//!
//! The schema is created and migrated at start by the migrations embedded in the binary
//! (`migrations/*.sql`, applied in order under an advisory lock, each recorded in
//! `wavrad_migrations`), so that processes starting together migrate once.
//!
//! The queue: [`Store::claim`] takes the oldest job that is queued, or running under a lease
//! that has run out, with `FOR UPDATE SKIP LOCKED`, so that two processes never take the same
//! job and neither waits for the other; leases are on the database's clock, so that the
//! machines' clocks need not agree. [`Store::finish`] writes the result only while its caller
//! still owns the job (one row lock decides), so that it is written once. Expiry and eviction
//! (`max_store_bytes`) take a transaction-scoped advisory lock: one process at a time. The
//! bytes of a job are those of its `document` and `status` and of its files' `data`
//! (`octet_length`, which reads the sizes without fetching the values).
//!
//! The calls block: each runs on the tokio runtime the store was opened on (so it must not be
//! called from that runtime's own threads; `spawn_blocking` and the solver's threads are fine),
//! and gives up after [`Postgres::OP_TIMEOUT`] when the database does not answer.

use super::{claimed, Counts, Inserted, Record, Store, StoreError};
use crate::server::queue::{now_ms, JobState, JobStatus, ProgressInfo};
use deadpool_postgres::{Manager, ManagerConfig, Pool, RecyclingMethod, Runtime};
use std::future::Future;
use std::str::FromStr;
use std::time::Duration;
use tokio_postgres::NoTls;

/// The embedded migrations, in order: (version, name, SQL).
const MIGRATIONS: &[(i32, &str, &str)] = &[(1, "jobs", include_str!("migrations/0001_jobs.sql"))];

/// Advisory lock keys (any two constants that other applications are unlikely to use).
const MIGRATION_LOCK: i64 = 0x7761_7672_6164_0001;
const EXPIRY_LOCK: i64 = 0x7761_7672_6164_0002;

fn pgerr(e: impl std::fmt::Display) -> StoreError {
    StoreError::Postgres(e.to_string())
}

pub struct Postgres {
    pool: Pool,
    handle: tokio::runtime::Handle,
}

impl Postgres {
    /// How long one call may wait for the database.
    pub const OP_TIMEOUT: Duration = Duration::from_secs(5);

    /// Connects to `url` (`postgres://user:password@host:port/database`, or the key=value
    /// form) with a pool of at most `pool_size` connections, and brings the schema up to date.
    /// Runs on the current tokio runtime, which later calls use.
    pub async fn connect(url: &str, pool_size: usize) -> Result<Postgres, StoreError> {
        let mut config = tokio_postgres::Config::from_str(url)
            .map_err(|e| StoreError::Postgres(format!("the database URL does not parse: {e}")))?;
        if config.get_connect_timeout().is_none() {
            config.connect_timeout(Duration::from_secs(3));
        }
        if config.get_application_name().is_none() {
            config.application_name("wavrad");
        }
        let manager = Manager::from_config(
            config,
            NoTls,
            ManagerConfig {
                recycling_method: RecyclingMethod::Fast,
            },
        );
        let pool = Pool::builder(manager)
            .max_size(pool_size.max(1))
            .wait_timeout(Some(Duration::from_secs(3)))
            .create_timeout(Some(Duration::from_secs(3)))
            .recycle_timeout(Some(Duration::from_secs(3)))
            .runtime(Runtime::Tokio1)
            .build()
            .map_err(pgerr)?;
        let store = Postgres {
            pool,
            handle: tokio::runtime::Handle::current(),
        };
        store.migrate().await?;
        Ok(store)
    }

    /// Applies the migrations this database has not seen, each in its own transaction.
    async fn migrate(&self) -> Result<(), StoreError> {
        let mut client = self.pool.get().await.map_err(pgerr)?;
        client
            .execute("SELECT pg_advisory_lock($1)", &[&MIGRATION_LOCK])
            .await
            .map_err(pgerr)?;
        let result = async {
            client
                .batch_execute(
                    "CREATE TABLE IF NOT EXISTS wavrad_migrations (
                        version integer PRIMARY KEY,
                        name text NOT NULL,
                        applied_at timestamptz NOT NULL DEFAULT now())",
                )
                .await
                .map_err(pgerr)?;
            let applied: Vec<i32> = client
                .query("SELECT version FROM wavrad_migrations", &[])
                .await
                .map_err(pgerr)?
                .iter()
                .map(|r| r.get(0))
                .collect();
            let known = MIGRATIONS.last().map_or(0, |m| m.0);
            if let Some(newer) = applied.iter().find(|v| **v > known) {
                return Err(StoreError::Postgres(format!(
                    "the database's schema (version {newer}) is newer than this wavrad knows \
                     ({known}); run a newer wavrad"
                )));
            }
            for (version, name, sql) in MIGRATIONS {
                if applied.contains(version) {
                    continue;
                }
                let txn = client.transaction().await.map_err(pgerr)?;
                txn.batch_execute(sql).await.map_err(pgerr)?;
                txn.execute(
                    "INSERT INTO wavrad_migrations (version, name) VALUES ($1, $2)",
                    &[version, name],
                )
                .await
                .map_err(pgerr)?;
                txn.commit().await.map_err(pgerr)?;
                tracing::info!(version, name, "database migrated");
            }
            Ok(())
        }
        .await;
        let _ = client
            .execute("SELECT pg_advisory_unlock($1)", &[&MIGRATION_LOCK])
            .await;
        result
    }

    /// Runs `f` on the store's runtime, from a thread outside it, for at most
    /// [`Self::OP_TIMEOUT`].
    fn run<T>(&self, f: impl Future<Output = Result<T, StoreError>>) -> Result<T, StoreError> {
        self.handle.block_on(async {
            tokio::time::timeout(Self::OP_TIMEOUT, f)
                .await
                .unwrap_or_else(|_| {
                    Err(StoreError::Postgres(
                        "the database did not answer in time".into(),
                    ))
                })
        })
    }

    /// How often a job was claimed (1 for a job solved by one process; more when a process
    /// lost it), or `None` for an unknown job.
    pub fn claims(&self, id: &str) -> Result<Option<i32>, StoreError> {
        self.run(async {
            let client = self.pool.get().await.map_err(pgerr)?;
            let row = client
                .query_opt("SELECT claims FROM wavrad_jobs WHERE id = $1", &[&id])
                .await
                .map_err(pgerr)?;
            Ok(row.map(|r| r.get(0)))
        })
    }

    async fn upsert(
        &self,
        record: &Record,
        files: &[(String, &[u8])],
        durable: bool,
    ) -> Result<(), StoreError> {
        let (document, status) = texts(record)?;
        let finished = record.status.finished_ms.map(ms);
        let mut client = self.pool.get().await.map_err(pgerr)?;
        let txn = client.transaction().await.map_err(pgerr)?;
        if !durable {
            txn.batch_execute("SET LOCAL synchronous_commit = off")
                .await
                .map_err(pgerr)?;
        }
        txn.execute(
            "INSERT INTO wavrad_jobs (id, state, created_ms, finished_ms, document, status)
             VALUES ($1, $2, $3, $4, $5, $6)
             ON CONFLICT (id) DO UPDATE SET state = EXCLUDED.state,
                 finished_ms = EXCLUDED.finished_ms, document = EXCLUDED.document,
                 status = EXCLUDED.status",
            &[
                &record.id(),
                &record.status.state.as_str(),
                &ms(record.status.created_ms),
                &finished,
                &document,
                &status,
            ],
        )
        .await
        .map_err(pgerr)?;
        write_files(&txn, record.id(), files).await?;
        txn.commit().await.map_err(pgerr)?;
        Ok(())
    }
}

fn ms(v: u64) -> i64 {
    i64::try_from(v).unwrap_or(i64::MAX)
}

fn lease_ms(lease: Duration) -> f64 {
    lease.as_secs_f64() * 1e3
}

fn texts(record: &Record) -> Result<(String, String), StoreError> {
    Ok((
        serde_json::to_string(&record.document)?,
        serde_json::to_string(&record.status)?,
    ))
}

fn parse_record(document: &str, status: &str) -> Result<Record, StoreError> {
    Ok(Record {
        document: serde_json::from_str(document)?,
        status: serde_json::from_str(status)?,
    })
}

async fn write_files(
    txn: &deadpool_postgres::Transaction<'_>,
    id: &str,
    files: &[(String, &[u8])],
) -> Result<(), StoreError> {
    if files.is_empty() {
        return Ok(());
    }
    let insert = txn
        .prepare_cached(
            "INSERT INTO wavrad_files (job_id, name, data) VALUES ($1, $2, $3)
             ON CONFLICT (job_id, name) DO UPDATE SET data = EXCLUDED.data",
        )
        .await
        .map_err(pgerr)?;
    for (name, data) in files {
        txn.execute(&insert, &[&id, name, data])
            .await
            .map_err(pgerr)?;
    }
    Ok(())
}

impl Store for Postgres {
    fn put_job(&self, record: &Record) -> Result<(), StoreError> {
        self.run(self.upsert(record, &[], true))
    }

    /// Committed with `synchronous_commit = off`: durable within the WAL writer's delay.
    fn put_job_lazily(&self, record: &Record) -> Result<(), StoreError> {
        self.run(self.upsert(record, &[], false))
    }

    /// A synchronous commit that writes makes every commit before it durable.
    fn sync(&self) -> Result<(), StoreError> {
        self.run(async {
            let client = self.pool.get().await.map_err(pgerr)?;
            client
                .execute(
                    "UPDATE wavrad_migrations SET applied_at = applied_at WHERE version = 1",
                    &[],
                )
                .await
                .map_err(pgerr)?;
            Ok(())
        })
    }

    fn put_finished(&self, record: &Record, files: &[(String, &[u8])]) -> Result<(), StoreError> {
        self.run(self.upsert(record, files, true))
    }

    fn jobs(&self) -> Result<Vec<Record>, StoreError> {
        self.run(async {
            let client = self.pool.get().await.map_err(pgerr)?;
            let rows = client
                .query("SELECT document, status FROM wavrad_jobs", &[])
                .await
                .map_err(pgerr)?;
            rows.iter()
                .map(|r| parse_record(r.get(0), r.get(1)))
                .collect()
        })
    }

    fn file(&self, id: &str, name: &str) -> Result<Option<Vec<u8>>, StoreError> {
        self.run(async {
            let client = self.pool.get().await.map_err(pgerr)?;
            let row = client
                .query_opt(
                    "SELECT data FROM wavrad_files WHERE job_id = $1 AND name = $2",
                    &[&id, &name],
                )
                .await
                .map_err(pgerr)?;
            Ok(row.map(|r| r.get(0)))
        })
    }

    fn remove(&self, id: &str) -> Result<bool, StoreError> {
        self.run(async {
            let client = self.pool.get().await.map_err(pgerr)?;
            let n = client
                .execute("DELETE FROM wavrad_jobs WHERE id = $1", &[&id])
                .await
                .map_err(pgerr)?;
            Ok(n > 0)
        })
    }

    /// One statement: the count of queued jobs and the insert see the same snapshot, so
    /// processes inserting at the same instant may each pass a nearly full queue; the
    /// capacity is a limit on the backlog, not an exact count.
    fn insert(
        &self,
        record: &Record,
        capacity: usize,
        durable: bool,
    ) -> Result<Inserted, StoreError> {
        let (document, status) = texts(record)?;
        self.run(async {
            let mut client = self.pool.get().await.map_err(pgerr)?;
            let txn = client.transaction().await.map_err(pgerr)?;
            if !durable {
                txn.batch_execute("SET LOCAL synchronous_commit = off")
                    .await
                    .map_err(pgerr)?;
            }
            let inserted = txn
                .query_opt(
                    "WITH q AS (SELECT count(*) AS n FROM wavrad_jobs WHERE state = 'queued')
                     INSERT INTO wavrad_jobs (id, state, created_ms, document, status)
                     SELECT $1, 'queued', $2, $3, $4 FROM q WHERE q.n < $5
                     ON CONFLICT (id) DO NOTHING RETURNING id",
                    &[
                        &record.id(),
                        &ms(record.status.created_ms),
                        &document,
                        &status,
                        &ms(capacity as u64),
                    ],
                )
                .await
                .map_err(pgerr)?;
            if inserted.is_some() {
                txn.commit().await.map_err(pgerr)?;
                return Ok(Inserted::New);
            }
            let row = txn
                .query_opt(
                    "SELECT document, status FROM wavrad_jobs WHERE id = $1",
                    &[&record.id()],
                )
                .await
                .map_err(pgerr)?;
            txn.commit().await.map_err(pgerr)?;
            Ok(match row {
                Some(r) => Inserted::Existing(Box::new(parse_record(r.get(0), r.get(1))?)),
                None => Inserted::Full,
            })
        })
    }

    fn job(&self, id: &str) -> Result<Option<Record>, StoreError> {
        self.run(async {
            let client = self.pool.get().await.map_err(pgerr)?;
            let row = client
                .query_opt(
                    "SELECT document, status FROM wavrad_jobs WHERE id = $1",
                    &[&id],
                )
                .await
                .map_err(pgerr)?;
            row.map(|r| parse_record(r.get(0), r.get(1))).transpose()
        })
    }

    fn list(&self, limit: usize) -> Result<Vec<JobStatus>, StoreError> {
        self.run(async {
            let client = self.pool.get().await.map_err(pgerr)?;
            let rows = client
                .query(
                    "SELECT status FROM wavrad_jobs ORDER BY created_ms DESC, id LIMIT $1",
                    &[&ms(limit as u64)],
                )
                .await
                .map_err(pgerr)?;
            rows.iter()
                .map(|r| Ok(serde_json::from_str(r.get(0))?))
                .collect()
        })
    }

    fn counts(&self) -> Result<Counts, StoreError> {
        self.run(async {
            let client = self.pool.get().await.map_err(pgerr)?;
            let rows = client
                .query(
                    "SELECT state, count(*) FROM wavrad_jobs GROUP BY state",
                    &[],
                )
                .await
                .map_err(pgerr)?;
            let mut counts = Counts::default();
            for r in rows {
                let n = usize::try_from(r.get::<_, i64>(1)).unwrap_or(0);
                match r.get::<_, &str>(0) {
                    "queued" => counts.queued = n,
                    "running" => counts.running = n,
                    "succeeded" => counts.succeeded = n,
                    "failed" => counts.failed = n,
                    _ => counts.cancelled = n,
                }
            }
            Ok(counts)
        })
    }

    fn claim(&self, owner: &str, lease: Duration) -> Result<Option<Record>, StoreError> {
        self.run(async {
            let mut client = self.pool.get().await.map_err(pgerr)?;
            let txn = client.transaction().await.map_err(pgerr)?;
            txn.batch_execute("SET LOCAL synchronous_commit = off")
                .await
                .map_err(pgerr)?;
            let row = txn
                .query_opt(
                    "UPDATE wavrad_jobs
                     SET state = 'running', owner = $1, claims = claims + 1,
                         lease_until = clock_timestamp() + $2::float8 * interval '1 millisecond'
                     WHERE id = (
                         SELECT id FROM wavrad_jobs
                         WHERE state = 'queued'
                            OR (state = 'running' AND lease_until < clock_timestamp())
                         ORDER BY created_ms, id
                         LIMIT 1
                         FOR UPDATE SKIP LOCKED)
                     RETURNING document, status",
                    &[&owner, &lease_ms(lease)],
                )
                .await
                .map_err(pgerr)?;
            let Some(row) = row else {
                return Ok(None);
            };
            let mut record = parse_record(row.get(0), row.get(1))?;
            claimed(&mut record.status, now_ms());
            let status = serde_json::to_string(&record.status)?;
            txn.execute(
                "UPDATE wavrad_jobs SET status = $2 WHERE id = $1",
                &[&record.id(), &status],
            )
            .await
            .map_err(pgerr)?;
            txn.commit().await.map_err(pgerr)?;
            Ok(Some(record))
        })
    }

    fn renew(&self, owner: &str, lease: Duration, status: &JobStatus) -> Result<bool, StoreError> {
        let text = serde_json::to_string(status)?;
        self.run(async {
            let mut client = self.pool.get().await.map_err(pgerr)?;
            let txn = client.transaction().await.map_err(pgerr)?;
            txn.batch_execute("SET LOCAL synchronous_commit = off")
                .await
                .map_err(pgerr)?;
            let n = txn
                .execute(
                    "UPDATE wavrad_jobs
                     SET lease_until = clock_timestamp() + $3::float8 * interval '1 millisecond',
                         status = $4
                     WHERE id = $1 AND owner = $2 AND state = 'running'",
                    &[&status.id, &owner, &lease_ms(lease), &text],
                )
                .await
                .map_err(pgerr)?;
            txn.commit().await.map_err(pgerr)?;
            Ok(n == 1)
        })
    }

    fn finish(
        &self,
        owner: &str,
        record: &Record,
        files: &[(String, &[u8])],
    ) -> Result<bool, StoreError> {
        let status = serde_json::to_string(&record.status)?;
        self.run(async {
            let mut client = self.pool.get().await.map_err(pgerr)?;
            let txn = client.transaction().await.map_err(pgerr)?;
            let n = txn
                .execute(
                    "UPDATE wavrad_jobs
                     SET state = $3, status = $4, finished_ms = $5, owner = NULL, lease_until = NULL
                     WHERE id = $1 AND owner = $2 AND state = 'running'",
                    &[
                        &record.id(),
                        &owner,
                        &record.status.state.as_str(),
                        &status,
                        &record.status.finished_ms.map(ms),
                    ],
                )
                .await
                .map_err(pgerr)?;
            if n != 1 {
                return Ok(false);
            }
            write_files(&txn, record.id(), files).await?;
            txn.commit().await.map_err(pgerr)?;
            Ok(true)
        })
    }

    fn release(&self, owner: &str, id: &str) -> Result<(), StoreError> {
        self.run(async {
            let mut client = self.pool.get().await.map_err(pgerr)?;
            let txn = client.transaction().await.map_err(pgerr)?;
            txn.batch_execute("SET LOCAL synchronous_commit = off")
                .await
                .map_err(pgerr)?;
            let row = txn
                .query_opt(
                    "SELECT status FROM wavrad_jobs
                     WHERE id = $1 AND owner = $2 AND state = 'running' FOR UPDATE",
                    &[&id, &owner],
                )
                .await
                .map_err(pgerr)?;
            let Some(row) = row else {
                return Ok(());
            };
            let mut status: JobStatus = serde_json::from_str(row.get(0))?;
            status.state = JobState::Queued;
            status.started_ms = None;
            status.progress = ProgressInfo {
                phase: "queued".into(),
                fraction: 0.0,
            };
            let text = serde_json::to_string(&status)?;
            txn.execute(
                "UPDATE wavrad_jobs SET state = 'queued', owner = NULL, lease_until = NULL,
                     status = $2
                 WHERE id = $1",
                &[&id, &text],
            )
            .await
            .map_err(pgerr)?;
            txn.commit().await.map_err(pgerr)?;
            Ok(())
        })
    }

    fn expire(&self, before_ms: u64) -> Result<usize, StoreError> {
        self.run(async {
            let mut client = self.pool.get().await.map_err(pgerr)?;
            let txn = client.transaction().await.map_err(pgerr)?;
            let locked: bool = txn
                .query_one("SELECT pg_try_advisory_xact_lock($1)", &[&EXPIRY_LOCK])
                .await
                .map_err(pgerr)?
                .get(0);
            if !locked {
                return Ok(0);
            }
            let n = txn
                .execute(
                    "DELETE FROM wavrad_jobs WHERE finished_ms <= $1",
                    &[&ms(before_ms)],
                )
                .await
                .map_err(pgerr)?;
            txn.commit().await.map_err(pgerr)?;
            Ok(n as usize)
        })
    }

    fn stored_bytes(&self) -> Result<u64, StoreError> {
        self.run(async {
            let client = self.pool.get().await.map_err(pgerr)?;
            let total: i64 = client
                .query_one(
                    "SELECT (coalesce((SELECT sum(octet_length(document) + octet_length(status))
                                       FROM wavrad_jobs), 0)
                           + coalesce((SELECT sum(octet_length(data)) FROM wavrad_files), 0))::bigint",
                    &[],
                )
                .await
                .map_err(pgerr)?
                .get(0);
            Ok(u64::try_from(total).unwrap_or(0))
        })
    }

    fn evict(&self, max_bytes: u64) -> Result<Vec<String>, StoreError> {
        self.run(async {
            let mut client = self.pool.get().await.map_err(pgerr)?;
            let txn = client.transaction().await.map_err(pgerr)?;
            let locked: bool = txn
                .query_one("SELECT pg_try_advisory_xact_lock($1)", &[&EXPIRY_LOCK])
                .await
                .map_err(pgerr)?
                .get(0);
            if !locked {
                return Ok(vec![]);
            }
            // every job's bytes, then the finished ones in the order they go, each with the
            // bytes forgotten up to and including it: a job goes while what is left before it
            // is still more than the limit
            let rows = txn
                .query(
                    "WITH sizes AS (
                         SELECT j.id, j.state, j.finished_ms,
                                octet_length(j.document) + octet_length(j.status)
                                    + coalesce(f.bytes, 0) AS bytes
                         FROM wavrad_jobs j
                         LEFT JOIN (SELECT job_id, sum(octet_length(data)) AS bytes
                                    FROM wavrad_files GROUP BY job_id) f ON f.job_id = j.id),
                     total AS (SELECT coalesce(sum(bytes), 0) AS t FROM sizes),
                     ranked AS (
                         SELECT id, bytes,
                                sum(bytes) OVER (ORDER BY finished_ms, id) AS upto
                         FROM sizes
                         WHERE state IN ('succeeded', 'failed', 'cancelled')
                           AND finished_ms IS NOT NULL)
                     DELETE FROM wavrad_jobs WHERE id IN (
                         SELECT id FROM ranked, total WHERE total.t - (ranked.upto - ranked.bytes) > $1::bigint)
                     RETURNING id",
                    &[&ms(max_bytes)],
                )
                .await
                .map_err(pgerr)?;
            txn.commit().await.map_err(pgerr)?;
            Ok(rows.iter().map(|r| r.get::<_, String>(0)).collect())
        })
    }

    fn ping(&self) -> Result<(), StoreError> {
        self.run(async {
            let client = self.pool.get().await.map_err(pgerr)?;
            client.query_one("SELECT 1", &[]).await.map_err(pgerr)?;
            Ok(())
        })
    }
}
