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

-- A job may wait for others (a graph build for the retargetings it needs): queued with scheduled_at
-- 'infinity', which the engine never fetches, and released by the trigger below when the last of them
-- is done; cancelled, saying why, when one of them fails or is cancelled.
CREATE TABLE IF NOT EXISTS modb_jobs.waits (
    job_id   bigint NOT NULL REFERENCES procrastinate_jobs (id) ON DELETE CASCADE,
    after_id bigint NOT NULL REFERENCES procrastinate_jobs (id) ON DELETE CASCADE,
    PRIMARY KEY (job_id, after_id),
    CHECK (job_id <> after_id)
);
CREATE INDEX IF NOT EXISTS waits_after_idx ON modb_jobs.waits (after_id);
COMMENT ON TABLE modb_jobs.waits IS 'Job job_id runs once job after_id is done';

CREATE OR REPLACE FUNCTION modb_jobs.release_waiting_jobs()
RETURNS trigger
LANGUAGE plpgsql
AS $$
DECLARE
    waiter record;
    payload text;
BEGIN
    FOR waiter IN
        SELECT j.id, j.queue_name FROM modb_jobs.waits w JOIN procrastinate_jobs j ON j.id = w.job_id
         WHERE w.after_id = NEW.id AND j.status = 'todo' ORDER BY j.id FOR UPDATE OF j
    LOOP
        IF NEW.status <> 'succeeded' THEN
            INSERT INTO modb_jobs.progress (job_id, error)
            VALUES (waiter.id, format('job %s, which this one waited for, %s: nothing was run', NEW.id,
                                      CASE NEW.status WHEN 'failed' THEN 'failed' ELSE 'was cancelled' END))
            ON CONFLICT (job_id) DO UPDATE SET error = EXCLUDED.error, updated_at = now();
            PERFORM procrastinate_cancel_job_v1(waiter.id, true, false);  -- its own waiters follow
        ELSIF NOT EXISTS (SELECT FROM modb_jobs.waits w JOIN procrastinate_jobs j ON j.id = w.after_id
                           WHERE w.job_id = waiter.id AND j.status <> 'succeeded') THEN
            UPDATE procrastinate_jobs SET scheduled_at = now() WHERE id = waiter.id;
            payload := json_build_object('type', 'job_inserted', 'job_id', waiter.id)::text;  -- as the engine's own
            PERFORM pg_notify('procrastinate_queue_v1#' || waiter.queue_name, payload);
            PERFORM pg_notify('procrastinate_any_queue_v1', payload);
        END IF;
    END LOOP;
    RETURN NULL;
END
$$;
COMMENT ON FUNCTION modb_jobs.release_waiting_jobs() IS
    'Trigger: when a job ends, the jobs waiting for it run (once nothing else holds them) or are cancelled (when it failed or was cancelled)';
CREATE OR REPLACE TRIGGER modb_release_waiting_jobs
    AFTER UPDATE OF status ON procrastinate_jobs FOR EACH ROW
    WHEN (OLD.status IS DISTINCT FROM NEW.status AND NEW.status IN ('succeeded', 'failed', 'cancelled', 'aborted'))
    EXECUTE FUNCTION modb_jobs.release_waiting_jobs();

CREATE OR REPLACE VIEW modb.jobs AS
SELECT j.id, j.task_name AS kind, j.queue_name AS queue,
       CASE j.status WHEN 'todo' THEN CASE WHEN j.scheduled_at = 'infinity' THEN 'waiting' ELSE 'queued' END
                     WHEN 'doing' THEN 'running' WHEN 'succeeded' THEN 'done'
                     WHEN 'failed' THEN 'failed' ELSE 'cancelled' END AS state,
       j.abort_requested AS cancel_requested, j.args->>'submitter' AS submitter,
       j.args - 'submitter' AS arguments, j.attempts, p.done, p.total, p.unit,
       (SELECT min(e.at) FROM procrastinate_events e WHERE e.job_id = j.id AND e.type = 'deferred') AS queued_at,
       (SELECT max(e.at) FROM procrastinate_events e WHERE e.job_id = j.id AND e.type = 'started') AS started_at,
       (SELECT max(e.at) FROM procrastinate_events e
         WHERE e.job_id = j.id AND e.type IN ('succeeded', 'failed', 'cancelled', 'aborted')) AS finished_at,
       p.log, p.result, p.error,
       (SELECT array_agg(w.after_id ORDER BY w.after_id) FROM modb_jobs.waits w WHERE w.job_id = j.id) AS waits_for
  FROM procrastinate_jobs j LEFT JOIN modb_jobs.progress p ON p.job_id = j.id;
COMMENT ON VIEW modb.jobs IS
    'Every job: kind, queue, state (waiting for other jobs, queued, running, done, failed, cancelled), who submitted it, its arguments, attempts, progress (done of total unit), times, log lines, result or error, and the jobs it waits for';

GRANT USAGE ON SCHEMA modb_jobs TO modb_reader;
GRANT SELECT ON modb.jobs TO modb_reader;
GRANT SELECT, INSERT, UPDATE, DELETE ON modb_jobs.progress TO modb_loader;
GRANT SELECT, INSERT, DELETE ON modb_jobs.waits TO modb_loader;
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
