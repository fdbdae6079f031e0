"""The REST interface's jobs: list and read them (a reader may), submit one and cancel one (a loader
token, whose name is the job's submitter; recorded in modb.audit_log in the same transaction as the
job row). A worker (`modb worker`) runs what is submitted; GET /api/jobs/ID follows it."""

from __future__ import annotations

from typing import Any

import psycopg
from starlette.exceptions import HTTPException
from starlette.requests import Request

from modb.jobs import schema
from modb.jobs.submit import TooManyQueued, cancel, job_document, submit, workers_alive

from .api import BadRequest, NotFound
from .body_rules import CollectionPath, JsonObject, Nullable, Number, Shape, Text
from .catalog_writes import Done, _int

MAX_LISTED = 200
# What each kind of job takes: the same arguments as its command (`modb graph build`).
ARGUMENTS = {
    "build_graph": Shape(
        {
            "name": Text(),
            "profile": Text(),
            "collection": Nullable(CollectionPath()),
            "min_turn_degrees": Number(0.0, 180.0, unit="degrees"),
        },
        ("name",),
        name="arguments",
    ),
}
SUBMITTED = Shape({"kind": Text(), "arguments": JsonObject()}, ("kind", "arguments"))


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


def submit_job(conn: psycopg.Connection, request: Request, body: Any) -> Done:
    """202 with the queued job; the token's name is its submitter."""
    fields = SUBMITTED(None, body)
    kind = fields["kind"]
    if kind not in ARGUMENTS:
        raise BadRequest(f'"kind": one of {", ".join(ARGUMENTS)}, got {kind!r:.60}')
    arguments = ARGUMENTS[kind](None, fields["arguments"])
    _tables(conn)
    try:
        job_id = submit(conn, kind, request.state.grant.name, **arguments)
    except TooManyQueued as e:
        raise HTTPException(429, str(e)) from None
    answer = {**job(conn, job_id), "workers_alive": workers_alive(conn)}  # 0: it waits for one
    return Done(
        answer, "submit job", f"job {job_id}", {"kind": kind, **arguments}, status=202,
        headers={"Location": f"/api/jobs/{job_id}"},
    )  # fmt: skip


def cancel_job(conn: psycopg.Connection, request: Request, body: Any) -> Done:
    """A queued job cancelled, a running one asked to stop at its next step; 409 when it ended."""
    job_id = _int(request, "ident", "job id")
    before = job(conn, job_id)
    if not cancel(conn, job_id):
        raise HTTPException(
            409, f"job {job_id} is {before['state']}: only a queued or running job stops"
        )
    return Done(job(conn, job_id), "cancel job", f"job {job_id}", {"was": before["state"]})
