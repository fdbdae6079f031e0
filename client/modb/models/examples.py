"""A primitive's examples as the model build reads them: its processed data in a collection
(modb.processed_data, made by `modb align`), with the skeleton they are on."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import psycopg

from modb.database import pgarray
from modb.motion import Motion, Skeleton

from .build import Example, Rig

ROWS = """
SELECT p.id, p.clip_id, p.version, p.mirrored, p.reference, p.rotations, p.translations,
       p.time_function, p.sections, v.skeleton_id, v.fps
  FROM modb.processed_data p
  JOIN modb.clip_versions v USING (clip_id, version)
 WHERE p.collection_id = %s AND p.primitive = %s
 ORDER BY p.id
"""
SKELETON = "SELECT name, hierarchy, joint_map, mirror_pairs FROM modb.skeletons WHERE id = %s"


class NoExamples(LookupError):
    """The collection has no (current) processed data of the primitive."""


@dataclass
class Inputs:
    collection_id: int
    primitive: str
    skeleton_id: int
    skeleton: Skeleton
    skeleton_row: dict[str, Any]  # name, hierarchy, joint_map, mirror_pairs as stored
    fps: float
    keyframes: list[int]
    examples: list[Example]
    rows: list[dict[str, Any]]  # per example: processed-data id, clip_id, version, mirrored


def rig_of(skeleton: Skeleton) -> Rig:
    index = {n: skeleton.names.index(skeleton.joint_map[n]) for n in ("left_hip", "right_hip",
                                                                      "pelvis")}  # fmt: skip
    return Rig(skeleton.parents, skeleton.offsets, skeleton.translated, index["left_hip"],
               index["right_hip"], index["pelvis"])  # fmt: skip


def stale_or_missing(conn: psycopg.Connection, collection: str, primitive: str) -> str | None:
    """Why the processed data must be aligned (again) first, or None when it is current."""
    rows, stale = conn.execute(
        "SELECT count(*), min(stale) FROM modb.processed_data_status "
        "WHERE collection = %s AND primitive = %s",
        [collection, primitive],
    ).fetchone()
    if rows == 0:
        return "it has no processed data"
    return f"its processed data is stale ({stale})" if stale else None


def read_inputs(conn: psycopg.Connection, collection: str, primitive: str) -> Inputs:
    (collection_id,) = conn.execute("SELECT modb.find_collection(%s)", [collection]).fetchone()
    if collection_id is None:
        raise NoExamples(f'no collection "{collection}"')
    pgarray.register(conn)
    with conn.cursor(binary=True) as cur:
        rows = cur.execute(ROWS, [collection_id, primitive]).fetchall()
    if not rows:
        raise NoExamples(f'collection "{collection}" has no processed data of "{primitive}"')
    skeleton_id, fps = rows[0][9], rows[0][10]
    name, hierarchy, joint_map, mirror_pairs = conn.execute(SKELETON, [skeleton_id]).fetchone()
    skeleton = Skeleton.from_row(hierarchy, joint_map, mirror_pairs, name)
    n_translated = len(skeleton.translated)
    examples, kept = [], []
    for ident, clip, version, mirrored, reference, r, t, tf, sections, *_ in rows:
        r = np.asarray(r, dtype=np.float64)
        t = np.zeros((len(r), n_translated, 3)) if t is None else np.asarray(t, np.float64)
        examples.append(Example(r, t, np.asarray(tf, dtype=np.float64), bool(reference)))
        kept.append({"id": ident, "clip_id": clip, "version": version, "mirrored": mirrored})
        if reference:
            keyframes = list(sections)
    row = {"name": name, "hierarchy": hierarchy, "joint_map": joint_map,
           "mirror_pairs": mirror_pairs}  # fmt: skip
    return Inputs(collection_id, primitive, skeleton_id, skeleton, row, float(fps), keyframes,
                  examples, kept)  # fmt: skip


def training_motions(conn: psycopg.Connection, document: dict[str, Any], n: int
                     ) -> list[tuple[int, Motion]]:  # fmt: skip
    """Up to n of the examples a model was built from (spread evenly over its inputs, those still
    stored), each turned and placed as the model's samples are and played at its own time:
    [(processed-data id, motion)]."""
    from modb_kernel import motion_model

    from .build import facing_forward

    ids = [i["id"] for i in document.get("inputs", [])]
    chosen = [ids[k] for k in np.unique(np.linspace(0, len(ids) - 1, min(n, len(ids))).round()
                                       .astype(int))] if ids else []  # fmt: skip
    pgarray.register(conn)
    with conn.cursor(binary=True) as cur:
        rows = cur.execute(
            "SELECT id, rotations, translations, time_function, reference "
            "FROM modb.processed_data WHERE id = ANY (%s) ORDER BY id",
            [chosen],
        ).fetchall()
    sk = document["skeleton"]
    skeleton = Skeleton.from_row(sk["hierarchy"], sk["joint_map"], sk["mirror_pairs"], sk["name"])
    rig = rig_of(skeleton)
    out = []
    for ident, r, t, tf, reference in rows:
        r = np.asarray(r, dtype=np.float64)
        t = np.zeros((len(r), 0, 3)) if t is None else np.asarray(t, np.float64)
        e = facing_forward(Example(r, t, np.asarray(tf, np.float64), reference), rig,
                           document["fps"])  # fmt: skip
        rotations, translations = motion_model.play(e.rotations, e.translations, e.time_function)
        out.append((ident, Motion(skeleton, document["fps"], rotations, translations,
                                  f"example_{ident}")))  # fmt: skip
    return out
