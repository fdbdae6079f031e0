"""A character's family graph in one command (`modb model graph NAME --collection C`): the models of
every primitive of the family (steps, turning steps, starts, stops, idle) annotated in the
collection that it lacks a current model of, built one after another, then the graph of them
(graphs.step_graph). A primitive with fewer examples than a model needs (its own segments and,
where the skeleton mirrors, the other side's) is said with its count and the minimum, not built.

Where the collection gives no idle model, the graph carries captured standing frames instead: the
longest still stretch of its capture (an idle segment, the frames before a clip's first start,
or after its last stop), at least standing.MIN_STANDING_S long. The same skeleton's standing can be
added to a collection for this, e.g. Bandai dataset 1's gestures beside Bandai dataset 2's walks."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import psycopg

from modb.database import pgarray
from modb_kernel import kinematics
from modb_kernel.processed import MIN_EXAMPLES, other_side
from modb_kernel.standing import MIN_STANDING_S

from . import graphs
from .pipeline import build_model

FAMILY = ("left_step", "right_step", "left_turning_step", "right_turning_step", "left_start",
          "right_start", "left_stop", "right_stop", "idle")  # fmt: skip

# Per primitive of the family: its segments in the current versions of the collection's clips
SEGMENTS = """
SELECT a.seg->>'name' AS primitive, c.clip_id, c.version, c.fps, c.n_frames, c.skeleton_id,
       (a.seg->>'start')::int AS start, (a.seg->>'end')::int AS "end",
       s.mirror_pairs IS NOT NULL AND jsonb_array_length(s.mirror_pairs) > 0 AS mirrors
  FROM modb.current_clips c
  JOIN modb.clips k ON k.id = c.clip_id
  JOIN modb.clip_versions v USING (clip_id, version)
  JOIN modb.skeletons s ON s.id = c.skeleton_id
 CROSS JOIN LATERAL jsonb_array_elements(coalesce(v.meta->'annotations', '[]')) AS a(seg)
 WHERE k.collection_id = ANY (modb.collection_subtree(%s)) AND a.seg->>'name' = ANY (%s)
 ORDER BY c.clip_id, (a.seg->>'start')::int
"""
# The actions annotated in the collection (`modb annotate --action` marks them with their hands)
ACTIONS = """
SELECT DISTINCT a.seg->>'name'
  FROM modb.current_clips c
  JOIN modb.clips k ON k.id = c.clip_id
  JOIN modb.clip_versions v USING (clip_id, version)
 CROSS JOIN LATERAL jsonb_array_elements(coalesce(v.meta->'annotations', '[]')) AS a(seg)
 WHERE k.collection_id = ANY (modb.collection_subtree(%s)) AND a.seg ? 'hands'
 ORDER BY 1
"""
CURRENT = """
SELECT primitive, name FROM modb.model_status
 WHERE kind = 'motion_primitive' AND collection = %s AND latest AND stale IS NULL
 ORDER BY created_at DESC
"""
SKELETON = """
SELECT s.hierarchy, s.joint_map
  FROM modb.clip_versions v JOIN modb.skeletons s ON s.id = v.skeleton_id
 WHERE v.clip_id = %s AND v.version = %s
"""
STILL_M = 0.05  # captured standing: the pelvis within this of where it began on the ground
FRAMES = """
SELECT rotations[%s:%s], translations[%s:%s] FROM modb.clip_versions
 WHERE clip_id = %s AND version = %s
