"""`modb bench actions`: a hand meeting targets (issue 63) over a grid fixed before tuning, per
reach action of a graph of models (an action node whose model has one inner keyframe).

The character stands from the first frame with its pelvis above the origin facing +Z (the idle
node's piece drawn with the seed) and performs the action where it stands (`stand` [0, 0]: no
walk), its hand target given in the world; each target is a fresh synthesis with the same seed, so
only the target differs. The grid, in the action's own frame (its pelvis starting above the origin
facing +Z; Y up; heights above the floor the action was captured on):

- the examples' peak box: per example the model was built from (its inputs, processed data played
  at its own time as the model's samples are placed: modb.models.examples.training_motions), the
  acting wrist at the frame where it is highest (two acting wrists: their midpoint where their mean
  height is highest, as a two-hand target is the midpoint of the hands); the box spans those points
  (least to greatest per axis, every example inside). "inside": its centre and its 8 corners;
- "+10 cm", "+20 cm", "+30 cm": that far beyond the box's face in six directions from its centre:
  up, down, front (+Z), back, out to the acting side and in across the body (a two-hand action:
  out to the right, -X, in to the left);
- "out of reach": OUT_OF_REACH_M in front of the pelvis, at the chest's height at the mean
  motion's keyframe, across from the box's centre.

Per target: the hand's error after the tree search, after refinement (the report's), after IK (the
wrists measured on the frames returned, at the report's keyframe frame: the root mean square over
the acting hands) and whether the report says reachable; the worst pose jump over the action's
frames (from the frame before it, the seam) against the source's p99.9 (a joint's move from one
frame to the next relative to the pelvis's ground point, over every example); the stance feet's
sliding (the most an ankle's ground point moves from where it is at the seam) against the
examples' (the same measure over each example: its median and greatest); joints past the
examples' range plus SLACK_DEGREES over the action's own frames once the seam from standing has
faded (SEAM_FADE_S; the model's limits: the most any example turns a joint from its mean rotation;
the pelvis and the joints above it, which carry the heading, and the legs, pinned where the
character stands as standing pins them, left out; counted per target: the joints past it in any
frame); and the
compute of the action (the wall time of the synthesis's step that performs it), beside a baseline
in the same run: the same action performed with no target (its mean motion: no search, no IK),
its jumps, sliding and joints past the range measured alike.
"""

from __future__ import annotations

import textwrap
import time
from typing import Any

import numpy as np
import psycopg

from modb.jobs.kernel_database import WorkerDatabase
from modb.models.examples import training_motions
from modb_kernel import (inertialization, kinematics, model_actions, model_synthesis, motion_model,
                         quaternion, standing)  # fmt: skip

DISTANCES_M = (0.1, 0.2, 0.3)
DIRECTIONS = ("up", "down", "front", "back", "out", "in")
OUT_OF_REACH_M = 1.2
SLACK_DEGREES = 10.0
SEAM_FADE_S = 4 * inertialization.HALFLIFE_SECONDS  # the seam's offset down to a 16th
JUMP_PERCENTILE = 99.9
BASELINE_ROUNDS = 10
MET_M = 0.01  # the aims: the wrist within 1 cm after IK wherever reachable,
BEFORE_IK_M = 0.02  # within 2 cm before IK (tree + refinement) inside the box
GROUPS = ("inside", "+10 cm", "+20 cm", "+30 cm", "out of reach")
GROUP_NAMES = {"inside": "inside", "10": "+10 cm", "20": "+20 cm", "30": "+30 cm",
               "out": "out of reach"}  # fmt: skip
WIDTH = 118
MAX_SECONDS = 60.0  # each synthesis's length: more than the idle piece and the action


class NoActions(LookupError):
    """The graph has none of the reach actions asked for."""


