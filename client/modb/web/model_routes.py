"""The REST interface's motion models (modb.models of kind motion_primitive, `modb model`): list
them (per collection), show one version, draw samples and read the training examples beside them
(frames and world positions, as clip frames are), and start a build (a loader token; a job where
the database has job tables)."""

from __future__ import annotations

from typing import Any

import numpy as np
import psycopg
from starlette.requests import Request

from modb.jobs import schema
from modb.motion import Motion

from .api import BadRequest, NotFound
from .bodies import parse
from .body_models import TEXT
from .catalog_writes import Done
from .job_routes import queue_job

MAX_SHOWN = 50  # samples or examples in one answer


def _name(request: Request) -> str:
    return request.path_params["name"]


def _whole(value: str | None, what: str, least: int, most: int, default: int | None) -> int | None:
    if value is None:
        return default
    try:
        number = int(value)
    except ValueError:
        raise BadRequest(f"{what}: a whole number, got {value!r:.40}") from None
    if not least <= number <= most:
        raise BadRequest(f"{what}: from {least} to {most}, got {number}")
    return number


def _query(request: Request, *allowed: str) -> dict[str, str]:
    unknown = sorted(set(request.query_params) - set(allowed))
    if unknown:
        raise BadRequest(f"unknown parameter {unknown[0]!r}: this page takes {', '.join(allowed)}")
    return dict(request.query_params)


def _load(conn: psycopg.Connection, name: str, version: int | None) -> dict[str, Any]:
    from modb.models.store import ModelNotFound, load

    if conn.execute("SELECT to_regclass('modb.model_status') IS NULL").fetchone()[0]:
        raise NotFound("the database's modb extension is older than 0.22.0: no motion models")
    try:
        return load(conn, name, version)
    except ModelNotFound as e:
        raise NotFound(str(e)) from None


def listing(conn: psycopg.Connection, request: Request) -> list[dict[str, Any]]:
    """GET /api/motion-models[?collection=PATH]: every version, with why it is stale."""
    from modb.models.store import listing as stored

    q = _query(request, "collection")
    if conn.execute("SELECT to_regclass('modb.model_status') IS NULL").fetchone()[0]:
        return []
    return stored(conn, q.get("collection"))


def show(conn: psycopg.Connection, request: Request) -> dict[str, Any]:
    """GET /api/motion-models/NAME[?version=N]: the version in brief (`modb model show`)."""
    from modb.models.store import ModelNotFound, brief

    q = _query(request, "version")
    version = _whole(q.get("version"), "version", 1, 2**31 - 1, None)
    if conn.execute("SELECT to_regclass('modb.model_status') IS NULL").fetchone()[0]:
        raise NotFound("the database's modb extension is older than 0.22.0: no motion models")
    try:
        return brief(conn, _name(request), version)
    except ModelNotFound as e:
        raise NotFound(str(e)) from None


def _frames(motion: Motion) -> dict[str, Any]:
    return {
        "n_frames": motion.n_frames,
        "rotations": np.round(motion.rotations, 7).tolist(),
        "translations": np.round(motion.translations, 6).tolist(),
        "positions": np.round(motion.world_positions(), 6).tolist(),
    }


def _motions_answer(row: dict[str, Any], motions: list[Motion], key: str, extra) -> dict[str, Any]:
    first = motions[0]
    return {
        "name": row["name"],
        "version": row["version"],
        "skeleton_id": row["skeleton_id"],
        "fps": first.fps,
        "joints": first.skeleton.names,
        "parents": first.skeleton.parents,
        "translated": first.skeleton.translated,
        key: [{**extra(k, m), **_frames(m)} for k, m in enumerate(motions)],
    }


def samples_args(request: Request) -> tuple[str, int, int, int | None]:
    q = _query(request, "n", "seed", "version")
    return (
        _name(request),
        _whole(q.get("n"), "n", 1, MAX_SHOWN, 10),
        _whole(q.get("seed"), "seed", 0, 2**31 - 1, 0),
        _whole(q.get("version"), "version", 1, 2**31 - 1, None),
    )


def samples(conn: psycopg.Connection, request: Request) -> dict[str, Any]:
    """GET /api/motion-models/NAME/samples?n=10&seed=0[&version=N]: n samples (modb.sample_motion),
    each starting at the origin facing +Z."""
    from modb.models.samples import sample_motions

    name, n, seed, version = samples_args(request)
    row = _load(conn, name, version)
    try:
        motions = sample_motions(conn, name, n, seed, row["version"])
    finally:
        # A server process keeps about 1.1-1.4 MB of each call's Python memory (BENCHMARKS.md, issue
        # 58): the connection is closed, not pooled again, so that no reader's process grows.
        conn.close()
    answer = _motions_answer(row, motions, "samples", lambda k, m: {"sample": k + 1})
    return {**answer, "seed": seed}


def examples_args(request: Request) -> tuple[str, int, int | None]:
    q = _query(request, "n", "version")
    return (
        _name(request),
        _whole(q.get("n"), "n", 1, MAX_SHOWN, 10),
        _whole(q.get("version"), "version", 1, 2**31 - 1, None),
    )


def examples(conn: psycopg.Connection, request: Request) -> dict[str, Any]:
    """GET /api/motion-models/NAME/examples?n=10[&version=N]: n of the examples the version was
    built from (spread evenly over them), placed and played as its samples are."""
    from modb.models.examples import training_motions

    name, n, version = examples_args(request)
    row = _load(conn, name, version)
    shown = training_motions(conn, row["data"], n)
    if not shown:
        raise NotFound(f"model {name} version {row['version']}: its examples are no longer stored")
    return _motions_answer(row, [m for _, m in shown], "examples",
                           lambda k, m: {"processed_data_id": shown[k][0]})  # fmt: skip


def build(conn: psycopg.Connection, request: Request, body: dict[str, Any]) -> Done:
    """POST /api/motion-models/NAME/build {"collection", "primitive", "seed", "variance",
    "report"} (body_models.ModelBuild): a job (202) where the database has job tables, else built
    at once (201)."""
    from modb.models.examples import NoExamples
    from modb.models.pipeline import build_model

    arguments = {"name": parse(TEXT, _name(request), "the model's name"), **body}
    if schema.installed(conn):
        return queue_job(conn, request, "build_model", arguments)
    try:
        made = build_model(conn, **arguments)
    except NoExamples as e:
        raise NotFound(str(e)) from None
    what = f"model {made['name']} version {made['version']}"
    detail = {k: made[k] for k in ("id", "version", "collection", "primitive")}
    return Done(made, "model build", what, detail, 201)
