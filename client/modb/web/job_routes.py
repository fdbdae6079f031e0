"""The REST interface's jobs: list and read them (a reader may), submit one and cancel one (a loader
token, whose name is the job's submitter; recorded in modb.audit_log in the same transaction as the
job row). A worker (`modb worker`) runs what is submitted; GET /api/jobs/ID follows it."""

from __future__ import annotations

from typing import Any

import psycopg
from starlette.exceptions import HTTPException
from starlette.requests import Request

from modb.jobs import schema
from modb.jobs.submit import (
    CannotWait,
    TooManyQueued,
    cancel,
    job_document,
    submit,
    workers_alive,
)

from .api import NotFound
from .bodies import parse
from .body_models import PATH
from .catalog_writes import Done, _existing, _int, _target_clips
from .catalog_writes import apply_script as apply_script_at_once

MAX_LISTED = 200
# What each kind of job takes, the arguments of its command: body_models.JOB_ARGUMENTS.


def _tables(conn: psycopg.Connection) -> None:
    if not schema.installed(conn):
        raise NotFound(schema.NO_TABLES)


def jobs(conn: psycopg.Connection) -> list[dict[str, Any]]:
    """The newest MAX_LISTED jobs, newest first (modb.jobs); none where there are no job tables."""
    if not schema.installed(conn):
        return []
    rows = conn.execute(
        "SELECT to_jsonb(j) FROM modb.jobs j ORDER BY id DESC LIMIT %s", [MAX_LISTED]
    )
    return [r for (r,) in rows]


def job(conn: psycopg.Connection, job_id: int) -> dict[str, Any]:
    _tables(conn)
    found = job_document(conn, job_id)
    if found is None:
        raise NotFound(f"no job with id {job_id}")
    return found


def _clips(conn: psycopg.Connection, arguments: dict[str, Any]) -> list[int]:
    """The clips the arguments name, by ids or by a collection (one of them: body_models.
    ClipArguments; 404 for one that is not there), taken out of them."""
    named = {k: arguments.pop(k) for k in ("clips", "from_collection") if k in arguments}
    if "clips" in named:
        return _target_clips(conn, {"clips": named["clips"]})
    return _target_clips(conn, {"collection": named["from_collection"]})


def queue_job(
    conn: psycopg.Connection,
    request: Request,
    kind: str,
    arguments: dict[str, Any],
    after: list[int] | None = None,
) -> Done:
    """202 with the queued job (its Location); the token's name is its submitter."""
    _tables(conn)
    if kind == "retarget":
        _existing(conn, "skeleton", arguments["skeleton"])
    if (
        kind == "apply_edit_script"
        and conn.execute(
            "SELECT 1 FROM modb.edit_scripts WHERE name = %s", [arguments["script"]]
        ).fetchone()
        is None
    ):
        raise NotFound(f"no edit script {arguments['script']!r}")
    try:
        job_id = submit(conn, kind, request.state.grant.name, after=after, **arguments)
    except TooManyQueued as e:
        raise HTTPException(429, str(e)) from None
    except CannotWait as e:
        raise HTTPException(409, str(e)) from None
    answer = {**job(conn, job_id), "workers_alive": workers_alive(conn)}  # 0: it waits for one
    return Done(
        answer, "submit job", f"job {job_id}", {"kind": kind, **arguments, "after": after},
        status=202, headers={"Location": f"/api/jobs/{job_id}"},
    )  # fmt: skip


def submit_job(conn: psycopg.Connection, request: Request, body: dict[str, Any]) -> Done:
    """POST /api/jobs: {"kind", "arguments", "after": [job ids] (optional)} (body_models.JOB)."""
    kind, arguments = body["kind"], body["arguments"]
    _tables(conn)
    if kind not in ("build_graph", "align", "build_model"):
        arguments = {"clips": _clips(conn, arguments), **arguments}
    return queue_job(conn, request, kind, arguments, body.get("after"))


def retarget_collection(conn: psycopg.Connection, request: Request, body: dict[str, Any]) -> Done:
    """POST /api/collections/PATH/retarget: every clip of it, as a job (body_models.
    CollectionRetarget)."""
    path = parse(PATH, request.path_params["path"], "collection path")
    arguments = body
    _tables(conn)
    arguments = {"clips": _target_clips(conn, {"collection": path}), **arguments}
    return queue_job(conn, request, "retarget", arguments)


def cancel_job(conn: psycopg.Connection, request: Request, body: Any) -> Done:
    """A queued job cancelled, a running one asked to stop at its next step; 409 when it ended."""
    job_id = _int(request, "ident", "job id")
    before = job(conn, job_id)
    if not cancel(conn, job_id):
        raise HTTPException(
            409, f"job {job_id} is {before['state']}: only a queued or running job stops"
        )
    return Done(job(conn, job_id), "cancel job", f"job {job_id}", {"was": before["state"]})


def steps_collection(conn: psycopg.Connection, request: Request, body: Any) -> Done:
    """POST /api/collections/PATH/steps: the steps of every clip of it, as a job."""
    path = parse(PATH, request.path_params["path"], "collection path")
    _tables(conn)
    return queue_job(
        conn, request, "annotate_steps", {"clips": _target_clips(conn, {"collection": path})}
    )


def action_collection(conn: psycopg.Connection, request: Request, body: dict[str, Any]) -> Done:
    """POST /api/collections/PATH/action {"action"}: the action of every clip of it, as a job."""
    path = parse(PATH, request.path_params["path"], "collection path")
    _tables(conn)
    clips = _target_clips(conn, {"collection": path})
    return queue_job(conn, request, "annotate_action", {"clips": clips, "action": body["action"]})


def align_primitive(conn: psycopg.Connection, request: Request, body: dict[str, Any]) -> Done:
    """POST /api/processed-data {"primitive", "collection"}: a job (202) where the database has job
    tables, else aligned at once (200 with the counts)."""
    arguments = body
    if schema.installed(conn):
        return queue_job(conn, request, "align", arguments)
    examples, aligned, deleted = conn.execute(
        "SELECT * FROM modb.align_primitive(%s, %s)",
        [arguments["primitive"], arguments["collection"]],
    ).fetchone()
    answer = {**arguments, "examples": examples, "aligned": aligned, "deleted": deleted}
    return Done(answer, "align", f"{arguments['primitive']} in {arguments['collection']}", answer)


def apply_script(conn: psycopg.Connection, request: Request, body: Any) -> Done:
    """POST /api/edit-scripts/NAME/apply: to clips, at once; to a whole collection, a job (202)
    where the database has job tables."""
    if "collection" in body and schema.installed(conn):
        clips = _target_clips(conn, body)
        return queue_job(
            conn,
            request,
            "apply_edit_script",
            {"script": request.path_params["name"], "clips": clips},
        )
    return apply_script_at_once(conn, request, body)
