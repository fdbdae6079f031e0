"""Submitting a job and waiting for it: the job row first (who, what), then either a worker runs it
(when one is alive) or, with none, this process does, said once; either way `modb jobs` lists it."""

from __future__ import annotations

import os
import socket
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import psycopg
from psycopg.types.json import Jsonb

from .connection import LOADER_ROLE
from .tasks import QUEUES
from .worker import STALLED_AFTER_S, run_one

FINISHED = ("done", "failed", "cancelled")
# Jobs that must not run at once (the engine runs one job of a lock at a time): builds of one graph.
LOCKS = {"build_graph": lambda arguments: f"graph {arguments['name']}"}
ENDED_BADLY = {"failed": "failed", "cancelled": "was cancelled", "aborted": "was cancelled"}
POLL_S = 0.5


@dataclass(frozen=True)
class JobState:
    id: int
    kind: str
    state: str
    done: int | None
    total: int | None
    unit: str | None
    log: list[str]
    result: dict | None
    error: str | None


class NotALoader(PermissionError):
    pass


class TooManyQueued(RuntimeError):
    """The submitter's cap on queued jobs is reached."""


class CannotWait(ValueError):
    """A job to wait for does not exist, or ended without being done."""


MAX_QUEUED = 20  # queued (not yet running) jobs one submitter may have: one cannot flood the queue


def submitter(conn: psycopg.Connection) -> str:
    """Who submits (the login role), when it may: a member of the loader role."""
    who, loader = conn.execute(
        "SELECT session_user, pg_has_role(session_user, %s, 'USAGE')", [LOADER_ROLE]
    ).fetchone()
    if not loader:
        raise NotALoader(
            f"{who} may list and read jobs but not submit, cancel or retry them: that needs the "
            f"{LOADER_ROLE} role (GRANT {LOADER_ROLE} TO {who})"
        )
    return who


def _still_to_run(conn: psycopg.Connection, after: list[int]) -> list[int]:
    """Of the jobs to wait for, those not done yet; their rows held until the submit commits, so
    none ends unseen by the trigger that releases the jobs waiting for it."""
    from .schema import OLD_TABLES, current

    if not current(conn):
        raise CannotWait(OLD_TABLES)
    rows = dict(
        conn.execute(
            "SELECT id, status::text FROM procrastinate_jobs WHERE id = ANY (%s) FOR SHARE",
            [after],
        ).fetchall()
    )
    missing = sorted(set(after) - set(rows))
    if missing:
        raise CannotWait(f"no job {missing[0]} to wait for (`modb jobs list` lists them)")
    for job_id, status in sorted(rows.items()):
        if status in ENDED_BADLY:
            raise CannotWait(
                f"job {job_id} {ENDED_BADLY[status]}, so a job waiting for it would never run: "
                f"retry it first (`modb jobs retry {job_id}`)"
            )
    return sorted(job_id for job_id, status in rows.items() if status != "succeeded")


def submit(
    conn: psycopg.Connection,
    kind: str,
    who: str,
    queue: str | None = None,
    after: list[int] | None = None,
    **arguments: Any,
) -> int:
    """Queues a job of `kind` (a modb task: build_graph, retarget, ...) for `who` (see submitter)
    in the connection's transaction, through the engine's own SQL function, on its kind's queue
    unless `queue` names another, to run once the jobs `after` are done; returns its id. Refused
    (TooManyQueued) when `who` has MAX_QUEUED jobs waiting already, (CannotWait) when a job of
    `after` does not exist or failed."""
    with conn.transaction():
        # one submitter's submits queue here, so two at once cannot both pass the count
        conn.execute("SELECT pg_advisory_xact_lock(hashtext('modb jobs of'), hashtext(%s))", [who])
        waiting = conn.execute(
            "SELECT count(*) FROM procrastinate_jobs "
            "WHERE status = 'todo' AND args->>'submitter' = %s",
            [who],
        ).fetchone()[0]
        if waiting >= MAX_QUEUED:
            raise TooManyQueued(
                f"{who} has {waiting} jobs waiting already (at most {MAX_QUEUED}): wait for them, "
                "or cancel some (`modb jobs list`, `modb jobs cancel ID`)"
            )
        waits = _still_to_run(conn, after) if after else []
        job_id = conn.execute(
            "SELECT (procrastinate_defer_jobs_v1(ARRAY["
            "ROW(%s, %s, 0, %s, NULL, %s, %s::timestamptz)"
            "::procrastinate_job_to_defer_v1]))[1]",
            [
                queue or QUEUES[kind],
                f"modb.{kind}",
                LOCKS[kind](arguments) if kind in LOCKS else None,
                Jsonb({"submitter": who, **arguments}),
                "infinity" if waits else None,  # never fetched until released (job_tables.sql)
            ],  # fmt: skip
        ).fetchone()[0]
        if waits:
            conn.execute(
                "INSERT INTO modb_jobs.waits (job_id, after_id) SELECT %s, unnest(%s::bigint[])",
                [job_id, waits],
            )
        return job_id


