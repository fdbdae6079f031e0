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

-- Who may do what (docs/roles.md): a reader lists jobs (modb.jobs); a loader submits, cancels and retries
-- them through the functions below, which take the submitter from the session, and holds no DML on the
-- engine's tables or modb's job tables; a worker (modb_worker, a member of modb_loader: it writes what jobs
-- make) runs them and writes both.
DO $$
BEGIN
    IF NOT EXISTS (SELECT FROM pg_catalog.pg_roles WHERE rolname = 'modb_worker') THEN
        CREATE ROLE modb_worker NOLOGIN;
        COMMENT ON ROLE modb_worker IS 'MoDB: run jobs (modb worker): the job tables, and what jobs make as modb_loader';
    END IF;
    IF NOT pg_catalog.pg_has_role('modb_worker', 'modb_loader', 'MEMBER') THEN
        GRANT modb_loader TO modb_worker;
    END IF;
END
$$;

-- Which worker process runs a job's current attempt (its connections' modb_jobs.runner): a worker that lost
-- the job (its heartbeats stopped, the job queued again and taken by another) may not report over the
-- newer attempt.
ALTER TABLE modb_jobs.progress ADD COLUMN IF NOT EXISTS runner text;
COMMENT ON COLUMN modb_jobs.progress.runner IS 'The worker process running the current attempt (host:pid), as its connections set modb_jobs.runner';

CREATE OR REPLACE FUNCTION modb_jobs.keep_the_newest_attempt()
RETURNS trigger
LANGUAGE plpgsql
AS $$
DECLARE
    mine text := nullif(current_setting('modb_jobs.runner', true), '');
    running text;
BEGIN
    IF mine IS NULL THEN  -- a user's cancel or retry, the engine's housekeeping: not a report
        RETURN NEW;
    END IF;
    SELECT p.runner INTO running FROM modb_jobs.progress p WHERE p.job_id = OLD.id;
    IF running IS NOT NULL AND running <> mine THEN
        RAISE WARNING 'job %: % ended an attempt that % has taken over since: its report is not kept', OLD.id, mine, running;
        RETURN NULL;
    END IF;
    RETURN NEW;
END
$$;
COMMENT ON FUNCTION modb_jobs.keep_the_newest_attempt() IS
    'Trigger: a job''s end reported by a worker process other than the one running its newest attempt is not kept';
CREATE OR REPLACE TRIGGER modb_keep_the_newest_attempt
    BEFORE UPDATE OF status ON procrastinate_jobs FOR EACH ROW
    WHEN (OLD.status = 'doing' AND NEW.status IN ('succeeded', 'failed', 'aborted'))
    EXECUTE FUNCTION modb_jobs.keep_the_newest_attempt();

CREATE OR REPLACE FUNCTION modb_jobs.refuse_circular_waits()
RETURNS trigger
LANGUAGE plpgsql
AS $$
BEGIN
    IF EXISTS (WITH RECURSIVE ahead(id) AS (
                   SELECT NEW.after_id
                   UNION
                   SELECT w.after_id FROM modb_jobs.waits w JOIN ahead a ON w.job_id = a.id)
               SELECT FROM ahead WHERE id = NEW.job_id) THEN
        RAISE EXCEPTION 'job % cannot wait for job %: that one waits for it, so neither would ever run', NEW.job_id, NEW.after_id
            USING ERRCODE = 'check_violation';
    END IF;
    RETURN NEW;
END
$$;
COMMENT ON FUNCTION modb_jobs.refuse_circular_waits() IS 'Trigger: a job never waits, however indirectly, for itself';
CREATE OR REPLACE TRIGGER modb_refuse_circular_waits BEFORE INSERT OR UPDATE ON modb_jobs.waits
    FOR EACH ROW EXECUTE FUNCTION modb_jobs.refuse_circular_waits();

CREATE OR REPLACE FUNCTION modb_jobs.check_loader()
RETURNS void
LANGUAGE plpgsql STABLE
AS $$
BEGIN
    IF NOT pg_catalog.pg_has_role(session_user, 'modb_loader', 'USAGE') THEN
        RAISE EXCEPTION '% may list and read jobs but not submit, cancel or retry them: that needs the modb_loader role',
                        session_user
            USING ERRCODE = 'insufficient_privilege', HINT = format('GRANT modb_loader TO %I', session_user);
    END IF;
