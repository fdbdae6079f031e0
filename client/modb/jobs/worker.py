"""`modb worker`: processes that take jobs from the database and run them here. One job at a time
per process (the work is numpy on one core): --concurrency N starts N processes. Each also queues
again the jobs of workers whose heartbeats stopped (killed, or their machine gone) for
`stalled_after` seconds."""

from __future__ import annotations

import asyncio
import logging
import multiprocessing
import os
import signal
import time

from procrastinate.worker import Worker

from .connection import as_loader
from .engine import job_app

log = logging.getLogger("modb.worker")
STALLED_AFTER_S = 30.0  # a worker silent this long has stopped: its running jobs are queued again
KEEP_DAYS = 30.0  # finished jobs are deleted after this long
PRUNE_EVERY_S = 3600.0


# A stalled job queued again only if it is still the silent worker's: one statement with the row
# locked, so two workers seeing the same stalled job (or a worker that fetched it meanwhile) never
# make it run twice.
REQUEUE = """
SELECT procrastinate_retry_job_v2(j.id, now(), NULL, NULL, NULL)
  FROM (SELECT id FROM procrastinate_jobs
         WHERE id = %(id)s AND status = 'doing' AND worker_id IS NOT DISTINCT FROM %(worker)s
           FOR UPDATE) j
"""


async def _housekeeping(app, me: Worker, stalled_after: float, keep_days: float) -> None:
    """Jobs of silent workers queued again; finished jobs deleted after keep_days, in whole hours
    (with their progress and log). A failed pass is logged and the next one runs."""
    pruned = None
    while True:
        await asyncio.sleep(max(1.0, stalled_after / 3))
        try:
            stalled = await app.job_manager.get_stalled_jobs(seconds_since_heartbeat=stalled_after)
            for job in stalled:
                if job.worker_id == me.worker_id:  # this worker is alive, however late its beat
                    continue
                await app.connector.execute_query_async(
                    query=REQUEUE, id=job.id, worker=job.worker_id
                )
                log.warning("job %s: its worker stopped answering; queued again", job.id)
            if pruned is None or time.monotonic() - pruned > PRUNE_EVERY_S:
                pruned = time.monotonic()
                await app.job_manager.delete_old_jobs(
                    nb_hours=int(keep_days * 24), include_failed=True, include_cancelled=True,
                    include_aborted=True,
                )  # fmt: skip
        except Exception:
            log.exception("job housekeeping failed; trying again in %.0f s", stalled_after / 3)


def _unreachable_errors() -> tuple[type[BaseException], ...]:
    """What a database that went away (stopped, restarting, the network down) raises."""
    import psycopg
    from procrastinate.exceptions import ConnectorException
    from psycopg_pool import PoolTimeout

    return (ConnectorException, PoolTimeout, psycopg.OperationalError, OSError)


RECONNECT_FIRST_S = 1.0
RECONNECT_MOST_S = 30.0


def run_one(
    conninfo: str,
    queues: list[str] | None,
    stalled_after: float,
    wait: bool = True,
    keep_days: float = KEEP_DAYS,
) -> None:
    """One worker in this process (returns when stopped, or with wait=False when no job is left).
    A waiting worker outlives the database going away: it says so once, tries again with a
    growing pause (RECONNECT_FIRST_S doubling up to RECONNECT_MOST_S), and says when it works
    again; the jobs it was running are queued again by the others (or itself) as stalled."""
    if not wait:
        _run_worker(conninfo, queues, stalled_after, wait, keep_days)
        return
    _say_an_outage_once()
    pause, down_since = RECONNECT_FIRST_S, None
    while True:
        started = time.monotonic()
        try:
            _run_worker(conninfo, queues, stalled_after, wait, keep_days)
            return  # stopped (a signal)
        except _unreachable_errors() as e:
            if time.monotonic() - started > 2 * RECONNECT_MOST_S:
                pause = RECONNECT_FIRST_S  # it worked a while: a new outage
            if down_since is None:
                down_since = time.monotonic()
                reason = " ".join(str(e).split())[:200] or type(e).__name__
                log.warning("the database is unreachable (%s): trying again, every %.0f s at "
                            "most, until it answers", reason, RECONNECT_MOST_S)  # fmt: skip
        time.sleep(pause)
        pause = min(RECONNECT_MOST_S, pause * 2)
        if _answers(conninfo):
            log.warning("the database answers again after %.0f s: taking jobs",
                        time.monotonic() - down_since)  # fmt: skip
            down_since, pause = None, RECONNECT_FIRST_S


