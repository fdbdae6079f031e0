"""What `modb synth` (and `modb demo`, `modb bench synth`) shows of a synthesis: its choices and
quality figures as text, as JSON, and a progress bar while it runs. modb.synthesis computes them."""

from __future__ import annotations

import json
import sys
from collections.abc import Callable

from tqdm import tqdm

from modb.output import open_output
from modb.provenance import StripSources, as_meta
from modb.synthesis.quality import (
    MISSED,
    NOT_JUDGED,
    REACH_AIM,
    REACH_MIN_DISTANCE,
    REACHED,
    GoalReach,
    Report,
    goal_outcomes,
)
from modb.synthesis.synth import Synthesis


def _ms(value: float | None) -> str:
    return "-" if value is None else f"{value:.1f}"


def format_report(
    result: Synthesis, rep: Report, names: dict[int, str], sources: StripSources
) -> str:
    """Every choice, then the summary."""
    lines = [
        "step  time s  snippet  clip (frames)                                   level  continuity  "
        "query ms  goal",
        "----  ------  -------  ----------------------------------------------  -----  ----------  "
        "--------  ----",
    ]
    for c in result.chain:
        mirror = " (mirror)" if c.mirrored else ""
        last = c.first_frame + c.n_frames - 1
        clip = f"{names.get(c.clip_id, c.clip_id)}{mirror} {c.first_frame}-{last}"
        level = "start" if c.relax_level is None else str(c.relax_level)
        continuity = "-" if c.continuity is None else f"{c.continuity:.2f}"
        lines.append(
            f"{c.step:4d}  {c.start_frame / c.fps:6.1f}  {c.snippet_id:7d}  {clip[:46]:46s}  "
            f"{level:>5s}  "
            f"{continuity:>10s}  {_ms(c.latency_ms):>8s}  {c.goal}{' reached' if c.reached else ''}"
        )
    return "\n".join(lines) + "\n\n" + format_summary(result, rep) + "\n" + sources.summary()


def format_summary(result: Synthesis, rep: Report) -> str:
    """The quality figures, goal by goal reach, and which aims are met."""
    lines = [
        f"strip: {rep.seconds:.1f} s, {rep.snippets} snippets, {rep.seams} seams"
        + (f" (ended early: {result.stopped})" if result.stopped else ""),
        f"query latency: p50 {_ms(rep.latency_ms_p50)} ms, p99 {_ms(rep.latency_ms_p99)} ms; "
        + _selection_max(rep),
        "relaxation levels: "
        + ", ".join(f"{k}: {v}" for k, v in rep.levels.items())
        + f" (last level {rep.last_level_share:.1%})",
        f"seam roughness: {rep.seam_share_over_one:.1%} of seams have r > 1 (natural steps: "
        f"{rep.natural_share_over_one:.1%} of {rep.natural_steps:,}); seam r p99 "
        f"{rep.seam_r_p99:.2f} "
        f"(natural r p99.9 {rep.natural_r_p999:.2f})",
        f"recombination: {rep.recombination:.1%} of seams",
        f"pose jump: largest {100 * rep.pose_jump_max:.1f} cm per frame (natural p99.9 "
        f"{100 * rep.natural_pose_jump_p999:.1f} cm); foot skating {100 * rep.foot_skating:.1f} "
        f"cm/s while standing (natural {100 * rep.natural_foot_skating:.1f} cm/s)",
        f"goal reach (straight line at the median walking speed, {rep.walking_speed:.2f} m/s):",
    ]
    outcomes = goal_outcomes(rep.goals)
    served = [g for g in rep.goals if g.became_current]
    for g, outcome in zip(served, outcomes):
        where = ", ".join(f"{v:g}" for v in g.target)
        took = "not reached" if g.seconds is None else f"{g.seconds:.1f} s = {g.ratio:.2f}x"
        lines.append(
            f"  goal {g.goal} ({where}): {g.distance_m:.1f} m{' behind' if g.behind else ''}, "
            f"straight {g.straight_seconds:.1f} s, took {took}{_goal_note(g, outcome)}"
        )
    if len(served) < len(rep.goals):
        why = (
            "missed: the course stalled before them"
            if outcomes[len(served)] == MISSED
            else "not judged: the strip ended first"
        )
        lines.append(
            f"  {_goal_numbers(len(served) + 1, len(rep.goals))}: never became current ({why})"
        )
    verdict = {True: "met", False: "NOT met", None: "not measured"}
    lines.append(
        "aims: "
        + "; ".join(
            f"{k}: {verdict[v]}" + (f" ({_reach_tally(outcomes)})" if k == REACH_AIM else "")
            for k, v in rep.aims.items()
        )
    )
    return "\n".join(lines)


