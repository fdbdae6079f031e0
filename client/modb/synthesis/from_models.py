"""Synthesis from a graph of motion models, as `modb synth --models` runs it: the strip comes from
the server (modb.synthesize_from_models: the same arguments give the same strip, whoever asks), and
its quality is measured here against the capture the models learnt from."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import psycopg
from psycopg.types.json import Jsonb

from modb.clips import read_motion
from modb.database import pgarray
from modb.motion import Motion, Skeleton
from modb_kernel.step_search import swing_side

from .chain import MAX_COORDINATE
from .quality import REACH_MIN_DISTANCE, NaturalSteps, foot_skating, pose_jumps

AIM_REACH_RATIO = 2.0  # a goal >= REACH_MIN_DISTANCE away within this times the straight line
AIM_SLIDING_RATIO = 1.5  # stance-foot sliding at most this times the source's
AIM_SEARCH_RATIO = 0.5  # median constraint error at most this times the best of 300 random draws

STRIP = """
SELECT fps, rotations, translations, report
  FROM modb.synthesize_from_models(%s, %s::float8[], %s, %s, %s, %s::jsonb)
"""
SKELETON = """
SELECT s.name, s.hierarchy, s.joint_map, s.mirror_pairs FROM modb.graphs g
  JOIN modb.skeletons s ON s.id = g.skeleton_id WHERE g.name = %s AND g.kind = 'models'
"""
# the captured examples the graph's walk models learnt from (not its actions'): clip versions and
# step segments
EXAMPLES = """
SELECT DISTINCT p.clip_id, p.version, p.primitive, p.segment
  FROM modb.graphs g, jsonb_each(g.data->'nodes') n, modb.models m,
       jsonb_array_elements(m.data->'inputs') i, modb.processed_data p
 WHERE g.name = %s AND g.kind = 'models' AND m.id = (n.value->>'model_id')::bigint
   AND n.value->>'type' IS DISTINCT FROM 'action'
   AND p.id = (i->>'id')::bigint AND NOT p.mirrored
 ORDER BY 1, 2
