"""Motion models in modb.models (kind motion_primitive): built from a collection's processed data
and stored as a new version, listed with why they are stale (modb.model_status), exported and
imported as one JSON file."""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

import numpy as np
import psycopg
from modb_kernel import kinematics, motion_model
from modb_kernel.foot_hold import stance_heights
from modb_kernel.model_samples import KIND
from modb_kernel.step_search import stance_side, swing_side
from psycopg.types.json import Jsonb

from . import build as B
from .examples import Inputs, rig_of
from .tree import build_tree

FILE_FORMAT = "modb motion model"
BUILT_BY_JOB = "built_by_job"  # the meta key naming the job that stored a version
# No document read: the counts are columns the database derives as a version is written
LISTING = """
SELECT s.id, s.name, s.version, s.latest, s.collection, s.primitive, s.skeleton_id,
       s.created_at::text, s.stale, m.examples, m.components, m.has_tree
  FROM modb.model_status s JOIN modb.models m USING (id)
 WHERE s.kind = %s AND (%s::text IS NULL OR s.collection = %s)
 ORDER BY s.name, s.version
"""


class ModelNotFound(LookupError):
    pass


def _not_found(name: str, version: int | None) -> ModelNotFound:
    which = "" if version is None else f" version {version}"
    return ModelNotFound(f'no motion model "{name}"{which} (modb model list names them)')


def build_document(inputs: Inputs, collection: str, seed: int, variance: float) -> dict[str, Any]:
    """The model of the inputs with what it was built from and how (a seeded build is the same)."""
    document = B.build(inputs.examples, rig_of(inputs.skeleton), inputs.fps, inputs.keyframes,
                       seed=seed, variance=variance)  # fmt: skip
    out = {
        "primitive": inputs.primitive,
        "collection": collection,
        "joints": inputs.skeleton.names,
        "skeleton": inputs.skeleton_row,
        **document,
        "inputs": inputs.rows,
    }  # fmt: skip
    out["pace"] = {"jump_p999_m": jump_p999(inputs)}
    stance = stance_side(swing_side(inputs.primitive))
    if stance is not None:  # where the capture holds the foot the step stands on
        sk = inputs.skeleton
        out["stance"] = stance_heights(sk.parents, sk.offsets, sk.translated, sk.names,
                                       sk.joint_map, stance,
                                       [(e.rotations, e.translations) for e in inputs.examples])
    return out


def jump_p999(inputs: Inputs) -> float:
    """The examples' pose jumps' p99.9 (kinematics.pose_jumps, each played at its own pace): how
    fast the capture moves, which a motion made from the model should not pass."""
    sk = inputs.skeleton
    pelvis = sk.index(sk.joint_map["pelvis"])
    jumps = []
    for e in inputs.examples:
        r, t = motion_model.play(e.rotations, e.translations, e.time_function)
        p = kinematics.world_positions(sk.parents, sk.offsets, r, t, sk.translated)
        jumps.append(kinematics.pose_jumps(p, pelvis))
    return float(np.percentile(np.concatenate(jumps), 99.9))


def save(conn: psycopg.Connection, name: str, inputs: Inputs, document: dict[str, Any],
         tree_seed: int | None = 0, job_id: int | None = None) -> tuple[int, int]:  # fmt: skip
    """Stores the document as the next version of `name` (with its acceleration tree unless
    tree_seed is None; marked with the job that built it, if one did); returns (id, version)."""
    meta = {} if job_id is None else {BUILT_BY_JOB: job_id}
    ident, version = conn.execute(
        "INSERT INTO modb.models (name, kind, skeleton_id, collection_id, data, meta) "
        "VALUES (%s, %s, %s, %s, %s, %s) RETURNING id, version",
        [name, KIND, inputs.skeleton_id, inputs.collection_id, Jsonb(document), Jsonb(meta)],
    ).fetchone()
    if tree_seed is not None:
        _store_tree(conn, ident, build_tree(document, seed=tree_seed))
    return ident, version