def reach_actions(models: dict, types: dict, wanted: list[str] | None) -> list[str]:
    """The graph's reach actions (action nodes whose model has a keyframe), in the graph's order,
    those named only when `wanted`; NoActions saying which are not."""
    reach = [n for n, t in types.items() if t == "action" and models[n].keyframe is not None]
    if wanted is None:
        if not reach:
            raise NoActions("the graph has no reach action (an action node whose model has one "
                            "inner keyframe)")  # fmt: skip
        return reach
    unknown = [n for n in wanted if n not in reach]
    if unknown:
        raise NoActions(f'"{unknown[0]:.100}" is not a reach action of the graph (its reach '
                        f"actions: {', '.join(reach) or 'none'})")  # fmt: skip
    return [n for n in reach if n in wanted]


body_jumps = kinematics.pose_jumps  # per frame step, a joint's largest move about the pelvis


def sliding(p: np.ndarray, ankles: list[int]) -> float:
    """The most an ankle's ground point moves from where it is at the first frame (metres)."""
    ground = p[:, ankles][..., [0, 2]]
    return float(np.linalg.norm(ground - ground[:1], axis=-1).max())


def peak(p: np.ndarray, wrists: list[int]) -> np.ndarray:
    """The acting wrists' point (their midpoint) at the frame where their mean height is highest."""
    mid = p[:, wrists].mean(axis=1)
    return mid[int(np.argmax(mid[:, 1]))]


def source(conn: psycopg.Connection, model, rig) -> dict[str, Any]:
    """The action's examples (every input of its model): their peaks, the box they span, their
    pose jumps' p99.9 and their feet's sliding."""
    doc = model.model
    examples = training_motions(conn, doc, len(doc.get("inputs", [])))
    if not examples:
        raise NoActions(f'the model "{doc.get("name")}" has none of its examples stored')
    ankles = list(rig.ankle.values())
    mirrored = {i for (i,) in conn.execute(
        "SELECT id FROM modb.processed_data WHERE id = ANY (%s) AND mirrored",
        [[i for i, _ in examples]]).fetchall()}  # fmt: skip
    peaks, jumps, slides = [], [], []
    for ident, motion in examples:
        p = rig.positions(motion.rotations, motion.translations)
        peaks.append(peak(p, model.wrist_joints))
        jumps.append(body_jumps(p, rig.pelvis))
        slides.append(sliding(p, ankles))
    peaks = np.array(peaks)
    # the box: the captured clips' peaks (the other side's mirrored ones are other people's)
    captured = peaks[[i not in mirrored for i, _ in examples]]
    return {"examples": len(examples), "peaks": peaks, "low": captured.min(axis=0),
            "high": captured.max(axis=0),
            "jump_p999_m": float(np.percentile(np.concatenate(jumps), JUMP_PERCENTILE)),
            "slide_median_m": float(np.median(slides)),
            "slide_max_m": float(max(slides))}  # fmt: skip


def chest_height(model, rig) -> float:
    """The chest's height at the keyframe of the model's mean motion (the action's frame)."""
    rotations, translations = motion_model.canonical_frames(model.model, np.zeros(model.split))
    p = rig.positions(rotations[model.keyframe : model.keyframe + 1],
                      translations[model.keyframe : model.keyframe + 1])[0]  # fmt: skip
    chest = rig.joint_map.get("chest") or rig.joint_map.get("neck")
    return float(p[rig.names.index(chest), 1])


def grid(low, high, hands, chest_y) -> list[tuple[str, str, np.ndarray]]:
    """[(group, label, target in the action's frame)]: the module's grid (its docstring)."""
    low, high = np.asarray(low, np.float64), np.asarray(high, np.float64)
    centre, half = (low + high) / 2, (high - low) / 2
    out_x = 1.0 if hands == ("left",) else -1.0  # +X is the character's left
    ways = {"up": (1, 1.0), "down": (1, -1.0), "front": (2, 1.0), "back": (2, -1.0),
            "out": (0, out_x), "in": (0, -out_x)}  # fmt: skip
    targets = [("inside", "centre", centre)]
    for corner in np.ndindex(2, 2, 2):
        label = "corner " + "".join("+" if c else "-" for c in corner)
        targets.append(("inside", label, np.where(np.array(corner) == 1, high, low)))
    for d in DISTANCES_M:
        for way in DIRECTIONS:
            axis, sign = ways[way]
            point = centre.copy()
            point[axis] += sign * (half[axis] + d)
            targets.append((f"+{round(100 * d)} cm", way, point))
    targets.append(("out of reach", f"{OUT_OF_REACH_M:g} m in front",
                    np.array([centre[0], chest_y, OUT_OF_REACH_M])))  # fmt: skip
    return targets


