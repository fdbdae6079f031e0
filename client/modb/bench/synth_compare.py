"""`modb bench synth-compare`: the two synthesis families this database holds, on the same courses.

Motion matching is the default path of `modb synth --collection C` (snippet selection with the
newest transition graph over the data, inertialized seams); models are `modb synth --models GRAPH`
(modb.synthesize_from_models on the graph of the same collection's step models). Both strips are
judged by the same code against the same source, the collection's captured clips:

- goals: reached (the pelvis within the arrival radius), and the time against the straight line at
  the source's median walking pace;
- pose jumps: the worst frame-to-frame move of a body joint relative to the pelvis's ground point,
  and the share of frames above the source's p99;
- foot sliding on contact frames: quality.foot_skating (an ankle or toe within 2 cm of its lowest
  and not rising);
- feet on the ground by a rule of their own (synthesis.feet, the toes' heights against the
  capture's): stance sliding of the lower toe near the floor, how far a toe goes below the
  capture's lowest, and swing clearance (the toes' 95th percentile), each against the capture's;
- root motion: the largest step of the top joint on the ground against its median step (a seam's
  jump in the travel shows as a spike);
- novelty: each frame's distance to the nearest frame of the source (RMS over the body's joints,
  positions relative to the pelvis's ground point in the frame of the hip heading; scipy's cKDTree);
- compute per second of motion walked (wall time of the call on this machine).

The courses are fixed here before any tuning: the demo's six goals, then right angles and
about-turns (turns of 90 and about 170 degrees).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import psycopg
from scipy.spatial import cKDTree

from modb.clips import read_motion
from modb.database import pgarray
from modb.motion import Motion
from modb.synthesis.chain import Settings
from modb.synthesis.feet import Ground
from modb.synthesis.from_models import first_frames
from modb.synthesis.from_models import synthesize as synthesize_models
from modb.synthesis.quality import foot_skating, pose_jumps
from modb.synthesis.root_motion import with_root_motion
from modb.synthesis.synth import synthesize as synthesize_snippets

COURSES = {
    "demo": [(0.0, 8.0), (8.0, 8.0), (8.0, 0.0), (0.0, 0.0), (-6.0, 6.0), (0.0, 12.0)],
    "right angles": [(0.0, 8.0), (8.0, 8.0), (8.0, 16.0), (0.0, 16.0), (0.0, 8.0)],
    "about-turns": [(0.0, 8.0), (1.0, 1.0), (2.0, 9.0), (3.0, 2.0), (4.0, 10.0)],
}
SECONDS = 60.0
RADIUS = 0.5
NOVELTY_STRIDE = 2  # every other source frame in the nearest-neighbour index


@dataclass
class Source:
    """The collection's captured clips, measured once."""

    pose_jump_p99: float
    walking_speed: float  # m/s, median pelvis speed over 1 s windows of moving frames
    index: cKDTree
    ground: Ground

    @classmethod
    def of(cls, conn: psycopg.Connection, collection: str) -> Source:
        pgarray.register(conn)
        rows = conn.execute(
            "SELECT c.clip_id, c.version FROM modb.current_clips c JOIN modb.clips k "
            "ON k.id = c.clip_id WHERE k.collection_id = ANY (modb.collection_subtree(%s)) "
            "ORDER BY 1",
            [collection],
        ).fetchall()
        if not rows:
            raise ValueError(f'collection "{collection}" holds no clips')
        motions = [read_motion(conn, clip, version) for clip, version in rows]
        jumps = np.concatenate([pose_jumps(m) for m in motions if m.n_frames > 1])
        speeds = np.concatenate([_speeds(m) for m in motions])
        moving = speeds[speeds > 0.3]
        features = np.concatenate([pose_features(m)[::NOVELTY_STRIDE] for m in motions])
        return cls(float(np.percentile(jumps, 99)),
                   float(np.median(moving)) if len(moving) else 1.0, cKDTree(features),
                   Ground.of(motions))  # fmt: skip