def stored_by_job(conn: psycopg.Connection, name: str, job_id: int
                  ) -> tuple[int, int, dict[str, Any]] | None:  # fmt: skip
    """(id, version, document) of the version of `name` that job job_id stored, if it did (a
    retried job finds its own result)."""
    return conn.execute(
        "SELECT id, version, data FROM modb.models WHERE name = %s AND kind = %s "
        "AND meta->%s = to_jsonb(%s::bigint)",
        [name, KIND, BUILT_BY_JOB, job_id],
    ).fetchone()


def _store_tree(conn: psycopg.Connection, ident: int, tree: dict[str, Any],
                stamped: bool = False) -> bool:  # fmt: skip
    """Writes the tree into the version's meta, where the database stamps it with the mixture it
    was drawn from (modb.models_check_documents); a tree `stamped` already (from a file) only when
    its stamp is this version's mixture. Returns whether it was written."""
    # two statements, not one with an OR: a build against an extension older than 0.26.0 (no
    # modb.model_mixture_md5) must still parse
    write = ("UPDATE modb.models SET meta = meta || jsonb_build_object('tree', %s::jsonb) "
             "WHERE id = %s")
    if not stamped:
        return conn.execute(write, [Jsonb(tree), ident]).rowcount == 1
    return conn.execute(write + " AND %s = modb.model_mixture_md5(data)",
                        [Jsonb(tree), ident, tree.get("mixture_md5")]).rowcount == 1


def listing(conn: psycopg.Connection, collection: str | None = None) -> list[dict[str, Any]]:
    with conn.cursor(row_factory=psycopg.rows.dict_row) as cur:
        return cur.execute(LISTING, [KIND, collection, collection]).fetchall()


def load(conn: psycopg.Connection, name: str, version: int | None = None) -> dict[str, Any]:
    """The stored row (id, name, version, skeleton_id, collection, data, meta, stale)."""
    with conn.cursor(row_factory=psycopg.rows.dict_row) as cur:
        row = cur.execute(
            "SELECT m.id, m.name, m.version, m.skeleton_id, s.collection, m.data, m.meta, s.stale, "
            "       m.created_at::text AS created_at "
            "FROM modb.models m JOIN modb.model_status s USING (id) "
            "WHERE m.name = %s AND m.kind = %s AND (%s::int IS NULL OR m.version = %s) "
            "ORDER BY m.version DESC LIMIT 1",
            [name, KIND, version, version],
        ).fetchone()
    if row is None:
        raise _not_found(name, version)
    return row


# What `show` prints, read from the documents in the server, and the tree's shape the database kept
# as the tree was written (a version's data is about 0.7 MB and its tree 4.5 MB: neither is sent).
BRIEF = """
SELECT m.id, m.name, m.version, s.collection, m.primitive, m.skeleton_id,
       m.created_at::text AS created_at, s.stale, m.data->'fps' AS fps,
       m.data->'n_frames' AS n_frames,
       m.data->'keyframes' AS keyframes, coalesce(m.examples, 0) AS examples,
       (SELECT count(*) FROM jsonb_array_elements(CASE WHEN jsonb_typeof(m.data->'inputs') = 'array'
                                                       THEN m.data->'inputs' ELSE '[]' END) i
         WHERE i->>'mirrored' = 'true') AS mirrored_examples,
       m.data->'spatial'->'explained' AS spatial_explained,
       m.data->'temporal'->'explained' AS temporal_explained,
       m.data->'mixture'->'weights' AS weights,
       coalesce(m.data->'mixture'->>'covariance_type', 'full') AS covariance,
       m.data->'mixture'->'bic' AS bic, coalesce(m.data->'settings', '{}') AS settings,
       m.tree_shape AS tree
  FROM modb.models m JOIN modb.model_status s USING (id)
 WHERE m.name = %s AND m.kind = %s AND (%s::int IS NULL OR m.version = %s)
 ORDER BY m.version DESC LIMIT 1
"""


