"""`modb synth`: a long strip toward goals, written as one BVH, with a quality report."""

from __future__ import annotations

import contextlib
import json
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import psycopg

from .avatar import Avatar
from .chain import (
    MAX_COORDINATE,
    MAX_SECONDS,
    Choice,
    Frame,
    Goal,
    NoContinuation,
    Settings,
    checked_goal,
    checked_number,
)
from modb.bvh_export import open_output
from modb.clips import read_motion
from modb.motion import Motion
from .quality import REACH_MIN_DISTANCE, NaturalSteps, Report, measure

WALKING_SPEEDS = (0.3, 2.5)  # m/s: snippets slower are standing, faster are running


@dataclass
class Synthesis:
    strip: Motion
    chain: list[Choice]
    goals: list[Goal]
    stopped: str | None = None  # why the strip ended before `seconds`, if it did
    collection: str | None = None  # drawn from (the database's choice when not given)
    notes: list[str] = field(default_factory=list)  # what the database chose, and why


def strip_motion(frames: Sequence[Frame], template: Motion, name: str) -> Motion:
    """The frames as a Motion on the first snippet's skeleton and rate (chains never mix them)."""
    return Motion(
        skeleton=template.skeleton,
        fps=template.fps,
        rotations=np.stack([f.rotations for f in frames]),
        translations=np.stack([f.translations for f in frames]),
        name=name,
        meta={"synthesized": True},
    )


def synthesize(
    conn: psycopg.Connection,
    goals: Sequence[Goal],
    seconds: float,
    settings: Settings,
    start_snippet: int | None = None,
    progress: Callable[[float], None] | None = None,
) -> Synthesis:
    """Frames until the strip lasts at least `seconds` (whole snippets).

    It ends early, saying why, when the database has nothing to play next (as modb.synthesize does).
    `seconds` is more than 0 and at most MAX_SECONDS (an hour): the strip is kept in memory.
    """
    seconds = checked_number("seconds", seconds, 0.0, MAX_SECONDS, above=True, unit="seconds")
    avatar = Avatar(conn, goals=goals, start_snippet=start_snippet, settings=settings)
    frames: list[Frame] = []
    stopped = None
    with contextlib.closing(avatar.frames()) as playing:
        try:
            for frame in playing:
                frames.append(frame)
                last = avatar.choices[-1]
                if frame.index == last.end_frame:
                    if progress:
                        progress(last.end_frame / last.fps)
                    if last.end_frame / last.fps >= seconds:
                        break
        except NoContinuation as e:
            if not avatar.choices:
                raise
            stopped = str(e)
    first = avatar.choices[0]
    template = avatar.library.get(first.clip_id, first.version, first.mirrored).motion
    return Synthesis(
        strip_motion(frames, template, "synthesized"),
        avatar.choices,
        list(goals),
        stopped,
        avatar.collection,
        avatar.notes,
    )


def _scope(collection: str | None) -> tuple[str, list]:
    """SQL condition on snippets s: in the collection, same poses and rate as the chain's first."""
    return (
        "s.pose_key = f.pose_key AND s.fps = f.fps AND NOT s.mirrored"
        " AND (%s::text IS NULL OR s.collection_id = ANY (modb.collection_subtree(%s)))",
        [collection, collection],
    )


def source_motions(
    conn: psycopg.Connection, first_snippet: int, collection: str | None
) -> list[Motion]:
    """The clips the chain could draw from (as captured): the scale of natural roughness."""
    condition, params = _scope(collection)
    rows = conn.execute(
        f"SELECT DISTINCT s.clip_id, s.version FROM modb.snippets s, modb.snippets f "
        f"WHERE f.id = %s AND {condition} ORDER BY 1, 2",
        [first_snippet, *params],
    ).fetchall()
    return [read_motion(conn, clip_id, version) for clip_id, version in rows]