def _synthesis(graph, models, rig, node, target, seed):
    """A synthesis standing from its first frame with the action due where it stands, its standing
    piece played (Synthesis.rest): the next act_step performs the action."""
    syn = model_synthesis.Synthesis(graph, models, rig, [], MAX_SECONDS, seed, actions=[
        {"primitive": node, "target": target, "stand": [0.0, 0.0]}])  # fmt: skip
    syn.act_without_walking()
    syn.rest()
    return syn


def perform(graph, models, rig, node, target, seed) -> tuple[Any, dict, float]:
    """(synthesis, its action's report record, seconds the step performing it took)."""
    syn = _synthesis(graph, models, rig, node, None if target is None else list(target), seed)
    t0 = time.perf_counter()
    syn.act_step()
    seconds = time.perf_counter() - t0
    (record,) = syn.actions
    return syn, record, seconds


def measure(syn, record, model, rig, world, limits, moved) -> dict[str, Any]:
    """The figures of one performed action (the frames as returned, the kernel's FK)."""
    rotations, translations = syn.frames()
    span = slice(record["first_frame"] - 1, record["first_frame"] + record["n_frames"])
    p = rig.positions(rotations[span], translations[span])
    figures = {}
    if world is not None:
        key = record["keyframe_frame"] - span.start
        wanted = model_actions.hand_targets(model, world)
        miss = np.linalg.norm(p[key, model.wrist_joints] - wanted, axis=-1)
        figures = {
            "tree_m": record["tree_error_m"], "refined_m": record["refined_error_m"],
            "ik_m": float(np.sqrt(np.mean(miss**2))), "ik_report_m": record["ik_error_m"],
            "reachable": bool(record["reachable"]), "keyframe_frame": record["keyframe_frame"],
        }  # fmt: skip
    # the action's frames once the seam from standing has faded (its pose is the standing's till
    # then: inertialization's offset, SEAM_FADE_S)
    settled = record["first_frame"] + int(round(SEAM_FADE_S * syn.fps))
    own = rotations[settled : span.stop][:, moved]
    turned = np.degrees(quaternion.angle_between(own, limits[0][None, moved]))
    past = turned.max(axis=0) - (limits[1][moved] + SLACK_DEGREES)
    return {
        **figures, "first_frame": record["first_frame"], "n_frames": record["n_frames"],
        "jump_m": float(body_jumps(p, rig.pelvis).max()),
        "slide_m": sliding(p, list(rig.ankle.values())),
        "past_joints": int((past > 0).sum()), "past_deg": float(max(past.max(), 0.0)),
        "past_names": [rig.names[moved[k]] for k in np.argsort(-past) if past[k] > 0],
    }  # fmt: skip