def _pelvis(motion: Motion) -> np.ndarray:
    sk = motion.skeleton
    return motion.world_positions()[:, sk.index(sk.joint_map["pelvis"])][:, [0, 2]]


def _speeds(motion: Motion) -> np.ndarray:
    pelvis, step = _pelvis(motion), max(1, int(round(motion.fps)))
    return np.linalg.norm(pelvis[step:] - pelvis[:-step], axis=1) if len(pelvis) > step else []


def pose_features(motion: Motion) -> np.ndarray:
    """(frames, 3 * body joints): positions relative to the pelvis's ground point, turned so the
    hips face +Z, divided by sqrt(joints) so a distance is an RMS over joints."""
    sk = motion.skeleton
    above = set(sk.above_pelvis())
    body = [k for k in range(len(sk.joints)) if k not in above]
    p = motion.world_positions()
    pelvis = p[:, sk.index(sk.joint_map["pelvis"])] * np.array([1.0, 0.0, 1.0])
    axis = p[:, sk.index(sk.joint_map["left_hip"])] - p[:, sk.index(sk.joint_map["right_hip"])]
    heading = np.arctan2(-axis[:, 2], axis[:, 0])
    local = p[:, body] - pelvis[:, None]
    c, s = np.cos(heading)[:, None], np.sin(heading)[:, None]
    x = c * local[..., 0] - s * local[..., 2]
    z = s * local[..., 0] + c * local[..., 2]
    return np.stack([x, local[..., 1], z], axis=-1).reshape(len(p), -1) / np.sqrt(len(body))


def goals_reached(motion: Motion, goals, speed: float) -> tuple[list[dict[str, Any]], int]:
    """Each goal in order: reached, and its time against the straight line; and the frame the
    last one reached (or the strip's last)."""
    pelvis, start, out = _pelvis(motion), 0, []
    for goal in goals:
        distance = float(np.linalg.norm(np.asarray(goal) - pelvis[start]))
        near = np.flatnonzero(np.linalg.norm(pelvis[start:] - goal, axis=1) <= RADIUS)
        if not len(near):
            out.append({"goal": list(goal), "reached": False, "distance_m": distance})
            return out, len(pelvis) - 1
        seconds = near[0] / motion.fps
        ratio = seconds * speed / max(distance, 1e-9)
        out.append({"goal": list(goal), "reached": True, "distance_m": distance,
                    "seconds": seconds, "ratio": ratio})  # fmt: skip
        start += int(near[0])
    return out, start


def measure(motion: Motion, goals, seconds_spent: float, source: Source) -> dict[str, Any]:
    reached, last = goals_reached(motion, goals, source.walking_speed)
    walked = motion if last >= motion.n_frames - 1 else first_frames(motion, last + 1)
    jumps = pose_jumps(walked)
    root = with_root_motion(walked)
    top = root.world_positions()[:, 0][:, [0, 2]]
    root_steps = np.linalg.norm(np.diff(top, axis=0), axis=1)
    distances, _ = source.index.query(pose_features(walked))
    ratios = [g["ratio"] for g in reached if g["reached"] and g["distance_m"] >= 5.0]
    return {
        "goals_reached": sum(g["reached"] for g in reached),
        "goals": len(goals),
        "reach_ratio_max": max(ratios) if ratios else None,
        "walked_seconds": (walked.n_frames - 1) / walked.fps,
        "pose_jump_max_cm": 100 * float(jumps.max()),
        "share_above_source_p99": float(np.mean(jumps > source.pose_jump_p99)),
        "foot_sliding_cm_s": 100 * foot_skating(walked)[0],
        "feet": source.ground.judge(walked),
        "root_step_max_over_median": float(root_steps.max() / max(np.median(root_steps), 1e-9)),
        "novelty_median_cm": 100 * float(np.median(distances)),
        "novelty_p95_cm": 100 * float(np.percentile(distances, 95)),
        "compute_per_motion_second": seconds_spent / max((walked.n_frames - 1) / walked.fps, 1e-9),
        "goal_detail": reached,
    }


