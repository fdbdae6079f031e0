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

from procrastinate.worker import Worker

from .engine import job_app

log = logging.getLogger("modb.worker")
STALLED_AFTER_S = 30.0  # a worker silent this long has stopped: its running jobs are queued again


async def _retry_stalled(app, me: Worker, stalled_after: float) -> None:
    while True:
        await asyncio.sleep(max(1.0, stalled_after / 3))
        for job in await app.job_manager.get_stalled_jobs(seconds_since_heartbeat=stalled_after):
            if job.worker_id == me.worker_id:  # this worker is alive, however late its heartbeat
                continue
            log.warning("job %s: its worker stopped answering; queued again", job.id)
            await app.job_manager.retry_job(job)


def run_one(
    conninfo: str, queues: list[str] | None, stalled_after: float, wait: bool = True
) -> None:
    """One worker in this process (returns when stopped, or with wait=False when no job is left)."""
    app = job_app(conninfo)

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
            retrying = asyncio.create_task(_retry_stalled(app, me, stalled_after))
            try:
                await me.run()
            finally:
                retrying.cancel()

    asyncio.run(main())


def run(conninfo: str, concurrency: int, queues: list[str] | None, stalled_after: float) -> int:
    """--concurrency N: N processes of run_one, stopped together by SIGINT or SIGTERM."""
    if concurrency == 1:
        run_one(conninfo, queues, stalled_after)
        return 0
    context = multiprocessing.get_context("spawn")  # no inherited connections or threads
    children = [
        context.Process(target=run_one, args=(conninfo, queues, stalled_after), daemon=False)
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
