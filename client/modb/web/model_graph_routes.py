"""Graphs of motion models (modb.graphs kind 'models', 96_model_graphs.sql) in the REST interface:
listed by kind, read with an ETag (a hash of the graph's skeleton and data), and replaced only by a
PUT whose If-Match names that ETag (428 without one; 409 with the current ETag when the graph
changed since it was read), as a skeleton's maps are. The database checks every graph written
(modb.model_graph_problem): a broken one is refused with its reason (400, database_errors). The
writes themselves are catalog_writes' create and replace of a graphs row."""

from __future__ import annotations

from typing import Any

import psycopg
from starlette.exceptions import HTTPException
from starlette.requests import Request
from starlette.responses import JSONResponse

from modb.editing.meta import entity_tag

from . import api
from .api import BadRequest

KIND = "models"
MAX_ID = 2**63 - 1

# per graph of models: how many nodes and transitions it has (the listing leaves out the data)
SIZES = """
SELECT id,
       CASE WHEN jsonb_typeof(data->'nodes') = 'object'
            THEN (SELECT count(*) FROM jsonb_object_keys(data->'nodes')) END AS nodes,
       CASE WHEN jsonb_typeof(data->'transitions') = 'array'
            THEN jsonb_array_length(data->'transitions') ELSE 0 END AS transitions
  FROM modb.graphs WHERE kind = %s
"""


def etag(skeleton_id: int | None, data: Any) -> str:
    """The entity tag of a graph of models: its skeleton and its data (what the editor changes)."""
    return entity_tag({"skeleton_id": skeleton_id, "data": data})


def _query(request: Request, *allowed: str) -> dict[str, str]:
    unknown = sorted(set(request.query_params) - set(allowed))
    if unknown:
        takes = ", ".join(allowed) if allowed else "no parameters"
        raise BadRequest(f"unknown parameter {unknown[0]!r}: {request.url.path} takes {takes}")
    repeated = sorted(k for k in request.query_params if len(request.query_params.getlist(k)) > 1)
    if repeated:
        raise BadRequest(f"parameter {repeated[0]!r} is given more than once")
    return dict(request.query_params)


def _ident(request: Request) -> int:
    text = request.path_params["ident"]
    if not text.isascii() or not text.isdigit() or int(text) > MAX_ID:
        raise BadRequest(f"graph id: a whole number from 0 to {MAX_ID}, got {text!r:.40}")
    return int(text)


def listing(conn: psycopg.Connection, request: Request) -> list[dict[str, Any]]:
    """GET /api/graphs[?kind=K]: every graph (of that kind); graphs of models with how many nodes
    and transitions they have."""
    kind = _query(request, "kind").get("kind")
    rows = [r for r in api.graphs(conn) if kind is None or r["kind"] == kind]
    if any(r["kind"] == KIND for r in rows):
        sizes = {i: (n, t) for i, n, t in conn.execute(SIZES, [KIND]).fetchall()}
        for r in rows:
            if r["kind"] == KIND:
                r["nodes"], r["transitions"] = sizes.get(r["id"], (None, 0))
    return rows


def one(conn: psycopg.Connection, request: Request) -> Any:
    """GET /api/graphs/ID: the graph; a graph of models with its ETag."""
    _query(request)
    out = api.graph(conn, _ident(request))
    if out["kind"] != KIND:
        return out
    return JSONResponse(out, headers={"ETag": etag(out["skeleton_id"], out["data"])})


def current_etag(conn: psycopg.Connection, ident: int) -> str:
    skeleton_id, data = conn.execute(
        "SELECT skeleton_id, data FROM modb.graphs WHERE id = %s", [ident]
    ).fetchone()
    return etag(skeleton_id, data)


def check_if_match(conn: psycopg.Connection, request: Request, ident: int) -> str:
    """Before a graph of models (its row locked) is replaced: 428 without If-Match, 409 with the
    current ETag when the graph changed since that one was read; the ETag matched, else."""
    if_match = request.headers.get("if-match")
    if not if_match:
        raise HTTPException(
            428,
            f"send If-Match with the ETag of the graph you read (GET /api/graphs/{ident}), "
            "so no edit is lost",
        )
    current = current_etag(conn, ident)
    if if_match != current:
        raise HTTPException(
            409,
            f"graph {ident} changed since it was read (now {current}): read it again and "
            "re-apply the change",
            headers={"ETag": current},
        )
    return current