def brief(conn: psycopg.Connection, name: str, version: int | None = None) -> dict[str, Any]:
    """A model's version in brief (what `show` prints and the REST view returns)."""
    with conn.cursor(row_factory=psycopg.rows.dict_row) as cur:
        row = cur.execute(BRIEF, [name, KIND, version, version]).fetchone()
    if row is None:
        raise _not_found(name, version)
    weights = row.pop("weights")
    row["mixture"] = {"components": len(weights), "weights": weights,
                      "covariance": row.pop("covariance"), "bic": row.pop("bic")}  # fmt: skip
    return row


def delete(conn: psycopg.Connection, name: str, version: int | None = None) -> int:
    """Deletes the model's version (every version when None); returns how many."""
    return conn.execute(
        "DELETE FROM modb.models "
        "WHERE name = %s AND kind = %s AND (%s::int IS NULL OR version = %s)",
        [name, KIND, version, version],
    ).rowcount


def rebuild_tree(conn: psycopg.Connection, name: str, version: int | None, seed: int,
                 progress: Callable[[str], None] | None = None) -> dict[str, Any]:  # fmt: skip
    row = load(conn, name, version)
    tree = build_tree(row["data"], seed=seed)
    _store_tree(conn, row["id"], tree)
    return tree


def export_document(conn: psycopg.Connection, name: str, version: int | None) -> dict[str, Any]:
    row = load(conn, name, version)
    return {"format": FILE_FORMAT, "name": row["name"], "version": row["version"],
            "collection": row["collection"], "data": row["data"], "meta": row["meta"]}  # fmt: skip


class BadModelFile(ValueError):
    pass


def import_document(conn: psycopg.Connection, document: Any, name: str | None = None
                    ) -> tuple[int, int, str, bool]:  # fmt: skip
    """Stores an exported model as the next version of its name (or `name`) on the stored skeleton
    of the same hierarchy, in the collection of the same path when there is one (else none: the
    model is then stale, as it was not built here). Returns (id, version, name, whether the file's
    acceleration tree was kept)."""
    if not isinstance(document, dict) or document.get("format") != FILE_FORMAT:
        raise BadModelFile(f'not a model file: its "format" is not "{FILE_FORMAT}"')
    data = document.get("data")
    if not isinstance(data, dict) or not isinstance(data.get("skeleton"), dict):
        raise BadModelFile('its "data" has no "skeleton"')
    name = name or document.get("name")
    if not isinstance(name, str) or not name:
        raise BadModelFile('it has no "name" (give one)')
    hierarchy = data["skeleton"].get("hierarchy")
    found = conn.execute(
        "SELECT id FROM modb.skeletons WHERE hierarchy = %s ORDER BY id LIMIT 1", [Jsonb(hierarchy)]
    ).fetchone()
    if found is None:
        raise BadModelFile(
            "no stored skeleton has its hierarchy: load a clip of that skeleton first "
            f"(its skeleton is named {data['skeleton'].get('name')!r})"
        )
    collection = document.get("collection")
    (collection_id,) = conn.execute(
        "SELECT modb.find_collection(%s)", [collection if isinstance(collection, str) else None]
    ).fetchone()
    meta = document.get("meta") if isinstance(document.get("meta"), dict) else {}
    tree = meta.pop("tree", None)
    ident, version = conn.execute(
        "INSERT INTO modb.models (name, kind, skeleton_id, collection_id, data, meta) "
        "VALUES (%s, %s, %s, %s, %s, %s) RETURNING id, version",
        [name, KIND, found[0], collection_id, Jsonb(data), Jsonb(meta)],
    ).fetchone()  # the database refuses a document that cannot be sampled, saying why
    # the file's tree only when the database finds it drawn from this very mixture
    kept = isinstance(tree, dict) and _store_tree(conn, ident, tree, stamped=True)
    return ident, version, name, kept


def dumps(document: dict[str, Any]) -> str:
    return json.dumps(document, separators=(",", ":"))
