"""Graphs of motion models (modb.graphs kind 'models', 96_model_graphs.sql) in the REST interface:
listed by kind, read with an ETag (a hash of the graph's skeleton and data), and replaced only by a
PUT whose If-Match names that ETag (428 without one; 409 with the current ETag when the graph
changed since it was read), as a skeleton's maps are. The database checks every graph written
(modb.model_graph_problem): a broken one is refused with its reason (400, database_errors). The
writes themselves are catalog_writes' create and replace of a graphs row."""

from __future__ import annotations

from typing import Any

import numpy as np
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


WALK_PARAMETERS = ("to", "action", "seconds", "seed", "arrival_radius")


def walk_args(request: Request) -> tuple[int, list, list, float, int, float]:
    """(graph id, goals, actions, seconds, seed, arrival radius) of GET /api/graphs/ID/synthesis:
    `to=X,Z` and `action=NAME:X,Y,Z[:SECONDS]` repeatable and kept in the order given, as
    `modb synth --models` takes them."""
    from modb.synthesis.chain import checked_goal
    from modb.synthesis.from_models import actions_in_course
    from modb_kernel.model_synthesis import MAX_ARRIVAL_RADIUS_M, MAX_SECONDS

    items = request.query_params.multi_items()
    unknown = sorted({k for k, _ in items} - set(WALK_PARAMETERS))
    if unknown:
        raise BadRequest(f"unknown parameter {unknown[0]!r}: {request.url.path} takes "
                         f"{', '.join(WALK_PARAMETERS)}")  # fmt: skip
    single = {k: v for k, v in items if k not in ("to", "action")}
    if len(single) < sum(k not in ("to", "action") for k, _ in items):
        raise BadRequest("seconds, seed and arrival_radius are given once each")
    course = [(k, v) for k, v in items if k in ("to", "action")]
    try:
        goals = [list(checked_goal(v.split(","))) for k, v in course if k == "to"]
        actions = actions_in_course(course)
    except ValueError as e:
        raise BadRequest(f"{e} (to=X,Z; action=NAME:X,Y,Z[:SECONDS])") from None
    if not goals and not actions:
        raise BadRequest("give a goal (to=X,Z) or an action (action=NAME:X,Y,Z)")
    seconds = _number(single.get("seconds"), "seconds", MAX_SECONDS, 20.0)
    radius = _number(single.get("arrival_radius"), "arrival_radius", MAX_ARRIVAL_RADIUS_M, 0.5)
    seed = single.get("seed", "0")
    if not seed.isascii() or not seed.isdigit() or int(seed) > 2**31 - 1:
        raise BadRequest(f"seed: a whole number from 0 to {2**31 - 1}, got {seed!r:.40}")
    return _ident(request), goals, actions, seconds, int(seed), radius


def _number(value: str | None, what: str, most: float, default: float) -> float:
    if value is None:
        return default
    try:
        number = float(value)
    except ValueError:
        raise BadRequest(f"{what}: a number, got {value!r:.40}") from None
    if not 0 < number <= most:
        raise BadRequest(f"{what}: above 0, at most {most:g}, got {number:g}")
    return number


def walk(conn: psycopg.Connection, request: Request) -> dict[str, Any]:
    """GET /api/graphs/ID/synthesis?to=X,Z&action=NAME:X,Y,Z[:S]&seconds=S[&seed=N]: the strip the
    graph of models walks (modb.synthesize_from_models: goals, then each action walked to and
    performed), its frames and the server's report (per action the hand's error after the tree,
    the refinement and IK)."""
    from modb.synthesis.from_models import synthesize

    ident, goals, actions, seconds, seed, radius = walk_args(request)
    row = conn.execute("SELECT name, kind FROM modb.graphs WHERE id = %s", [ident]).fetchone()
    if row is None or row[1] != KIND:
        raise HTTPException(404, f"no graph of models with id {ident} (GET /api/graphs?kind="
                                 "models lists them)")  # fmt: skip
    try:
        strip = synthesize(conn, row[0], goals, seconds, seed, radius, actions)
    finally:
        conn.close()  # the call's memory goes with its server process (as samples do)
    m = strip.motion
    return {"graph": row[0], "seed": seed, "fps": m.fps, "n_frames": m.n_frames,
            "joints": m.skeleton.names, "parents": m.skeleton.parents,
            "translated": m.skeleton.translated,
            "rotations": np.round(m.rotations, 7).tolist(),
            "translations": np.round(m.translations, 6).tolist(),
            "report": strip.report}  # fmt: skip
