-- modb's job tables beside the engine's (procrastinate_*): what a job did, and the view modb.jobs over both.
-- Made by `modb worker --init` (and `modb db start`); can run again.
CREATE SCHEMA IF NOT EXISTS modb_jobs;
COMMENT ON SCHEMA modb_jobs IS 'MoDB: what running and finished jobs did (the engine''s own tables are procrastinate_*)';

CREATE TABLE IF NOT EXISTS modb_jobs.progress (
    job_id     bigint PRIMARY KEY REFERENCES procrastinate_jobs (id) ON DELETE CASCADE,
    done       bigint NOT NULL DEFAULT 0,
    total      bigint,
    unit       text,
    log        text[] NOT NULL DEFAULT '{}',
    result     jsonb,
    error      text,
    updated_at timestamptz NOT NULL DEFAULT now()
);
COMMENT ON TABLE modb_jobs.progress IS
    'Per job: items done of total (in unit), its log lines, its result (ids of what it made) or error; written by the worker as it goes';

CREATE OR REPLACE VIEW modb.jobs AS
SELECT j.id, j.task_name AS kind, j.queue_name AS queue,
       CASE j.status WHEN 'todo' THEN 'queued' WHEN 'doing' THEN 'running' WHEN 'succeeded' THEN 'done'
                     WHEN 'failed' THEN 'failed' ELSE 'cancelled' END AS state,
       j.abort_requested AS cancel_requested, j.args->>'submitter' AS submitter,
       j.args - 'submitter' AS arguments, j.attempts, p.done, p.total, p.unit,
       (SELECT min(e.at) FROM procrastinate_events e WHERE e.job_id = j.id AND e.type = 'deferred') AS queued_at,
       (SELECT max(e.at) FROM procrastinate_events e WHERE e.job_id = j.id AND e.type = 'started') AS started_at,
       (SELECT max(e.at) FROM procrastinate_events e
         WHERE e.job_id = j.id AND e.type IN ('succeeded', 'failed', 'cancelled', 'aborted')) AS finished_at,
       p.log, p.result, p.error
  FROM procrastinate_jobs j LEFT JOIN modb_jobs.progress p ON p.job_id = j.id;
COMMENT ON VIEW modb.jobs IS
    'Every job: kind, queue, state (queued, running, done, failed, cancelled), who submitted it, its arguments, attempts, progress (done of total unit), times, log lines, result or error';

GRANT USAGE ON SCHEMA modb_jobs TO modb_reader;
GRANT SELECT ON modb.jobs TO modb_reader;
GRANT SELECT, INSERT, UPDATE, DELETE ON modb_jobs.progress TO modb_loader;
-- Workers and submitters connect as modb_loader (client/modb/jobs/engine.py): the engine's tables and
-- sequences are theirs to use.
GRANT SELECT, INSERT, UPDATE, DELETE
    ON procrastinate_jobs, procrastinate_workers, procrastinate_events, procrastinate_periodic_defers TO modb_loader;
DO $$
DECLARE s regclass;
BEGIN
    FOR s IN SELECT oid FROM pg_class WHERE relkind = 'S' AND relname LIKE 'procrastinate%' LOOP
        EXECUTE format('GRANT USAGE ON SEQUENCE %s TO modb_loader', s);
    END LOOP;
END
$$;
