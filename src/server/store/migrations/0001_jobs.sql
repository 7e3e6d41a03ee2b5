-- Jobs: the document as posted, the status as served (both JSON text), and the columns the
-- queue works on. `state` and `finished_ms` repeat the status's fields for the queries.
CREATE TABLE wavrad_jobs (
    id          text PRIMARY KEY,
    state       text NOT NULL CHECK (state IN ('queued', 'running', 'succeeded', 'failed', 'cancelled')),
    created_ms  bigint NOT NULL,
    finished_ms bigint,
    -- the process solving it, and until when (the database's clock) its claim holds
    owner       text,
    lease_until timestamptz,
    -- how often the job was claimed: 1 unless a process lost it (died, shut down)
    claims      integer NOT NULL DEFAULT 0,
    document    text NOT NULL,
    status      text NOT NULL
);
CREATE INDEX wavrad_jobs_claimable ON wavrad_jobs (created_ms, id) WHERE state IN ('queued', 'running');
CREATE INDEX wavrad_jobs_newest ON wavrad_jobs (created_ms DESC, id);
CREATE INDEX wavrad_jobs_finished ON wavrad_jobs (finished_ms) WHERE finished_ms IS NOT NULL;

-- A job's files: result.json, the PNGs, scene.glb. They go with their job.
CREATE TABLE wavrad_files (
    job_id text NOT NULL REFERENCES wavrad_jobs (id) ON DELETE CASCADE,
    name   text NOT NULL,
    data   bytea NOT NULL,
    PRIMARY KEY (job_id, name)
);