"""


@dataclass
class ModelStrip:
    motion: Motion
    report: dict[str, Any]  # the server's: steps, goals reached, notes
    graph: str
    goals: list[tuple[float, float]]
    seed: int


def synthesize(conn: psycopg.Connection, graph: str, goals: list[tuple[float, float]],
               seconds: float, seed: int = 0, radius: float = 0.5,
               actions: list[dict[str, Any]] | None = None) -> ModelStrip:  # fmt: skip
    """The strip modb.synthesize_from_models walks, as a Motion of the graph's skeleton; actions
    as that function takes them."""
    pgarray.register(conn)
    with conn.cursor(binary=True) as cur:
        fps, rotations, translations, report = cur.execute(
            STRIP, [graph, [[float(v) for v in g] for g in goals], seconds, seed, radius,
                    None if not actions else Jsonb(actions)]
        ).fetchone()
    row = conn.execute(SKELETON, [graph]).fetchone()
    skeleton = Skeleton.from_row(row[1], row[2], row[3], row[0])
    r = np.asarray(rotations, dtype=np.float64)
    t = np.zeros((len(r), 0, 3)) if translations is None else np.asarray(translations, np.float64)
    motion = Motion(skeleton, float(fps), r, t, f"synth_{graph}".replace(" ", "_"),
                    meta={"graph of models": graph, "seed": seed})  # fmt: skip
    # the course as walked: the goals and where each action was performed
    return ModelStrip(motion, report, graph, [tuple(g) for g in report["goals"]], seed)


def parse_action(text: str, goals_before: int) -> dict[str, Any]:
    """'NAME:X,Y,Z[:SECONDS]' (`modb synth --action`, the REST walk's `action`) as
    modb.synthesize_from_models's action, after `goals_before` goals."""
    name, _, rest = text.partition(":")
    point, _, seconds = rest.partition(":")
    try:
        target = [float(v) for v in point.split(",")]
        if not name or len(target) != 3 or not all(abs(v) <= MAX_COORDINATE for v in target):
            raise ValueError
        action = {"primitive": name, "target": target, "after": goals_before}
        if seconds:
            action["seconds"] = float(seconds)
    except ValueError:
        raise ValueError(f"action {text!r:.200}: expected NAME:X,Y,Z[:SECONDS], the graph's "
                         "action and where its hand goes (a repeated motion such as a wave: the "
                         "point it faces, and for how long) in world metres, e.g. "
                         "raise_right_hand:0.3,1.75,4") from None  # fmt: skip
    return action


def actions_in_course(course: list[tuple[str, str]]) -> list[dict[str, Any]]:
    """The actions of a course [("to", "X,Z") or ("action", "NAME:X,Y,Z[:S]"), ...] in the order
    given, each after the goals before it."""
    return [parse_action(text, sum(1 for kind, _ in course[:k] if kind == "to"))
            for k, (kind, text) in enumerate(course) if kind == "action"]  # fmt: skip


def stance_sliding(motion: Motion, steps: list[tuple[str, int, int]]) -> np.ndarray:
    """Per frame of each step (swing side, first frame, last frame): the horizontal speed (m/s) of
    the foot it stands on, at its slower point (ankle or toe: the foot rolls over its toes)."""
    sk = motion.skeleton
    positions = motion.world_positions()
    out = []
    for swing, first, last in steps:
        stance = "right" if swing == "left" else "left"
        joints = [sk.index(sk.joint_map[f"{stance}_{part}"]) for part in ("ankle", "toe")]
        ground = positions[first : last + 1][:, joints][..., [0, 2]]
        if len(ground) > 1:
            out.append(np.linalg.norm(np.diff(ground, axis=0), axis=-1).min(axis=1) * motion.fps)
    return np.concatenate(out) if out else np.zeros(0)


@dataclass
class Source:
    """What the models learnt from, measured: the scale the strip is judged on."""

    natural: NaturalSteps
    sliding: float  # m/s, stance-foot sliding over the captured steps
    walking_speed: float  # m/s, the median pelvis speed over the captured steps

    @classmethod
    def of(cls, conn: psycopg.Connection, graph: str) -> Source:
        pgarray.register(conn)
        clips: dict[tuple[int, int], list[tuple[str, int, int]]] = {}
        for clip_id, version, primitive, segment in conn.execute(EXAMPLES, [graph]).fetchall():
            swing = swing_side(primitive)
            if swing:
                step = (swing, segment["start"], segment["end"])
                clips.setdefault((clip_id, version), []).append(step)
        if not clips:
            raise ValueError(f'graph "{graph}": its models name no captured steps to judge it by')
        motions, sliding, speeds = [], [], []
        for (clip_id, version), steps in clips.items():
            m = read_motion(conn, clip_id, version)
            motions.append(m)
            sliding.append(stance_sliding(m, steps))
            pelvis = m.world_positions()[:, m.skeleton.index(m.skeleton.joint_map["pelvis"])]
            for _, first, last in steps:
                travel = np.linalg.norm((pelvis[last] - pelvis[first])[[0, 2]])
                speeds.append(travel * m.fps / max(last - first, 1))
        return cls(NaturalSteps.of(motions), float(np.concatenate(sliding).mean()),
                   float(np.median(speeds)))  # fmt: skip


def measure(strip: ModelStrip, source: Source) -> dict[str, Any]:
    """The strip's figures against the source's, and which aims they meet."""
    motion, report = strip.motion, strip.report
    fps = motion.fps
    walked = report["stood_from_frame"]
    moving = motion if walked is None else first_frames(motion, walked + 1)
    # not the pieces of standing, nor the actions (report["actions"])
    stepped = [r for r in report["steps"] if not r.get("rest") and not r.get("action")]
    # a step runs from the frame before its first (the seam: its stance foot touches down) on
    steps = [
        (
            side,
            max(r["first_frame"] - 1, 0),
            min(r["first_frame"] + r["n_frames"], motion.n_frames) - 1,
        )
        for r in stepped
        if (side := r["swing"])
    ]
    sliding = float(stance_sliding(motion, steps).mean()) if steps else 0.0
    # the walk's jumps: an action's frames are judged against its own capture (modb bench actions)
    jumps = pose_jumps(motion)
    for a in report.get("actions", []):
        jumps[max(a["first_frame"] - 1, 0) : a["first_frame"] + a["n_frames"] - 1] = 0.0
    errors = np.array([[s["tree_error_m"], s["error_m"], s["random_error_m"]]
                       for s in stepped])  # fmt: skip
    goals = _goals(motion, strip.goals, report["reached"], source.walking_speed)
    for g in goals:  # an action's place, not a goal given
        g["action"] = report.get("places", {}).get(str(g["goal"]))
    out = {
        "graph": strip.graph,
        "seed": strip.seed,
        "seconds": (motion.n_frames - 1) / fps,
        "steps": len(stepped),
        "stood_from_seconds": None if walked is None else walked / fps,
        "rested_from_seconds": None if report.get("rested_from_frame") is None else (
            report["rested_from_frame"] / fps),  # fmt: skip
        "notes": report["notes"],
        "goals": goals,
        "walking_speed": source.walking_speed,
        "pose_jump_max": float(jumps.max()) if len(jumps) else 0.0,
        "source_pose_jump_p999": source.natural.pose_jump_p999,
        "stance_sliding": sliding,
        "source_stance_sliding": source.sliding,
        "foot_skating": foot_skating(moving)[0],
        "source_foot_skating": source.natural.foot_skating,
        "constraint_error_median": {
            "tree_m": float(np.median(errors[:, 0])),
            "refined_m": float(np.median(errors[:, 1])),
            "best_of_300_random_m": float(np.median(errors[:, 2])),
        },
    }
    judged = [g for g in goals if g["distance_m"] >= REACH_MIN_DISTANCE]
    out["aims"] = {
        "goals >= 5 m reached within 2x straight line": all(
            g["reached"] and g["ratio"] <= AIM_REACH_RATIO for g in judged) if judged else None,
        "pose jump <= source p99.9": out["pose_jump_max"] <= out["source_pose_jump_p999"],
        "stance-foot sliding <= 1.5x source": sliding <= AIM_SLIDING_RATIO * source.sliding,
        "search error <= half the best of 300 random": out["constraint_error_median"]["refined_m"]
        <= AIM_SEARCH_RATIO * out["constraint_error_median"]["best_of_300_random_m"],
    }  # fmt: skip
    return out


def first_frames(motion: Motion, n: int) -> Motion:
    """The motion's first n frames."""
    return Motion(motion.skeleton, motion.fps, motion.rotations[:n], motion.translations[:n],
                  motion.name, meta=motion.meta)  # fmt: skip


def _goals(motion: Motion, goals, reached: dict[str, int], speed: float) -> list[dict[str, Any]]:
    """Each goal: how far the pelvis stood from it when it became current, and when it was
    reached against the straight line at the source's walking speed."""
    sk = motion.skeleton
    pelvis = motion.world_positions()[:, sk.index(sk.joint_map["pelvis"])][:, [0, 2]]
    out, start = [], 0
    for k, goal in enumerate(goals, start=1):
        frame = reached.get(str(k))
        distance = float(np.linalg.norm(np.asarray(goal) - pelvis[start]))
        seconds = None if frame is None else (frame - start) / motion.fps
        straight = distance / speed
        closest = float(np.linalg.norm(pelvis[start:] - goal, axis=-1).min())
        out.append({"goal": k, "target": list(goal), "distance_m": distance,
                    "reached": frame is not None, "seconds": seconds,
                    "straight_seconds": straight, "closest_m": closest,
                    "ratio": None if seconds is None else seconds / straight})  # fmt: skip
        if frame is None:
            break
        start = frame
    return out