def cancel(conn: psycopg.Connection, job_id: int) -> bool:
    """A queued job cancelled, a running one asked to stop at its next step; False when it had
    already ended."""
    return (
        conn.execute("SELECT procrastinate_cancel_job_v1(%s, true, false)", [job_id]).fetchone()[0]
        is not None
    )


def retry(conn: psycopg.Connection, job: dict, who: str) -> int:
    """A failed job queued again (its id), or a cancelled one as a new job (the new id); so too a
    failed job whose cancel was asked (the engine keeps it marked)."""
    if job["state"] == "failed" and not job["cancel_requested"]:
        conn.execute("SELECT procrastinate_retry_job_v2(%s, now(), NULL, NULL, NULL)", [job["id"]])
        return job["id"]
    return submit(
        conn, job["kind"].removeprefix("modb."), who, after=job.get("waits_for"), **job["arguments"]
    )


def workers_alive(conn: psycopg.Connection, within_s: float = STALLED_AFTER_S) -> int:
    return conn.execute(
        "SELECT count(*) FROM procrastinate_workers "
        "WHERE last_heartbeat > now() - make_interval(secs => %s)",
        [within_s],
    ).fetchone()[0]


def job_document(conn: psycopg.Connection, job_id: int) -> dict[str, Any] | None:
    """Everything modb.jobs says of the job, as `modb jobs show` and GET /api/jobs/ID give it."""
    row = conn.execute("SELECT to_jsonb(j) FROM modb.jobs j WHERE id = %s", [job_id]).fetchone()
    return row[0] if row else None


def job_state(conn: psycopg.Connection, job_id: int) -> JobState | None:
    row = conn.execute(
        "SELECT id, kind, state, done, total, unit, coalesce(log, '{}'), result, error "
        "FROM modb.jobs WHERE id = %s",
        [job_id],
    ).fetchone()
    return JobState(*row) if row else None


def run_and_wait(
    conn: psycopg.Connection,
    conninfo: str,
    kind: str,
    who: str,
    shown: Callable[[JobState], None],
    quiet: bool = False,
    **arguments: Any,
) -> JobState:
    """Submits a job and waits until it ends: run by a worker when one is alive, else in this
    process (said once, unless quiet), on a queue of its own so that this process runs this job
    only. `shown` gets each state seen (a progress bar, log lines)."""
    runner, queue = None, None
    if not workers_alive(conn):
        queue = f"{QUEUES[kind]}.{socket.gethostname()}.{os.getpid()}"[:128]  # the column's width
    job_id = submit(conn, kind, who, queue, **arguments)

    def run_here(on: str, why: str) -> threading.Thread:
        if not quiet:
            print(f"modb: job {job_id}: {why}; running it in this process", file=sys.stderr)
        thread = threading.Thread(
            target=run_one, args=(conninfo, [on], STALLED_AFTER_S, False), daemon=True
        )
        thread.start()
        return thread

    if queue is not None:
        runner = run_here(queue, "no worker is running (`modb worker` starts one)")
    try:
        while True:
            state = job_state(conn, job_id)
            shown(state)
            if state.state in FINISHED:
                if runner is not None:
                    runner.join()
                return state
            if runner is None and state.state == "queued" and not workers_alive(conn):
                # the workers stopped since: their queue's jobs, this one among them, run here
                runner = run_here(QUEUES[kind], "the workers stopped")
            time.sleep(POLL_S)
    except KeyboardInterrupt:
        cancel(conn, job_id)
        print(f"modb: job {job_id} cancelled (nothing half-made is kept)", file=sys.stderr)
        raise