def run(conn: psycopg.Connection, graph_name: str, actions: list[str] | None = None, seed: int = 0,
        groups: list[str] | None = None, progress=lambda text: None) -> dict[str, Any]:  # fmt: skip
    """Every reach action of the graph (or those named) over the grid (its groups named only):
    the figures per target, the source's and the baseline's."""
    db = WorkerDatabase(conn)
    graph, models, rig = model_synthesis.load(db, graph_name)
    types = model_synthesis.node_types(graph)
    out = {"graph": graph_name, "seed": seed, "actions": []}
    for node in reach_actions(models, types, actions):
        model = models[node]
        progress(f"{node}: its examples")
        src = source(conn, model, rig)
        limits = (np.asarray(model.model["limits"]["mean"], np.float64),
                  np.asarray(model.model["limits"]["degrees"], np.float64))  # fmt: skip
        above, j = set(), rig.pelvis
        while j >= 0:
            above.add(j)
            j = rig.parents[j]
        # the legs are pinned where the character stands, as its standing pins them: left out
        legs = {j for chain in standing.Legs(rig).chains.values() for j in chain}
        moved = [j for j in range(len(rig.names)) if j not in above and j not in legs]
        # the floor the action stands on: the standing piece's lift (the same for every target)
        probe, record, _ = perform(graph, models, rig, node, None, seed)
        lift = probe.spot.lift
        plain = measure(probe, record, model, rig, None, limits, moved)
        baseline = [perform(graph, models, rig, node, None, seed)[2]
                    for _ in range(BASELINE_ROUNDS)]  # fmt: skip
        rows = []
        targets = [t for t in grid(src["low"], src["high"], model.hands, chest_height(model, rig))
                   if groups is None or t[0] in groups]  # fmt: skip
        progress(f"{node}: {len(targets)} targets")
        for group, label, local in targets:
            world = local + np.array([0.0, lift, 0.0])  # the spot: pelvis at the origin, facing +Z
            syn, record, seconds = perform(graph, models, rig, node, world, seed)
            rows.append({"group": group, "label": label, "local": local.tolist(),
                         "target": world.tolist(), "seconds": seconds,
                         **measure(syn, record, model, rig, world, limits, moved)})  # fmt: skip
        out["actions"].append({
            "action": node, "hands": list(model.hands), "examples": src["examples"],
            "box_low": src["low"].tolist(), "box_high": src["high"].tolist(), "lift_m": lift,
            "source_jump_p999_m": src["jump_p999_m"], "source_slide_median_m":
            src["slide_median_m"], "source_slide_max_m": src["slide_max_m"],
            "baseline_seconds": baseline, "baseline": plain, "targets": rows,
        })  # fmt: skip
    return out


def _pair(values, scale=100.0, fmt=".1f") -> str:
    if not values:
        return "-"
    return f"{scale * np.median(values):{fmt}}/{scale * max(values):{fmt}}"


def _ms(seconds) -> str:
    ms = 1e3 * np.asarray(seconds)
    return f"{np.median(ms):.0f}/{np.percentile(ms, 99):.0f}"


def table(result: dict[str, Any]) -> str:
    """Per action: its box and source, a row per group of targets, the baseline, the aims."""
    blocks = []
    for a in result["actions"]:
        low, high = np.array(a["box_low"]), np.array(a["box_high"])
        size = " x ".join(f"{100 * v:.0f}" for v in high - low)
        centre = ", ".join(f"{v:.2f}" for v in (low + high) / 2)
        lines = [
            *wrapped(f"{a['action']} ({', '.join(a['hands'])}): {a['examples']} examples; peak "
                     f"box {size} cm (X x Y x Z) about ({centre}) m; the source's pose jump "
                     f"p99.9 {100 * a['source_jump_p999_m']:.2f} cm, its feet sliding "
                     f"{100 * a['source_slide_median_m']:.2f} cm median, "
                     f"{100 * a['source_slide_max_m']:.2f} cm most"),
            "",
            "| targets | n | tree cm | refined cm | IK cm | reachable | jump/p99.9 | sliding cm "
            "| past range+10 | ms p50/p99 |",
            "|" + "---|" * 10,
        ]  # fmt: skip
        rows = a["targets"]
        for group in [*GROUPS, "all"]:
            rs = [r for r in rows if group in ("all", r["group"])]
            if not rs:
                continue
            lines.append(
                f"| {group} | {len(rs)} | {_pair([r['tree_m'] for r in rs])} "
                f"| {_pair([r['refined_m'] for r in rs])} | {_pair([r['ik_m'] for r in rs])} "
                f"| {sum(r['reachable'] for r in rs)}/{len(rs)} "
                f"| {max(r['jump_m'] for r in rs) / a['source_jump_p999_m']:.2f} "
                f"| {100 * max(r['slide_m'] for r in rs):.2f} "
                f"| {sum(r['past_joints'] for r in rs)} | {_ms([r['seconds'] for r in rs])} |"
            )
        b = a["baseline"]
        lines.append(f"| no target (baseline) | {len(a['baseline_seconds'])} | | | | "
                     f"| {b['jump_m'] / a['source_jump_p999_m']:.2f} | {100 * b['slide_m']:.2f} "
                     f"| {b['past_joints']} | {_ms(a['baseline_seconds'])} |")  # fmt: skip
        lines += ["", *aims(a)]
        blocks.append("\n".join(lines))
    return "\n\n".join(["\n".join(wrapped(HEADINGS)), *blocks])