def _selection_max(rep: Report) -> str:
    """The walk's slowest selection, the first and the last beside it."""
    return (
        f"selection max {_ms(rep.latency_ms_max)} ms (first {_ms(rep.latency_ms_first)} ms, "
        f"last {_ms(rep.latency_ms_last)} ms)"
    )


def _goal_note(g: GoalReach, outcome: str) -> str:
    if outcome == NOT_JUDGED:
        return " (still current when the strip ended, before 2x: not judged)"
    if outcome == MISSED:
        return " (missed: over 2x)" if g.reached else " (missed: not reached)"
    if g.behind:
        return " (behind: its time reported only)"
    if g.distance_m < REACH_MIN_DISTANCE:
        return " (nearer than 5 m: its time reported only)"
    return ""


def _goal_numbers(first: int, last: int) -> str:
    return f"goal {first}" if first == last else f"goals {first}-{last}"


def _reach_tally(outcomes: list[str]) -> str:
    """How many goals of those judged were reached (within 2x where that counts), and how many
    were not judged."""
    judged = [o for o in outcomes if o != NOT_JUDGED]
    if not judged:
        return f"none of {len(outcomes)} goals judged: the strip ended first"
    tally = f"{judged.count(REACHED)} of {len(judged)} goals reached"
    if len(judged) < len(outcomes):
        tally += f"; {len(outcomes) - len(judged)} more not judged: the strip ended first"
    return tally


def write_report_json(
    path: str, result: Synthesis, rep: Report, sources: StripSources, allow_stdout: bool = False
) -> None:
    """The choices and figures as JSON, written through open_output (`-`: standard output if
    `allow_stdout`)."""
    data = {
        "report": rep.as_json(),
        "sources": {"shares": as_meta(sources), "crossings": sources.crossings},
        "chain": [
            {
                **{
                    k: getattr(c, k)
                    for k in (
                        "step",
                        "snippet_id",
                        "clip_id",
                        "version",
                        "mirrored",
                        "first_frame",
                        "n_frames",
                        "fps",
                        "goal",
                        "target",
                        "reached",
                        "relax_level",
                        "continuity",
                        "proximity",
                        "latency_ms",
                        "waited_ms",
                    )
                },
                "start_time": c.start_frame / c.fps,
                "position": c.placement.position,
                "heading": c.placement.heading,
                "end_position": c.end.position,
                "end_heading": c.end.heading,
            }
            for c in result.chain
        ],
    }
    with open_output(path, allow_stdout=allow_stdout) as f:
        json.dump(
            data, f, indent=1, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o)
        )
        f.write("\n")


def print_progress(total: float) -> Callable[[float], None]:
    bar = tqdm(
        total=round(total, 1),
        unit="s",
        file=sys.stderr,
        bar_format="{l_bar}{bar}| {n:.1f}/{total} s",
    )

    def update(done: float) -> None:
        bar.update(round(min(done, total) - bar.n, 1))
        if done >= total:
            bar.close()

    return update