@dataclass
class Walked:
    """A strip one family walked, and the wall time its call took."""

    motion: Motion
    seconds_spent: float


def result(source: Source, collection: str, graph: str, seconds: float, seed: int
           ) -> dict[str, Any]:  # fmt: skip
    """What run() returns, before its courses (compared() adds each)."""
    return {"collection": collection, "graph": graph, "seconds": seconds, "seed": seed,
            "source_pose_jump_p99_cm": 100 * source.pose_jump_p99,
            "source_walking_speed": source.walking_speed, "courses": {}}  # fmt: skip


def compared(goals, matched: Walked, modelled: Walked, source: Source) -> dict[str, Any]:
    """One course as both families walked it, judged alike: {"goals", family: figures}."""
    return {
        "goals": goals,
        "motion matching": measure(matched.motion, goals, matched.seconds_spent, source),
        "models": measure(modelled.motion, goals, modelled.seconds_spent, source),
    }


def run(conn: psycopg.Connection, collection: str, graph: str, seconds: float = SECONDS,
        seed: int = 0, courses: dict[str, list] | None = None) -> dict[str, Any]:  # fmt: skip
    """Every course walked by both families: {..., "courses": {name: {family: figures}}}."""
    source = Source.of(conn, collection)
    out = result(source, collection, graph, seconds, seed)
    for name, goals in (courses or COURSES).items():
        t = time.perf_counter()
        snippets = synthesize_snippets(conn, goals, seconds, Settings(collection=collection))
        matched = Walked(snippets.strip, time.perf_counter() - t)
        t = time.perf_counter()
        models = synthesize_models(conn, graph, goals, seconds, seed)
        modelled = Walked(models.motion, time.perf_counter() - t)
        out["courses"][name] = compared(goals, matched, modelled, source)
    return out


ROWS = (
    ("goals reached", lambda f: f"{f['goals_reached']} of {f['goals']}"),
    ("slowest goal >= 5 m, x straight line",
     lambda f: "-" if f["reach_ratio_max"] is None else f"{f['reach_ratio_max']:.2f}"),
    ("worst pose jump, cm", lambda f: f"{f['pose_jump_max_cm']:.1f}"),
    ("frames above the source's p99", lambda f: f"{100 * f['share_above_source_p99']:.2f}%"),
    ("foot sliding, cm/s", lambda f: f"{f['foot_sliding_cm_s']:.1f}"),
    ("stance sliding (toes), x capture", lambda f: f"{f['feet']['sliding_x_source']:.2f}"),
    ("toe below the capture's lowest, cm", lambda f: f"{f['feet']['toe_dip_cm']:.1f}"),
    ("swing clearance (toe p95), x capture", lambda f: f"{f['feet']['clearance_x_source']:.2f}"),
    ("root motion, largest step / median", lambda f: f"{f['root_step_max_over_median']:.2f}"),
    ("novelty, median / p95, cm",
     lambda f: f"{f['novelty_median_cm']:.1f} / {f['novelty_p95_cm']:.1f}"),
    ("compute per second walked, s", lambda f: f"{f['compute_per_motion_second']:.3f}"),
)  # fmt: skip


def table(result: dict[str, Any]) -> str:
    """A Markdown table: a row per figure, a column per course and family (MM: motion
    matching)."""
    names = list(result["courses"])
    head = ["figure"] + [f"{n}: {family}" for n in names for family in ("MM", "models")]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for label, show in ROWS:
        cells = [show(result["courses"][n][family]) for n in names
                 for family in ("motion matching", "models")]  # fmt: skip
        lines.append("| " + " | ".join([label, *cells]) + " |")
    return "\n".join(lines)