HEADINGS = ("Errors of the hand: median/max over the targets; reachable: the report's; jump/p99.9 "
            "and sliding: the worst target's; past range+10: joints past the examples' range + 10 "
            "degrees, summed over the targets.")  # fmt: skip


def wrapped(text: str, indent: str = "") -> list[str]:
    """The text in lines of at most WIDTH characters (BENCHMARKS.md's)."""
    return textwrap.wrap(text, WIDTH, subsequent_indent=indent, break_on_hyphens=False)


def aims(a: dict[str, Any]) -> list[str]:
    """The issue's aims for one action, each met or not, with the targets that miss."""
    rows, out = a["targets"], []

    def said(ok, text, misses):
        where = "; ".join(misses[:6]) + (" ..." if len(misses) > 6 else "")
        out.extend(wrapped(f"- {'met' if ok else 'NOT met'}: {text}"
                           + (f" (misses: {where})" if misses else ""), "  "))  # fmt: skip

    def name(r, value=""):
        return f"{r['group']} {r['label']}{value}"

    reachable = [r for r in rows if r["reachable"]]
    far = [name(r, f" {100 * r['ik_m']:.1f} cm") for r in reachable if r["ik_m"] > MET_M]
    said(not far, f"after IK within {100 * MET_M:g} cm wherever reachable "
         f"({len(reachable) - len(far)}/{len(reachable)})", far)  # fmt: skip
    inside = [r for r in rows if r["group"] == "inside"]
    if inside:
        far = [name(r, f" {100 * r['refined_m']:.1f} cm") for r in inside
               if r["refined_m"] > BEFORE_IK_M]  # fmt: skip
        said(not far, f"before IK (tree + refinement) within {100 * BEFORE_IK_M:g} cm inside the "
             f"box ({len(inside) - len(far)}/{len(inside)})", far)  # fmt: skip
    unsaid = [name(r) for r in rows if r["group"] == "out of reach" and r["reachable"]]
    elsewhere = [name(r, f" {100 * r['ik_m']:.1f} cm") for r in rows
                 if not r["reachable"] and r["group"] != "out of reach"]  # fmt: skip
    said(not unsaid, "out of reach said" + (f"; also said unreachable: {', '.join(elsewhere)}"
                                            if elsewhere else ""), unsaid)  # fmt: skip
    jumps = [name(r, f" {r['jump_m'] / a['source_jump_p999_m']:.2f}x") for r in rows
             if r["jump_m"] > a["source_jump_p999_m"]]  # fmt: skip
    said(not jumps, "no pose jump above the source's p99.9", jumps)
    slid = [name(r, f" {100 * r['slide_m']:.2f} cm") for r in rows
            if r["slide_m"] > a["source_slide_median_m"]]  # fmt: skip
    said(not slid, "feet planted: sliding at most the source's median example's", slid)
    past = [name(r, f" {'/'.join(r['past_names'])}, {r['past_deg']:.1f} deg") for r in rows
            if r["past_joints"]]  # fmt: skip
    b = a["baseline"]
    plain = (f"; with no target: {'/'.join(b['past_names'])}, {b['past_deg']:.1f} deg"
             if b["past_joints"] else "")  # fmt: skip
    said(not past, f"every joint within the examples' range + {SLACK_DEGREES:g} degrees{plain}",
         past)  # fmt: skip
    return out