def format_model_report(figures: dict, server_report: dict) -> str:
    """`modb synth --models --report`: the steps and the figures against the source's."""
    lines = [f"graph of models {figures['graph']} (seed {figures['seed']}): "
             f"{figures['steps']} steps, {figures['seconds']:.1f} s"]  # fmt: skip
    for s in server_report["steps"]:
        if s.get("rest") or s.get("action"):
            continue  # a piece of standing (the line after the goals says from when), an action
        lines.append(
            f"  frame {s['first_frame']:>6}  {s['node']:<14} goal {s['goal'] or '-'}  constraint "
            f"error {100 * s['error_m']:5.1f} cm (tree {100 * s['tree_error_m']:5.1f}, best of 300 "
            f"random {100 * s['random_error_m']:5.1f})"
        )
    for g in figures["goals"]:
        when = (f"reached in {g['seconds']:.1f} s ({g['ratio']:.2f}x the straight line)"
                if g["reached"] else f"not reached (closest {g['closest_m']:.2f} m)")  # fmt: skip
        x, z = g["target"]
        what = (f"the place of {g['action']} ({x:.2f}, {z:.2f})" if g.get("action")
                else f"goal {g['goal']} ({x:g}, {z:g})")  # fmt: skip
        lines.append(f"{what}, {g['distance_m']:.1f} m away: {when}")
    lines += [action_line(a) for a in server_report.get("actions", [])]
    c = figures["constraint_error_median"]
    lines += [
        f"constraint error, median: {100 * c['refined_m']:.1f} cm (tree alone "
        f"{100 * c['tree_m']:.1f}, best of 300 random draws {100 * c['best_of_300_random_m']:.1f})",
        f"worst pose jump {100 * figures['pose_jump_max']:.1f} cm per frame (source p99.9 "
        f"{100 * figures['source_pose_jump_p999']:.1f})",
        f"stance-foot sliding {100 * figures['stance_sliding']:.1f} cm/s (source "
        f"{100 * figures['source_stance_sliding']:.1f}); foot skating while low "
        f"{100 * figures['foot_skating']:.1f} cm/s "
        f"(source {100 * figures['source_foot_skating']:.1f})",
    ]
    if figures["stood_from_seconds"] is not None:
        lines.append(f"stands in its last pose from {figures['stood_from_seconds']:.1f} s")
    if figures.get("rested_from_seconds") is not None:
        lines.append(f"comes to rest at {figures['rested_from_seconds']:.1f} s and stands, idling")
    lines += [f"aim {'met' if ok else 'MISSED' if ok is False else 'not judged'}: {aim}"
              for aim, ok in figures["aims"].items()]  # fmt: skip
    return "\n".join(lines)


def action_line(a: dict) -> str:
    """An action's line: where and when, and the hand's error after each stage."""
    def cm(key: str) -> str:
        return "-" if a.get(key) is None else f"{100 * a[key]:.1f}"

    where = "" if a.get("target") is None else " at ({:g}, {:g}, {:g})".format(*a["target"])
    if a.get("keyframe_frame") is None:  # a repeated motion (a wave): it faces the point
        return (f"action {a['action']} facing{where[3:]}: frames {a['first_frame']}-"
                f"{a['first_frame'] + a['n_frames'] - 1}, {a.get('repeats', 1)} pass(es)"
                + ("; cut by the end of the strip" if a.get("cut") else ""))
    line = (f"action {a['action']}{where}: frame {a['first_frame']}, keyframe "
            f"{a.get('keyframe_frame', '-')}; hand error {cm('tree_error_m')} cm after the tree, "
            f"{cm('refined_error_m')} after refinement, {cm('placed_error_m')} as placed, "
            f"{cm('ik_error_m')} after IK")
    if a.get("reachable") is False:
        line += f"; out of reach: the nearest point reached, {cm('unreached_m')} cm short"
    return line + ("; cut by the end of the strip" if a.get("cut") else "")


def write_model_report_json(path: str, figures: dict, server_report: dict) -> None:
    with open_output(path, "w", allow_stdout=True) as f:
        f.write(json.dumps({"report": figures, "steps": server_report["steps"]}, indent=2) + "\n")