END
$$;
COMMENT ON FUNCTION modb_jobs.check_loader() IS 'Refuses, saying why, a session whose login is not in modb_loader';

-- SECURITY DEFINER (PL/pgSQL, a fixed search_path): these write the engine's tables for a loader, with
-- the submitter taken from the session. A web server's writer (a member of modb_web) may name the token
-- a job is submitted for: that token is then its submitter.
CREATE OR REPLACE FUNCTION modb_jobs.submit(kind text, queue text, lock text, arguments jsonb,
                                            after bigint[] DEFAULT '{}', token text DEFAULT NULL)
RETURNS bigint
LANGUAGE plpgsql VOLATILE SECURITY DEFINER SET search_path = pg_catalog, public, pg_temp
AS $$
DECLARE
    max_queued constant int := 20;
    who text := session_user;
    waiting bigint;
    missing bigint;
    ended record;
    pending bigint[];
    job bigint;
BEGIN
    PERFORM modb_jobs.check_loader();
    IF token IS NOT NULL AND EXISTS (SELECT FROM pg_roles WHERE rolname = 'modb_web')
       AND pg_has_role(session_user, 'modb_web', 'MEMBER') THEN
        who := token;
    END IF;
    -- one submitter's submits queue here, so two at once cannot both pass the count
    PERFORM pg_advisory_xact_lock(hashtext('modb jobs of'), hashtext(who));
    SELECT count(*) INTO waiting FROM procrastinate_jobs j WHERE j.status = 'todo' AND j.args->>'submitter' = who;
    IF waiting >= max_queued THEN
        RAISE EXCEPTION '% has % jobs waiting already (at most %): wait for them, or cancel some (`modb jobs list`, `modb jobs cancel ID`)',
                        who, waiting, max_queued USING ERRCODE = 'MJ001';
    END IF;
    SELECT a INTO missing FROM unnest(coalesce(after, '{}')) a
     WHERE NOT EXISTS (SELECT FROM procrastinate_jobs j WHERE j.id = a) ORDER BY a LIMIT 1;
    IF missing IS NOT NULL THEN
        RAISE EXCEPTION 'no job % to wait for (`modb jobs list` lists them)', missing USING ERRCODE = 'MJ002';
    END IF;
    -- the rows held until this commits, so none ends unseen by the trigger that releases its waiters
    pending := ARRAY(SELECT j.id FROM procrastinate_jobs j WHERE j.id = ANY (coalesce(after, '{}'))
                      ORDER BY j.id FOR SHARE);
    SELECT j.id, j.status INTO ended FROM procrastinate_jobs j
     WHERE j.id = ANY (pending) AND j.status IN ('failed', 'cancelled', 'aborted') ORDER BY j.id LIMIT 1;
    IF FOUND THEN
        RAISE EXCEPTION 'job % %, so a job waiting for it would never run: retry it first (`modb jobs retry %`)',
                        ended.id, CASE ended.status WHEN 'failed' THEN 'failed' ELSE 'was cancelled' END, ended.id
            USING ERRCODE = 'MJ002';
    END IF;
    pending := ARRAY(SELECT j.id FROM procrastinate_jobs j WHERE j.id = ANY (pending) AND j.status <> 'succeeded'
                      ORDER BY j.id);
    job := (procrastinate_defer_jobs_v1(ARRAY[ROW(
        queue, 'modb.' || kind, 0, lock, NULL,
        (arguments - 'submitter') || jsonb_build_object('submitter', who),
        CASE WHEN cardinality(pending) > 0 THEN 'infinity'::timestamptz END  -- never fetched until released
    )::procrastinate_job_to_defer_v1]))[1];
    INSERT INTO modb_jobs.waits (job_id, after_id) SELECT job, unnest(pending);
    RETURN job;
END
$$;
COMMENT ON FUNCTION modb_jobs.submit(text, text, text, jsonb, bigint[], text) IS
    'Queues a job of kind (modb.KIND) on queue for the session''s login (or the web token given by a modb_web writer), to run once the jobs after are done; refused past 20 queued jobs of one submitter, or when a job to wait for does not exist or ended badly. Returns its id';