class _OutageOnce(logging.Filter):
    """Drops what the engine and the connection pool log of a database gone away (a traceback
    of each failed wait, a line per failed connection): the worker says it once, itself."""

    def filter(self, record: logging.LogRecord) -> bool:
        if record.name.startswith("psycopg.pool") and record.levelno < logging.ERROR:
            return False
        error = record.exc_info[1] if record.exc_info else None
        return not isinstance(error, _unreachable_errors())


def _say_an_outage_once() -> None:
    """This process's log: messages on stderr (as Python prints them by default), an outage's
    noise left out."""
    handler = logging.StreamHandler()
    handler.setFormatter(logging.Formatter("%(message)s"))
    handler.addFilter(_OutageOnce())
    root = logging.getLogger()
    if not root.handlers:
        root.addHandler(handler)
        root.setLevel(logging.WARNING)


def _answers(conninfo: str) -> bool:
    import psycopg

    try:
        with psycopg.connect(as_loader(conninfo), connect_timeout=5) as conn:
            conn.execute("SELECT 1")
        return True
    except psycopg.Error:
        return False


def _run_worker(conninfo: str, queues: list[str] | None, stalled_after: float, wait: bool,
                keep_days: float) -> None:  # fmt: skip
    app = job_app(conninfo)
    if not wait:  # a command running its own job says how it ended, in words: not the engine's log
        logging.getLogger("procrastinate").setLevel(logging.CRITICAL)

    async def main() -> None:
        async with app.open_async():
            me = Worker(
                app,
                queues=queues,
                wait=wait,
                concurrency=1,
                name=f"modb worker {os.uname().nodename}:{os.getpid()}",
                additional_context={"conninfo": conninfo},
                update_heartbeat_interval=max(0.5, stalled_after / 6),
                stalled_worker_timeout=stalled_after,
                abort_job_polling_interval=1.0,  # a cancel reaches a running job within 1 s
                install_signal_handlers=wait,
            )
            # A command running its own job (wait=False) leaves the others' jobs to the workers.
            chores = wait and asyncio.create_task(_housekeeping(app, me, stalled_after, keep_days))
            try:
                await me.run()
            finally:
                if chores:
                    chores.cancel()

    asyncio.run(main())


def _child(conninfo: str, queues: list[str] | None, stalled_after: float, keep_days: float) -> None:
    # Its own process group: a Ctrl-C or a stop signal reaches it once, from the parent (a second
    # SIGTERM would end it at once, mid-job, where the first lets it finish the job).
    os.setpgrp()
    run_one(conninfo, queues, stalled_after, True, keep_days)


def run(
    conninfo: str,
    concurrency: int,
    queues: list[str] | None,
    stalled_after: float,
    keep_days: float = KEEP_DAYS,
) -> int:
    """--concurrency N: N processes of run_one, stopped together by SIGINT or SIGTERM."""
    if concurrency == 1:
        run_one(conninfo, queues, stalled_after, True, keep_days)
        return 0
    context = multiprocessing.get_context("spawn")  # no inherited connections or threads
    children = [
        context.Process(
            target=_child, args=(conninfo, queues, stalled_after, keep_days), daemon=False
        )
        for _ in range(concurrency)
    ]
    for child in children:
        child.start()

    def stop(signum, frame) -> None:
        for child in children:
            if child.is_alive():
                os.kill(child.pid, signal.SIGTERM)

    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    for child in children:
        child.join()
    return max((child.exitcode or 0) for child in children)
