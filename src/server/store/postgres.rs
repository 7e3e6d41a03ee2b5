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
//! Round trips: the path of a synchronous render crosses the store four times (the job's
//! insert, its claim, its result, and the image read for the answer), and on loopback each
//! round trip to the database costs 0.1–0.3 ms of the answer, more on a loaded machine. So each
//! call makes as few as it can: statements are prepared once per connection (deadpool's
//! statement cache) instead of at every call, which halves a statement's round trips; a write
//! is one statement where it can be (a result and all its files together, in one statement
//! with data-modifying `WITH` parts, which commits as one); and a transaction that need not
//! wait for the disk ([`Lazy`]) sends its `BEGIN` with its first statement and its `COMMIT`
//! with its last (tokio-postgres pipelines requests that are polled together, in the order
//! they are first polled). Files are compressed with lz4 where the server has it (migration
//! 2): PostgreSQL's default, pglz, took about 4 ms to compress the 200 kB image of a 50 ms
//! job, on the path of every result.
//!
//! The calls block: each runs on the tokio runtime the store was opened on (so it must not be
//! called from that runtime's own threads; `spawn_blocking` and the solver's threads are fine),
//! and gives up after [`Postgres::OP_TIMEOUT`] when the database does not answer.

use super::{claimed, Counts, Inserted, Record, Store, StoreError};
use crate::server::queue::{now_ms, JobState, JobStatus, ProgressInfo};
use deadpool_postgres::{Manager, ManagerConfig, Pool, RecyclingMethod, Runtime};
use futures_util::future::{join, join3};
use std::future::Future;
use std::str::FromStr;
use std::time::Duration;
use tokio_postgres::types::ToSql;
use tokio_postgres::{NoTls, Row};

/// The embedded migrations, in order: (version, name, SQL).
const MIGRATIONS: &[(i32, &str, &str)] = &[
    (1, "jobs", include_str!("migrations/0001_jobs.sql")),
    (
        2,
        "files_lz4",
        include_str!("migrations/0002_files_lz4.sql"),
    ),
];

/// Advisory lock keys (any two constants that other applications are unlikely to use).
const MIGRATION_LOCK: i64 = 0x7761_7672_6164_0001;
const EXPIRY_LOCK: i64 = 0x7761_7672_6164_0002;

/// Opens a transaction whose commit does not wait for the WAL flush (one message, two
/// statements: the simple query protocol).
const BEGIN_LAZILY: &str = "BEGIN; SET LOCAL synchronous_commit = off";

/// A record and its files, inserted or replaced, in one statement (`$1`–`$6`: id, state,
/// created, finished, document, status; `$7`, `$8`: the files' names and bytes, as arrays):
/// one round trip for all the files instead of one each, and one commit.
const UPSERT: &str = "
    WITH job AS (
        INSERT INTO wavrad_jobs (id, state, created_ms, finished_ms, document, status)
        VALUES ($1, $2, $3, $4, $5, $6)
        ON CONFLICT (id) DO UPDATE SET state = EXCLUDED.state,
            finished_ms = EXCLUDED.finished_ms, document = EXCLUDED.document,
            status = EXCLUDED.status
        RETURNING id)
    INSERT INTO wavrad_files (job_id, name, data)
    SELECT job.id, f.name, f.data FROM job, unnest($7::text[], $8::bytea[]) AS f (name, data)
    ON CONFLICT (job_id, name) DO UPDATE SET data = EXCLUDED.data";

/// A claimed job's final record and its files, only while its owner holds it, in one
/// statement (`$1`–`$5`: id, owner, state, status, finished; `$6`, `$7`: the files' names and
/// bytes): the id when written, no row otherwise (and then no file either).
const FINISH: &str = "
    WITH done AS (
        UPDATE wavrad_jobs
        SET state = $3, status = $4, finished_ms = $5, owner = NULL, lease_until = NULL
        WHERE id = $1 AND owner = $2 AND state = 'running'
        RETURNING id),
    files AS (
        INSERT INTO wavrad_files (job_id, name, data)
        SELECT done.id, f.name, f.data FROM done, unnest($6::text[], $7::bytea[]) AS f (name, data)
        ON CONFLICT (job_id, name) DO UPDATE SET data = EXCLUDED.data)
    SELECT id FROM done";

fn pgerr(e: impl std::fmt::Display) -> StoreError {
    StoreError::Postgres(e.to_string())
}

pub struct Postgres {
    pool: Pool,
    handle: tokio::runtime::Handle,
}

impl Postgres {
    /// How long one call may wait for the database.
    const OP_TIMEOUT: Duration = Duration::from_secs(5);

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

    /// Runs `sql` (a read, or a write that commits durably on its own), prepared once per
    /// connection; its rows.
    async fn query(
        &self,
        sql: &str,
        params: &[&(dyn ToSql + Sync)],
    ) -> Result<Vec<Row>, StoreError> {
        let client = self.pool.get().await.map_err(pgerr)?;
        let statement = client.prepare_cached(sql).await.map_err(pgerr)?;
        client.query(&statement, params).await.map_err(pgerr)
    }