CREATE OR REPLACE FUNCTION modb_jobs.cancel(job_id bigint)
RETURNS boolean
LANGUAGE plpgsql VOLATILE SECURITY DEFINER SET search_path = pg_catalog, public, pg_temp
AS $$
BEGIN
    PERFORM modb_jobs.check_loader();
    RETURN procrastinate_cancel_job_v1(job_id, true, false) IS NOT NULL;
END
$$;
COMMENT ON FUNCTION modb_jobs.cancel(bigint) IS
    'A queued job cancelled, a running one asked to stop at its next step; false when it had already ended';

CREATE OR REPLACE FUNCTION modb_jobs.retry(job_id bigint, token text DEFAULT NULL)
RETURNS bigint
LANGUAGE plpgsql VOLATILE SECURITY DEFINER SET search_path = pg_catalog, public, pg_temp
AS $$
DECLARE
    j record;
BEGIN
    PERFORM modb_jobs.check_loader();
    SELECT * INTO j FROM procrastinate_jobs p WHERE p.id = retry.job_id FOR UPDATE;
    IF NOT FOUND THEN
        RAISE EXCEPTION 'no job %', job_id USING ERRCODE = 'no_data_found';
    END IF;
    IF j.status = 'failed' AND NOT j.abort_requested THEN
        PERFORM procrastinate_retry_job_v2(j.id, now(), NULL, NULL, NULL);
        RETURN j.id;
    END IF;
    IF j.status NOT IN ('failed', 'cancelled', 'aborted') THEN
        RAISE EXCEPTION 'job % is %: a failed or cancelled job is retried', j.id, j.status USING ERRCODE = 'MJ003';
    END IF;
    -- cancelled (or failed with its cancel asked): the same work as a new job of this session's
    RETURN modb_jobs.submit(substr(j.task_name, 6), j.queue_name, j.lock, j.args,
                            ARRAY(SELECT w.after_id FROM modb_jobs.waits w WHERE w.job_id = j.id ORDER BY 1), token);
END
$$;
COMMENT ON FUNCTION modb_jobs.retry(bigint, text) IS
    'A failed job queued again (its id), or a cancelled one as a new job of the session''s submitter (the new id)';

REVOKE ALL ON FUNCTION modb_jobs.submit(text, text, text, jsonb, bigint[], text), modb_jobs.cancel(bigint),
                       modb_jobs.retry(bigint, text) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb_jobs.submit(text, text, text, jsonb, bigint[], text), modb_jobs.cancel(bigint),
                          modb_jobs.retry(bigint, text) TO modb_loader;

GRANT USAGE ON SCHEMA modb_jobs TO modb_reader;
GRANT SELECT ON modb.jobs TO modb_reader;
-- Loaders held DML on the job tables before (modb 0.25.0 and older): taken back.
REVOKE INSERT, UPDATE, DELETE, TRUNCATE ON modb_jobs.progress, modb_jobs.waits FROM modb_loader;
REVOKE INSERT, UPDATE, DELETE, TRUNCATE
    ON procrastinate_jobs, procrastinate_workers, procrastinate_events, procrastinate_periodic_defers FROM modb_loader;
GRANT SELECT ON modb_jobs.progress, modb_jobs.waits TO modb_loader;
GRANT SELECT ON procrastinate_jobs, procrastinate_workers, procrastinate_events, procrastinate_periodic_defers TO modb_loader;
GRANT SELECT, INSERT, UPDATE, DELETE ON modb_jobs.progress TO modb_worker;
GRANT SELECT, DELETE ON modb_jobs.waits TO modb_worker;
GRANT SELECT, INSERT, UPDATE, DELETE
    ON procrastinate_jobs, procrastinate_workers, procrastinate_events, procrastinate_periodic_defers TO modb_worker;
DO $$
DECLARE s regclass;
BEGIN
    FOR s IN SELECT oid FROM pg_class WHERE relkind = 'S' AND relname LIKE 'procrastinate%' LOOP
        EXECUTE format('REVOKE USAGE ON SEQUENCE %s FROM modb_loader', s);
        EXECUTE format('GRANT USAGE ON SEQUENCE %s TO modb_worker', s);
    END LOOP;
END
$$;