"""


def of_the_steps_skeleton(segments: list[dict[str, Any]]
                          ) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:  # fmt: skip
    """(the segments on the skeleton most of the steps are on, the others)."""
    skeletons: dict[int, int] = {}
    for s in segments:
        if s["primitive"] in graphs.STEPS:
            skeletons[s["skeleton_id"]] = skeletons.get(s["skeleton_id"], 0) + 1
    if not skeletons:
        return segments, []
    chosen = max(skeletons, key=lambda k: (skeletons[k], -k))
    return ([s for s in segments if s["skeleton_id"] == chosen],
            [s for s in segments if s["skeleton_id"] != chosen])  # fmt: skip


def examples(segments: list[dict[str, Any]], primitives: tuple[str, ...] = FAMILY
             ) -> dict[str, int]:  # fmt: skip
    """Per primitive: how many examples a model of it would learn from."""
    own: dict[str, int] = {}
    for s in segments:
        own[s["primitive"]] = own.get(s["primitive"], 0) + 1
    mirrors = all(s["mirrors"] for s in segments)
    return {p: own.get(p, 0) + (own.get(other_side(p) or "", 0) if mirrors else 0)
            for p in primitives}  # fmt: skip


def standing_stretch(segments: list[dict[str, Any]], fps: float) -> dict[str, Any] | None:
    """The longest still stretch of the collection's capture (see the module's description):
    {clip_id, version, start, end} (frames, both included), or None."""
    by_clip: dict[int, list[dict[str, Any]]] = {}
    for s in segments:
        by_clip.setdefault(s["clip_id"], []).append(s)
    stretches = []
    for clip, found in by_clip.items():
        first, last = min(s["start"] for s in found), max(s["end"] for s in found)
        for s in found:
            if s["primitive"] == "idle":
                stretches.append((s, s["start"], s["end"]))
            elif s["primitive"].endswith("_start") and s["start"] == first:
                stretches.append((s, 0, s["start"]))
            elif s["primitive"].endswith("_stop") and s["end"] == last:
                stretches.append((s, s["end"], s["n_frames"] - 1))
    stretches = [t for t in stretches if (t[2] - t[1]) / fps >= MIN_STANDING_S]
    if not stretches:
        return None
    s, start, end = max(stretches, key=lambda t: (t[2] - t[1], -t[0]["clip_id"]))
    return {"clip_id": s["clip_id"], "version": s["version"], "start": start, "end": end}


def stillest(pelvis: np.ndarray, least: int) -> tuple[int, int]:
    """(first, past the last) of the longest run of frames whose pelvis stays within STILL_M of
    where the run began on the ground (a standing person shifting onto a foot before a start is no
    longer still); the whole run where none lasts least frames."""
    best = (0, len(pelvis))
    longest = 0
    for a in range(len(pelvis)):
        away = np.linalg.norm(pelvis[a:] - pelvis[a], axis=1) > STILL_M
        b = a + (int(np.argmax(away)) if away.any() else len(away))
        if b - a > longest:
            longest, best = b - a, (a, b)
    return best if longest >= least else (0, len(pelvis))


def standing_frames(conn: psycopg.Connection, stretch: dict[str, Any], fps: float
                    ) -> dict[str, Any]:  # fmt: skip
    """The stretch's frames as the graph document's "standing": its stillest part."""
    pgarray.register(conn)
    first, last = stretch["start"] + 1, stretch["end"] + 1  # SQL arrays count from 1
    with conn.cursor(binary=True) as cur:
        rotations, translations = cur.execute(FRAMES, [first, last, first, last,
                                                       stretch["clip_id"],
                                                       stretch["version"]]).fetchone()  # fmt: skip
    rotations = np.asarray(rotations, dtype=np.float64)
    hierarchy, joint_map = conn.execute(SKELETON, [stretch["clip_id"], stretch["version"]]
                                        ).fetchone()  # fmt: skip
    joints = hierarchy["joints"]
    moved = np.zeros((len(rotations), 0, 3)) if translations is None else np.asarray(
        translations, dtype=np.float64)  # fmt: skip
    positions = kinematics.world_positions([j["parent"] for j in joints],
                                           np.array([j["offset"] for j in joints]), rotations,
                                           moved, hierarchy["translated"])  # fmt: skip
    pelvis = positions[:, [j["name"] for j in joints].index(joint_map["pelvis"])][:, [0, 2]]
    a, b = stillest(pelvis, int(np.ceil(MIN_STANDING_S * fps)))
    rotations, moved = rotations[a:b], moved[a:b]
    stretch = {**stretch, "start": stretch["start"] + a, "end": stretch["start"] + b - 1}
    return {"fps": fps, "source": stretch,
            "rotations": np.round(rotations, 6).tolist(),
            "translations": None if translations is None else np.round(moved, 6).tolist()}


def build_family(
    conn: psycopg.Connection,
    name: str,
    collection: str,
    chosen: list[str] | None = None,
    seed: int = 0,
    say: Callable[[str], None] = lambda line: None,
    advance: Callable[[int, int], None] = lambda done, total: None,
    job_id: int | None = None,
) -> dict[str, Any]:
    """Builds the models the collection lacks (named NAME_PRIMITIVE), then stores the graph NAME;
    returns {graph, built, kept, too_few: {primitive: examples}, minimum, standing}."""
    if conn.execute("SELECT modb.find_collection(%s)", [collection]).fetchone()[0] is None:
        raise graphs.GraphError(f'no collection "{collection}" (modb list names them)')
    actions = tuple(r[0] for r in conn.execute(ACTIONS, [collection]).fetchall()
                    if r[0] not in FAMILY)  # fmt: skip
    primitives = FAMILY + actions
    with conn.cursor(row_factory=psycopg.rows.dict_row) as cur:
        segments = cur.execute(SEGMENTS, [collection, list(primitives)]).fetchall()
    segments, others = of_the_steps_skeleton(segments)
    mixed = sorted({s["primitive"] for s in others})  # a model learns from one skeleton only
    counts = examples(segments, primitives)
    current: dict[str, str] = {}
    for primitive, model in conn.execute(CURRENT, [collection]).fetchall():
        current.setdefault(primitive, model)
    wanted = [p for p in primitives if counts[p] >= MIN_EXAMPLES and p not in current
              and p not in mixed]  # fmt: skip
    too_few = {p: n for p, n in counts.items() if 0 < n < MIN_EXAMPLES and p not in current}
    built = []
    for k, primitive in enumerate(wanted):
        say(f"building {name}_{primitive}: {counts[primitive]} examples of {primitive!r}")
        made = build_model(conn, f"{name}_{primitive}", collection, primitive, seed, say=say,
                           job_id=job_id)  # fmt: skip
        built.append(made["name"])
        current[primitive] = made["name"]
        advance(k + 1, len(wanted) + 1)
    picked = list(chosen or []) + [m for p, m in current.items() if p in primitives]
    standing = None
    if "idle" not in current and segments and "idle" not in mixed:
        fps = float(segments[0]["fps"])
        stretch = standing_stretch(segments, fps)
        if stretch is not None:
            standing = standing_frames(conn, stretch, fps)
    graph = graphs.build(conn, name, collection, list(dict.fromkeys(picked)), standing,
                         [a for a in actions if a in current])  # fmt: skip
    advance(len(wanted) + 1, len(wanted) + 1)
    return {
        "graph": graph.name,
        "described": graph.describe(),
        "built": built,
        "kept": sorted(m for p, m in current.items() if m not in built),
        "too_few": too_few,
        "other_skeletons": {p: sum(s["primitive"] == p for s in others) for p in mixed},
        "skeleton_id": segments[0]["skeleton_id"] if segments else None,
        "minimum": MIN_EXAMPLES,
        "standing": None if standing is None else standing["source"],
    }


def summary(made: dict[str, Any]) -> list[str]:
    """What the command prints: the graph, the models built and kept, what could not be built."""
    lines = [made["described"]]
    lines.append("built: " + (", ".join(made["built"]) or "nothing (every model was current)"))
    if made["kept"]:
        lines.append("kept (current): " + ", ".join(made["kept"]))
    for primitive, n in sorted(made["too_few"].items()):
        lines.append(f"not built: {primitive}: {n} example{'' if n == 1 else 's'}, a model needs "
                     f"at least {made['minimum']}")  # fmt: skip
    for primitive, n in sorted(made.get("other_skeletons", {}).items()):
        lines.append(f"not built: {primitive}: {n} of its segments are on other skeletons than "
                     f"the steps' ({made['skeleton_id']}): retarget those clips onto it (modb "
                     "retarget) or move them out of the collection")  # fmt: skip
    if made["standing"]:
        s = made["standing"]
        lines.append(f"standing: no idle model; captured standing from clip {s['clip_id']} version "
                     f"{s['version']} frames {s['start']}-{s['end']}")  # fmt: skip
    elif "idle" not in made["described"]:
        lines.append("standing: none (no idle model, no still stretch of at least "
                     f"{MIN_STANDING_S:g} s in the collection): the character stops in its last "
                     "pose; add standing capture of the same skeleton and annotate it")  # fmt: skip
    return lines