    /// Runs one statement that writes, its rows: on its own (committed when it ends, after the
    /// WAL flush) when `durable`, otherwise in a [`Lazy`] transaction that sends `BEGIN`, the
    /// statement and `COMMIT` together. One round trip either way.
    async fn write(
        &self,
        durable: bool,
        sql: &str,
        params: &[&(dyn ToSql + Sync)],
    ) -> Result<Vec<Row>, StoreError> {
        if durable {
            return self.query(sql, params).await;
        }
        let txn = self.lazily().await?;
        let (client, statement) = (txn.client(), txn.prepare(sql).await?);
        let (begun, rows, committed) = join3(
            client.batch_execute(BEGIN_LAZILY),
            client.query(&statement, params),
            client.batch_execute("COMMIT"),
        )
        .await;
        begun.map_err(pgerr)?;
        let rows = rows.map_err(pgerr)?;
        committed.map_err(pgerr)?;
        txn.ended();
        Ok(rows)
    }

    /// A connection for a [`Lazy`] transaction (not begun yet).
    async fn lazily(&self) -> Result<Lazy, StoreError> {
        Ok(Lazy(Some(self.pool.get().await.map_err(pgerr)?)))
    }

    async fn upsert(
        &self,
        record: &Record,
        files: &[(String, &[u8])],
        durable: bool,
    ) -> Result<(), StoreError> {
        let (document, status) = texts(record)?;
        let (names, data) = columns(files);
        self.write(
            durable,
            UPSERT,
            &[
                &record.id(),
                &record.status.state.as_str(),
                &ms(record.status.created_ms),
                &record.status.finished_ms.map(ms),
                &document,
                &status,
                &names,
                &data,
            ],
        )
        .await?;
        Ok(())
    }

    async fn record(&self, id: &str) -> Result<Option<Record>, StoreError> {
        let rows = self
            .query(
                "SELECT document, status FROM wavrad_jobs WHERE id = $1",
                &[&id],
            )
            .await?;
        rows.first()
            .map(|r| parse_record(r.get(0), r.get(1)))
            .transpose()
    }
}

/// A transaction that commits without waiting for the WAL flush (claims, renewals, releases,
/// lazy inserts), on a connection of the pool. It is begun by hand ([`BEGIN_LAZILY`]) so that
/// `BEGIN` can go out with the first statement (tokio-postgres's own transactions wait for
/// the answer to `BEGIN` before anything else is sent) and `COMMIT` with the last: a
/// transaction of one statement costs one round trip, as the statement alone would.
///
/// Dropped before [`Lazy::ended`] (an error, or the caller's timeout) it closes its
/// connection rather than hand it back to the pool in the middle of a transaction: the server
/// rolls the transaction back when the connection goes.
struct Lazy(Option<deadpool_postgres::Client>);

impl Lazy {
    fn client(&self) -> &deadpool_postgres::Client {
        self.0
            .as_ref()
            .expect("a connection until the transaction ends")
    }

    /// `sql` prepared on this connection, once (deadpool's statement cache).
    async fn prepare(&self, sql: &str) -> Result<tokio_postgres::Statement, StoreError> {
        self.client().prepare_cached(sql).await.map_err(pgerr)
    }

    /// The transaction is over (its `COMMIT` answered): the connection goes back to the pool.
    fn ended(mut self) {
        self.0.take();
    }
}

impl Drop for Lazy {
    fn drop(&mut self) {
        if let Some(client) = self.0.take() {
            drop(deadpool_postgres::Object::take(client));
        }
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

/// Files as the two arrays of [`UPSERT`] and [`FINISH`]: names and bytes.
fn columns<'a>(files: &'a [(String, &'a [u8])]) -> (Vec<&'a str>, Vec<&'a [u8]>) {
    files
        .iter()
        .map(|(name, data)| (name.as_str(), *data))
        .unzip()
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
            self.query(
                "UPDATE wavrad_migrations SET applied_at = applied_at WHERE version = 1",
                &[],
            )
            .await?;
            Ok(())
        })
    }

    fn put_finished(&self, record: &Record, files: &[(String, &[u8])]) -> Result<(), StoreError> {
        self.run(self.upsert(record, files, true))
    }

    fn jobs(&self) -> Result<Vec<Record>, StoreError> {
        self.run(async {
            let rows = self
                .query("SELECT document, status FROM wavrad_jobs", &[])
                .await?;
            rows.iter()
                .map(|r| parse_record(r.get(0), r.get(1)))
                .collect()
        })
    }

    fn file(&self, id: &str, name: &str) -> Result<Option<Vec<u8>>, StoreError> {
        self.run(async {
            let rows = self
                .query(
                    "SELECT data FROM wavrad_files WHERE job_id = $1 AND name = $2",
                    &[&id, &name],
                )
                .await?;
            Ok(rows.first().map(|r| r.get(0)))
        })
    }