def median_walking_speed(
    conn: psycopg.Connection, first_snippet: int, collection: str | None
) -> float:
    condition, params = _scope(collection)
    (speed,) = conn.execute(
        f"SELECT percentile_cont(0.5) WITHIN GROUP (ORDER BY v) FROM ("
        f"  SELECT sqrt(s.net_translation[1] ^ 2 + s.net_translation[3] ^ 2) / ((s.n_frames - 1) / "
        f"s.fps) AS v"
        f"    FROM modb.snippets s, modb.snippets f WHERE f.id = %s AND {condition}) x "
        f"WHERE v BETWEEN %s AND %s",
        [first_snippet, *params, *WALKING_SPEEDS],
    ).fetchone()
    if speed is None:
        raise ValueError("the source has no walking snippets to measure goal reach against")
    return float(speed)


def report(conn: psycopg.Connection, result: Synthesis) -> Report:
    first, collection = result.chain[0].snippet_id, result.collection
    natural = NaturalSteps.of(source_motions(conn, first, collection))
    return measure(
        result.strip,
        result.chain,
        result.goals,
        natural,
        median_walking_speed(conn, first, collection),
    )


def _ms(value: float | None) -> str:
    return "-" if value is None else f"{value:.1f}"


def clip_names(conn: psycopg.Connection, chain: Sequence[Choice]) -> dict[int, str]:
    return dict(
        conn.execute(
            "SELECT id, name FROM modb.clips WHERE id = ANY (%s)",
            [sorted({c.clip_id for c in chain})],
        ).fetchall()
    )


def format_report(result: Synthesis, rep: Report, names: dict[int, str]) -> str:
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
    return "\n".join(lines) + "\n\n" + format_summary(result, rep)


def format_summary(result: Synthesis, rep: Report) -> str:
    """The quality figures, goal by goal reach, and which aims are met."""
    lines = [
        f"strip: {rep.seconds:.1f} s, {rep.snippets} snippets, {rep.seams} seams"
        + (f" (ended early: {result.stopped})" if result.stopped else ""),
        f"query latency: p50 {_ms(rep.latency_ms_p50)} ms, p99 {_ms(rep.latency_ms_p99)} ms",
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
    served = [g for g in rep.goals if g.goal <= max(c.goal for c in result.chain)]
    for g in served:
        where = ", ".join(f"{v:g}" for v in g.target)
        took = "not reached" if g.seconds is None else f"{g.seconds:.1f} s = {g.ratio:.2f}x"
        note = (
            ""
            if g.counts_for_aim
            else " (behind: reported only)"
            if g.behind
            else " (nearer than 5 m: reported only)"
            if g.distance_m < REACH_MIN_DISTANCE
            else " (still current when the strip ended, before 2x: not counted)"
        )
        lines.append(
            f"  goal {g.goal} ({where}): {g.distance_m:.1f} m{' behind' if g.behind else ''}, "
            f"straight {g.straight_seconds:.1f} s, took {took}{note}"
        )
    if len(served) < len(rep.goals):
        lines.append(
            f"  goals {len(served) + 1}-{len(rep.goals)}: never became current (not reached)"
        )
    verdict = {True: "met", False: "NOT met", None: "not measured"}
    lines.append("aims: " + "; ".join(f"{k}: {verdict[v]}" for k, v in rep.aims.items()))
    return "\n".join(lines)


def write_report_json(
    path: str, result: Synthesis, rep: Report, allow_stdout: bool = False
) -> None:
    """The choices and figures as JSON, written through open_output (`-`: standard output if
    `allow_stdout`)."""
    data = {
        "report": rep.as_json(),
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


def parse_goal(text: str) -> Goal:
    """'X,Z' (or 'X,Y,Z') world metres."""
    try:
        return checked_goal(text.split(","))
    except ValueError:
        raise ValueError(
            f"--to {text!r:.200}: expected X,Z in metres (each at most {MAX_COORDINATE:,.0f} "
            f"from the origin), e.g. --to 3,-4"
        ) from None


def print_progress(total: float) -> Callable[[float], None]:
    from tqdm import tqdm

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
