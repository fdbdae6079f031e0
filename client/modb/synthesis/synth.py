"""A long strip synthesized toward goals (what `modb synth` writes) and its quality report as
figures; modb.cli.synth_report prints them."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import psycopg

from modb.clips import read_motion
from modb.motion import Motion
from modb.validation import checked_number

from .avatar import Avatar
from .chain import MAX_SECONDS, Choice, Frame, Goal, NoContinuation, Settings
from .quality import NaturalSteps, Report, measure

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


def clip_names(conn: psycopg.Connection, chain: Sequence[Choice]) -> dict[int, str]:
    return dict(
        conn.execute(
            "SELECT id, name FROM modb.clips WHERE id = ANY (%s)",
            [sorted({c.clip_id for c in chain})],
        ).fetchall()
    )
