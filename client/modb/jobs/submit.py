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

from .connection import LOADER_ROLE, WORKER_ROLE
from .tasks import QUEUES
from .worker import STALLED_AFTER_S, run_one

FINISHED = ("done", "failed", "cancelled")
# Jobs that must not run at once (the engine runs one job of a lock at a time): builds of one graph.
LOCKS = {"build_graph": lambda arguments: f"graph {arguments['name']}"}
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


class NoWorker(RuntimeError):
    """No worker is running and this login may not run a job itself: the job waits."""


class CannotWait(ValueError):
    """A job to wait for does not exist, or ended without being done."""


MAX_QUEUED = 20  # queued jobs one submitter may have (modb_jobs.submit's max_queued)


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


# The job functions' own refusals (job_tables.sql), raised as these
REFUSALS = {"MJ001": TooManyQueued, "MJ002": CannotWait}


def _refusals_in_words(call: Callable[[], Any]) -> Any:
    try:
        return call()
    except psycopg.errors.InsufficientPrivilege as e:
        raise NotALoader(e.diag.message_primary) from None
    except psycopg.Error as e:
        if e.sqlstate in REFUSALS:
            raise REFUSALS[e.sqlstate](e.diag.message_primary) from None
        raise


def submit(
    conn: psycopg.Connection,
    kind: str,
    who: str | None = None,
    queue: str | None = None,
    after: list[int] | None = None,
    **arguments: Any,
) -> int:
    """Queues a job of `kind` (a modb task: build_graph, retarget, ...) through the job tables'
    modb_jobs.submit, in the connection's transaction, on its kind's queue unless `queue` names
    another, to run once the jobs `after` are done; returns its id. The database takes the
    submitter from the session: `who` is a web token's name, which counts only for a web server's
    writer (modb_web). Refused (TooManyQueued) when the submitter has 20 jobs waiting already,
    (CannotWait) when a job of `after` does not exist or failed, (NotALoader)."""
    from .schema import OLD_TABLES, current

    if not current(conn):
        raise CannotWait(OLD_TABLES)
    with conn.transaction():
        return _refusals_in_words(lambda: conn.execute(
            "SELECT modb_jobs.submit(%s, %s, %s, %s, %s, %s)",
            [kind, queue or QUEUES[kind], LOCKS[kind](arguments) if kind in LOCKS else None,
             Jsonb(arguments), after or [], who],
        ).fetchone()[0])  # fmt: skip


def cancel(conn: psycopg.Connection, job_id: int) -> bool:
    """A queued job cancelled, a running one asked to stop at its next step; False when it had
    already ended."""
    return _refusals_in_words(
        lambda: conn.execute("SELECT modb_jobs.cancel(%s)", [job_id]).fetchone()[0]
    )


def retry(conn: psycopg.Connection, job: dict, who: str | None = None) -> int:
    """A failed job queued again (its id), or a cancelled one as a new job of this session's
    submitter (the new id, `who` as in submit); so too a failed job whose cancel was asked."""
    return _refusals_in_words(
        lambda: conn.execute("SELECT modb_jobs.retry(%s, %s)", [job["id"], who]).fetchone()[0]
    )


def may_run_jobs(conn: psycopg.Connection) -> bool:
    """Whether this login may run a job itself (connect as the worker role)."""
    return conn.execute(
        "SELECT pg_has_role(session_user, %s, 'MEMBER')", [WORKER_ROLE]
    ).fetchone()[0]


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
    only; a login that may not run jobs (not in modb_worker) is refused that (NoWorker, the job
    left queued for a worker). `shown` gets each state seen (a progress bar, log lines)."""
    runner, queue = None, None
    if not workers_alive(conn):
        if not may_run_jobs(conn):
            job_id = submit(conn, kind, who, **arguments)
            raise NoWorker(
                f"job {job_id} is queued, and no worker is running: `modb worker` (as a member of "
                f"{WORKER_ROLE}) runs it; this login is not one, so it may not run it here"
            )
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
