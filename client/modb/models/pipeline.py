"""`modb model build` from start to end, the same in the CLI's process and in a job worker: the
primitive's processed data aligned first where it is missing or stale, the model built, stored as
the next version with its acceleration tree, and (asked for) its quality report."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import psycopg
from threadpoolctl import threadpool_limits

from . import quality, store
from .build import VARIANCE_KEPT
from .examples import Inputs, read_inputs, stale_or_missing

STAGES = ("align", "read", "build", "store", "report")


def build_model(
    conn: psycopg.Connection,
    name: str,
    collection: str,
    primitive: str,
    seed: int = 0,
    variance: float = VARIANCE_KEPT,
    report: bool = False,
    say: Callable[[str], None] = lambda line: None,
    advance: Callable[[int, int], None] = lambda done, total: None,
    job_id: int | None = None,
) -> dict[str, Any]:
    """Builds and stores the model; returns what was made (with the report when asked). A job's
    build (job_id) marks the version it stores, so that a retry of the job finds it and stores
    no second one."""
    # One thread for BLAS and OpenMP: a build is many small fits (a mixture per size tried, a KMeans
    # per tree node), where threads only wait for each other; on a busy two-core host OpenMP's
    # spinning made a build 6x slower (97 s against 17 s, the same model: BENCHMARKS.md).
    with threadpool_limits(limits=1):
        return _build_model(conn, name, collection, primitive, seed, variance, report, say, advance,
                            job_id)  # fmt: skip


def _build_model(
    conn: psycopg.Connection,
    name: str,
    collection: str,
    primitive: str,
    seed: int,
    variance: float,
    report: bool,
    say: Callable[[str], None],
    advance: Callable[[int, int], None],
    job_id: int | None,
) -> dict[str, Any]:
    total = len(STAGES) - (0 if report else 1)
    earlier = store.stored_by_job(conn, name, job_id) if job_id is not None else None
    if earlier is not None:
        say(f"version {earlier[1]} of {name!r} was stored by this job before it was retried: "
            "kept, not built again")  # fmt: skip
        return _made(conn, earlier, name, collection, primitive, seed, report, advance, total)
    why = stale_or_missing(conn, collection, primitive)
    if why is not None:
        say(f"aligning {primitive!r} in {collection!r} first: {why}")
        with conn.transaction():
            examples, aligned, deleted = conn.execute(
                "SELECT * FROM modb.align_primitive(%s, %s)", [primitive, collection]
            ).fetchone()
        say(f"aligned {aligned} of {examples} examples, {deleted} stale rows deleted")
    advance(1, total)
    inputs = read_inputs(conn, collection, primitive)
    advance(2, total)
    document = store.build_document(inputs, collection, seed, variance)
    mixture = document["mixture"]
    say(
        f"{len(inputs.examples)} examples ({sum(r['mirrored'] for r in inputs.rows)} mirrored): "
        f"{len(document['spatial']['components'])} spatial and "
        f"{len(document['temporal']['components'])} temporal components keep "
        f"{variance:.0%} of the variance; a mixture of {len(mixture['weights'])} "
        f"{mixture['covariance_type']}-covariance Gaussians (least BIC)"
    )
    advance(3, total)
    with conn.transaction():
        ident, version = store.save(conn, name, inputs, document, tree_seed=seed, job_id=job_id)
    return _made(conn, (ident, version, document), name, collection, primitive, seed, report,
                 advance, total, inputs)  # fmt: skip


def _made(conn: psycopg.Connection, stored: tuple[int, int, dict[str, Any]], name: str,
          collection: str, primitive: str, seed: int, report: bool,
          advance: Callable[[int, int], None], total: int, inputs: Inputs | None = None,
          ) -> dict[str, Any]:  # fmt: skip
    """What a build made: the stored version in brief, and its quality report when asked."""
    ident, version, document = stored
    mixture = document["mixture"]
    advance(4, total)
    if report and inputs is None:
        inputs = read_inputs(conn, collection, primitive)
    made: dict[str, Any] = {
        "id": ident,
        "name": name,
        "version": version,
        "collection": collection,
        "primitive": primitive,
        "examples": len(document.get("inputs", [])),
        "spatial_components": len(document["spatial"]["components"]),
        "temporal_components": len(document["temporal"]["components"]),
        "mixture_components": len(mixture["weights"]),
        "covariance": mixture["covariance_type"],
    }
    if report:
        made["report"] = {"model": name, "version": version, "collection": collection,
                          **quality.report(inputs, document, seed)}  # fmt: skip
        advance(5, total)
    return made