    fn remove(&self, id: &str) -> Result<bool, StoreError> {
        self.run(async {
            let rows = self
                .query("DELETE FROM wavrad_jobs WHERE id = $1 RETURNING id", &[&id])
                .await?;
            Ok(!rows.is_empty())
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
            let inserted = self
                .write(
                    durable,
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
                .await?;
            if !inserted.is_empty() {
                return Ok(Inserted::New);
            }
            // a statement of its own, which sees a job that another process inserted while
            // the insert above waited for it
            Ok(match self.record(record.id()).await? {
                Some(r) => Inserted::Existing(Box::new(r)),
                None => Inserted::Full,
            })
        })
    }

    fn job(&self, id: &str) -> Result<Option<Record>, StoreError> {
        self.run(self.record(id))
    }

    fn list(&self, limit: usize) -> Result<Vec<JobStatus>, StoreError> {
        self.run(async {
            let rows = self
                .query(
                    "SELECT status FROM wavrad_jobs ORDER BY created_ms DESC, id LIMIT $1",
                    &[&ms(limit as u64)],
                )
                .await?;
            rows.iter()
                .map(|r| Ok(serde_json::from_str(r.get(0))?))
                .collect()
        })
    }

    fn counts(&self) -> Result<Counts, StoreError> {
        self.run(async {
            let rows = self
                .query(
                    "SELECT state, count(*) FROM wavrad_jobs GROUP BY state",
                    &[],
                )
                .await?;
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

    /// Two round trips: `BEGIN` with the claim, then the claimed status with `COMMIT`.
    fn claim(&self, owner: &str, lease: Duration) -> Result<Option<Record>, StoreError> {
        self.run(async {
            let txn = self.lazily().await?;
            let client = txn.client();
            let take = txn
                .prepare(
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
                )
                .await?;
            let start = txn
                .prepare("UPDATE wavrad_jobs SET status = $2 WHERE id = $1")
                .await?;
            let (begun, row) = join(
                client.batch_execute(BEGIN_LAZILY),
                client.query_opt(&take, &[&owner, &lease_ms(lease)]),
            )
            .await;
            begun.map_err(pgerr)?;
            let Some(row) = row.map_err(pgerr)? else {
                client.batch_execute("COMMIT").await.map_err(pgerr)?;
                txn.ended();
                return Ok(None);
            };
            let mut record = parse_record(row.get(0), row.get(1))?;
            claimed(&mut record.status, now_ms());
            let status = serde_json::to_string(&record.status)?;
            let (written, committed) = join(
                client.execute(&start, &[&record.id(), &status]),
                client.batch_execute("COMMIT"),
            )
            .await;
            written.map_err(pgerr)?;
            committed.map_err(pgerr)?;
            txn.ended();
            Ok(Some(record))
        })
    }

    fn renew(&self, owner: &str, lease: Duration, status: &JobStatus) -> Result<bool, StoreError> {
        let text = serde_json::to_string(status)?;
        self.run(async {
            let rows = self
                .write(
                    false,
                    "UPDATE wavrad_jobs
                     SET lease_until = clock_timestamp() + $3::float8 * interval '1 millisecond',
                         status = $4
                     WHERE id = $1 AND owner = $2 AND state = 'running'
                     RETURNING id",
                    &[&status.id, &owner, &lease_ms(lease), &text],
                )
                .await?;
            Ok(rows.len() == 1)
        })
    }

    /// One statement, committed durably: the result is on disk before the job is seen done.
    fn finish(
        &self,
        owner: &str,
        record: &Record,
        files: &[(String, &[u8])],
    ) -> Result<bool, StoreError> {
        let status = serde_json::to_string(&record.status)?;
        let (names, data) = columns(files);
        self.run(async {
            let rows = self
                .write(
                    true,
                    FINISH,
                    &[
                        &record.id(),
                        &owner,
                        &record.status.state.as_str(),
                        &status,
                        &record.status.finished_ms.map(ms),
                        &names,
                        &data,
                    ],
                )
                .await?;
            Ok(rows.len() == 1)
        })
    }

    fn release(&self, owner: &str, id: &str) -> Result<(), StoreError> {
        self.run(async {
            let txn = self.lazily().await?;
            let client = txn.client();
            let held = txn
                .prepare(
                    "SELECT status FROM wavrad_jobs
                     WHERE id = $1 AND owner = $2 AND state = 'running' FOR UPDATE",
                )
                .await?;
            let give_back = txn
                .prepare(
                    "UPDATE wavrad_jobs SET state = 'queued', owner = NULL, lease_until = NULL,
                         status = $2
                     WHERE id = $1",
                )
                .await?;
            let (begun, row) = join(
                client.batch_execute(BEGIN_LAZILY),
                client.query_opt(&held, &[&id, &owner]),
            )
            .await;
            begun.map_err(pgerr)?;
            let Some(row) = row.map_err(pgerr)? else {
                client.batch_execute("COMMIT").await.map_err(pgerr)?;
                txn.ended();
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
            let (written, committed) = join(
                client.execute(&give_back, &[&id, &text]),
                client.batch_execute("COMMIT"),
            )
            .await;
            written.map_err(pgerr)?;
            committed.map_err(pgerr)?;
            txn.ended();
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
