"""modb's job kinds, each run in the worker's process: it reads the inputs, computes with the
kernel and numpy here, and writes each item in one transaction (a retry after a killed worker
replaces or finds it, never doubles it). Progress, log lines and the result: modb_jobs.progress."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import procrastinate
import psycopg
from procrastinate.exceptions import JobAborted

from modb.database.connection import connect
from modb.web import database_errors

from . import clip_jobs
from .connection import as_loader, as_worker
from .graph_build import build_here
from .progress import JobProgress

# A queue per kind: a long graph build does not hold back a retargeting.
QUEUES = {
    "build_graph": "graphs",
    "retarget": "clips",
    "apply_edit_script": "clips",
    "split_by_annotation": "clips",
    "annotate_steps": "clips",
    "annotate_action": "clips",
    "align": "primitives",
    "build_model": "primitives",
    "build_family": "primitives",
}

Work = Callable[..., dict[str, Any]]


def _run(context: procrastinate.JobContext, what: str, work: Work) -> dict[str, Any]:
    """work(conn, progress, stop_when_asked) in a loader's connection, its progress, log, result or
    error kept with the job; a cancel stops it at its next item (what it finished stays)."""
    conninfo = context.additional_context["conninfo"]
    progress = JobProgress(as_worker(conninfo), context.job.id)
    try:
        progress.log(what)

        def stop_when_asked() -> None:
            if context.should_abort():
                raise JobAborted("cancelled")

        with connect(as_loader(conninfo)) as conn:
            result = work(conn, progress, stop_when_asked)
        progress.finish(result)
        return result
    except JobAborted:
        progress.log("cancelled: what it finished is whole and listed; nothing is half-made")
        raise
    except Exception as e:
        progress.fail(_in_words(e))
        raise
    finally:
        progress.close()


def _in_words(e: Exception) -> str:
    """What went wrong as a user reads it: a database error's message and hint, without its
    CONTEXT lines (where in PL/pgSQL it was raised) or the driver's prefixes."""
    if isinstance(e, psycopg.Error) and e.diag.message_primary:
        return database_errors.message(e)
    return str(e)


def build_graph(
    context,
    submitter: str,
    name: str,
    profile: str = "default",
    collection: str | None = None,
    min_turn_degrees: float = 45.0,
) -> dict[str, Any]:
    def work(conn, progress, stop_when_asked):
        def advance(done: int, total: int) -> None:
            stop_when_asked()
            progress.advance(done, total, "snippets")

        def notice(text: str) -> None:
            stop_when_asked()
            progress.log(text)

        graph_id = build_here(
            conn, name, profile, collection, min_turn_degrees, notice=notice, advance=advance
        )
        return {"graph_id": graph_id, "graph": name}

    return _run(
        context,
        f"building transition graph {name!r} (profile {profile}, collection "
        f"{collection or 'all'}) for {submitter}",
        work,
    )


def retarget(
    context,
    submitter: str,
    clips: list[int],
    skeleton: int,
    collection: str | None = None,
    fps: float | None = None,
    mirrored: bool = False,
) -> dict[str, Any]:
    def work(conn, progress, stop_when_asked):
        made = clip_jobs.retarget(
            conn, progress, clips, stop_when_asked, skeleton, collection, fps, mirrored
        )
        return {"clips": made}

    return _run(
        context, f"retargeting {len(clips)} clips onto skeleton {skeleton} for {submitter}", work
    )


def apply_edit_script(context, submitter: str, script: str, clips: list[int]) -> dict[str, Any]:
    def work(conn, progress, stop_when_asked):
        made = clip_jobs.apply_edit_script(
            conn, progress, clips, stop_when_asked, script, context.job.id
        )
        return {"clips": made}

    return _run(
        context, f"applying edit script {script!r} to {len(clips)} clips for {submitter}", work
    )


def split_by_annotation(
    context,
    submitter: str,
    clips: list[int],
    annotation: str | None = None,
    collection: str | None = None,
) -> dict[str, Any]:
    def work(conn, progress, stop_when_asked):
        made = clip_jobs.split_by_annotation(
            conn, progress, clips, stop_when_asked, annotation, collection
        )
        return {"clips": made}

    return _run(
        context,
        f"splitting {len(clips)} clips by annotation {annotation or '(every one)'} for {submitter}",
        work,
    )


def annotate_steps(context, submitter: str, clips: list[int]) -> dict[str, Any]:
    def work(conn, progress, stop_when_asked):
        return {"clips": clip_jobs.annotate_steps(conn, progress, clips, stop_when_asked)}

    return _run(context, f"finding the steps of {len(clips)} clips for {submitter}", work)


def annotate_action(context, submitter: str, clips: list[int], action: str) -> dict[str, Any]:
    def work(conn, progress, stop_when_asked):
        made = clip_jobs.annotate_action(conn, progress, clips, stop_when_asked, action)
        return {"clips": made, "action": action}

    return _run(context, f"finding the action {action!r} of {len(clips)} clips for {submitter}",
                work)  # fmt: skip


def align(context, submitter: str, primitive: str, collection: str) -> dict[str, Any]:
    def work(conn, progress, stop_when_asked):
        return clip_jobs.align(conn, progress, stop_when_asked, primitive, collection)

    return _run(context, f"aligning {primitive!r} in {collection!r} for {submitter}", work)


def build_model(
    context,
    submitter: str,
    name: str,
    collection: str,
    primitive: str,
    seed: int = 0,
    variance: float = 0.95,
    report: bool = False,
) -> dict[str, Any]:
    from modb.models.pipeline import build_model as build

    def work(conn, progress, stop_when_asked):
        def advance(done: int, total: int) -> None:
            stop_when_asked()
            progress.advance(done, total, "stages")

        return build(conn, name, collection, primitive, seed, variance, report, progress.log,
                     advance, job_id=context.job.id)  # fmt: skip

    return _run(context, f"building model {name!r} of {primitive!r} in {collection!r} for "
                f"{submitter}", work)  # fmt: skip


def build_family(
    context,
    submitter: str,
    name: str,
    collection: str,
    chosen: list[str] | None = None,
    seed: int = 0,
) -> dict[str, Any]:
    from modb.models.family import build_family as build

    def work(conn, progress, stop_when_asked):
        def advance(done: int, total: int) -> None:
            stop_when_asked()
            progress.advance(done, total, "models")

        return build(conn, name, collection, chosen, seed, progress.log, advance,
                     job_id=context.job.id)  # fmt: skip

    return _run(context, f"building the family graph {name!r} of {collection!r} for {submitter}",
                work)  # fmt: skip


KINDS = {
    "build_graph": build_graph,
    "retarget": retarget,
    "apply_edit_script": apply_edit_script,
    "split_by_annotation": split_by_annotation,
    "annotate_steps": annotate_steps,
    "annotate_action": annotate_action,
    "align": align,
    "build_model": build_model,
    "build_family": build_family,
}


def register(app: procrastinate.App) -> None:
    """modb's tasks on the app, named modb.KIND, each on its kind's queue."""
    for kind, function in KINDS.items():
        app.task(name=f"modb.{kind}", queue=QUEUES[kind], pass_context=True)(function)
