"""modb's job kinds, each run in the worker's process: it reads the inputs, computes with the
kernel and numpy here, and writes the result in one transaction (a retry after a killed worker
replaces or finds it, never doubles it). Progress, log lines and the result: modb_jobs.progress."""

from __future__ import annotations

from typing import Any

import procrastinate
from procrastinate.exceptions import JobAborted

from modb.database.connection import connect

from .connection import as_loader
from .graph_build import build_here
from .progress import JobProgress

QUEUES = {"build_graph": "graphs"}  # a queue per kind: a long build does not hold back the others


def _conninfo(context: procrastinate.JobContext) -> str:
    return context.additional_context["conninfo"]


def build_graph(
    context: procrastinate.JobContext,
    submitter: str,
    name: str,
    profile: str = "default",
    collection: str | None = None,
    min_turn_degrees: float = 45.0,
) -> dict[str, Any]:
    conninfo = _conninfo(context)
    job_id = context.job.id
    progress = JobProgress(as_loader(conninfo), job_id)
    try:
        progress.log(f"building transition graph {name!r} (profile {profile}, "
                     f"collection {collection or 'all'}) for {submitter}")  # fmt: skip

        def stop_when_asked() -> None:  # at each step: a cancel stops the job there
            if context.should_abort():
                raise JobAborted("cancelled: nothing stored")

        def advance(done: int, total: int) -> None:
            stop_when_asked()
            progress.advance(done, total, "snippets")

        def notice(text: str) -> None:
            stop_when_asked()
            progress.log(text)

        with connect(as_loader(conninfo)) as conn:
            graph_id = build_here(
                conn, name, profile, collection, min_turn_degrees, notice=notice, advance=advance
            )
        result = {"graph_id": graph_id, "graph": name}
        progress.finish(result)
        return result
    except JobAborted:
        progress.log("cancelled before the graph was stored: nothing was written")
        raise
    except Exception as e:
        progress.fail(str(e))
        raise
    finally:
        progress.close()


KINDS = {"build_graph": build_graph}


def register(app: procrastinate.App) -> None:
    """modb's tasks on the app, named modb.KIND, each on its kind's queue."""
    for kind, function in KINDS.items():
        app.task(name=f"modb.{kind}", queue=QUEUES[kind], pass_context=True)(function)
