"""`modb annotate`: a clip version's annotation segments (named frame ranges): list, add, remove;
`--steps` finds the steps of clips and collections (modb.annotate_steps; a job where the database
has job tables), `--action NAME` the action done standing in each (modb.annotate_action)."""

from __future__ import annotations

import argparse
import sys

import psycopg

from modb.editing.meta import MetaNotFound, StaleMeta, read_meta, write_meta
from modb.loader.annotations import (
    AnnotationError,
    checked,
    parse_segment,
    segments_of,
    with_segments,
)

from . import as_job
from .common import VERSION, connect


def add_parser(sub: argparse._SubParsersAction) -> None:
    annotate = sub.add_parser(
        "annotate", help="list, add or remove a clip's annotation segments (named frame ranges)"
    )
    annotate.add_argument(
        "sources",
        nargs="+",
        metavar="CLIP",
        help="clip id, name, or collection/name (with --steps or --action: clips and collections)",
    )
    annotate.add_argument("--version", type=VERSION, help="clip version (default: newest)")
    annotate.add_argument(
        "--segment",
        action="append",
        default=[],
        metavar="NAME:START-END",
        help="add a segment: frames START to END (0-based, inclusive, as stored); repeatable",
    )
    annotate.add_argument(
        "--remove",
        action="append",
        default=[],
        metavar="NAME",
        help="remove every segment named NAME (or NAME:START-END: that one); repeatable",
    )
    annotate.add_argument(
        "--steps",
        action="store_true",
        help="find the steps from the feet's contacts: left_step and right_step segments, and "
        "turning steps, starts, stops and idle where the clip has them, marked "
        "automatic (a run again replaces those, never a person's)",
    )
    annotate.add_argument(
        "--action",
        metavar="NAME",
        help="find the action done standing (a reach or a wave) in each clip: a segment NAME "
        "with its keyframes and hands, and idle for a standing lead-in and lead-out, marked "
        "automatic (a run again replaces those, never a person's)",
    )
    annotate.add_argument(
        "-q", "--quiet", action="store_true", help="with --steps or --action: no progress"
    )
    as_job.add_options(annotate, "with --steps or --action")
    annotate.set_defaults(func=run)


Found = list[tuple[int, int | None, dict[str, int]]]  # per clip: id, version, count per primitive


def find_steps(conn: psycopg.Connection, args: argparse.Namespace, clips: list[int]) -> Found | int:
    """The steps of the clips, found as a job where the database runs them (args: --background,
    --after, -q, as `modb annotate --steps` takes them), else here; an exit status when there is
    nothing to print (queued) or it failed (said why)."""
    as_a_job = as_job.usable(conn, args, "annotate --steps", "0.21.0")
    if as_a_job is None:
        return 2
    if as_a_job:
        done = as_job.run(conn, args, "annotate --steps", "annotate_steps", {"clips": clips})
        if done is None or isinstance(done, int):
            return done or 0
        return [(c["clip_id"], c["version"], c["steps"]) for c in done.result["clips"]]
    found = []
    for clip in clips:
        with conn.transaction():
            rows = conn.execute(
                "SELECT version, name FROM modb.annotate_steps(%s)", [clip]
            ).fetchall()
        counts = dict.fromkeys(STEPS, 0)
        for _, name in rows:
            counts[name] = counts.get(name, 0) + 1
        found.append((clip, rows[0][0] if rows else None, counts))
    return found


def totals(found: Found) -> str:
    """What was found, summed over the clips: '419 clips: 2059 left_step, ...'."""
    kinds = list(STEPS) + sorted({n for _, _, c in found for n in c} - set(STEPS))
    summed = {n: sum(c.get(n, 0) for _, _, c in found) for n in kinds}
    return f"{len(found)} clips: " + ", ".join(f"{summed[n]} {n}" for n in kinds)


def sources(conn: psycopg.Connection, args: argparse.Namespace) -> list[int] | None:
    """The clips of the SOURCE arguments, each once (None, said why, when one names nothing)."""
    from modb.clips import ClipNotFound, clips_in

    try:
        return list(dict.fromkeys(c for spec in args.sources for c in clips_in(conn, spec)))
    except ClipNotFound as e:
        print(f"modb annotate: {e}", file=sys.stderr)
        return None


def steps(args: argparse.Namespace) -> int:
    with connect(args) as conn:
        clips = sources(conn, args)
        if clips is None:
            return 2
        found = find_steps(conn, args, clips)
    if isinstance(found, int):
        return found
    kinds = list(STEPS) + sorted({n for _, _, c in found for n in c} - set(STEPS))
    for clip, version, counts in found:
        print(
            f"clip {clip}" + (f" version {version}" if version else "") + ": "
            + ", ".join(f"{counts[n]} {n}" for n in kinds if counts.get(n) or n in STEPS)
        )  # fmt: skip
    print(totals(found))
    return 0


STEPS = ("left_step", "right_step")  # always counted; the other primitives where found


def find_action(conn: psycopg.Connection, args: argparse.Namespace, clips: list[int]
                ) -> list[dict] | int:  # fmt: skip
    """The action of each clip, found as a job where the database runs them, else here (each clip
    in its transaction): per clip {clip_id, version, segments}; an exit status when queued or
    refused (said why)."""
    as_a_job = as_job.usable(conn, args, "annotate --action", "0.29.0")
    if as_a_job is None:
        return 2
    if as_a_job:
        arguments = {"clips": clips, "action": args.action}
        done = as_job.run(conn, args, "annotate --action", "annotate_action", arguments)
        if done is None or isinstance(done, int):
            return done or 0
        return done.result["clips"]
    found = []
    for clip in clips:
        try:
            with conn.transaction():
                rows = conn.execute(
                    "SELECT version, name, start_frame, end_frame, keyframes, hands, kind "
                    "FROM modb.annotate_action(%s, %s)", [clip, args.action]
                ).fetchall()  # fmt: skip
        except psycopg.Error as e:
            hint = e.diag.message_hint
            print(f"modb annotate: {e.diag.message_primary or e}" + (f"\n  {hint}" if hint else ""),
                  file=sys.stderr)  # fmt: skip
            return 1
        found.append({"clip_id": clip, "version": rows[0][0] if rows else None, "segments": [
            {"name": n, "start": a, "end": b, "keyframes": k, "hands": h, "kind": kind}
            for _, n, a, b, k, h, kind in rows]})  # fmt: skip
    return found


def action(args: argparse.Namespace) -> int:
    with connect(args) as conn:
        clips = sources(conn, args)
        if clips is None:
            return 2
        found = find_action(conn, args, clips)
    if isinstance(found, int):
        return found
    kinds: dict[str, int] = {}
    for clip in found:
        parts = []
        for s in clip["segments"]:
            if s["name"] == args.action:
                kinds[s["kind"]] = kinds.get(s["kind"], 0) + 1
                parts.insert(0, f"{s['name']} {s['start']}-{s['end']} ({s['kind']}, "
                             f"{' and '.join(s['hands'])} hand{'s' if len(s['hands']) > 1 else ''}"
                             f"), keyframes {','.join(map(str, s['keyframes']))}")  # fmt: skip
            else:
                parts.append(f"{s['name']} {s['start']}-{s['end']}")
        if not args.quiet:
            print(f"clip {clip['clip_id']} version {clip['version']}: " + "; ".join(parts))
    print(f"{len(found)} clips: " + ", ".join(f"{n} {k}" for k, n in sorted(kinds.items())))
    return 0


def run(args: argparse.Namespace) -> int:
    from modb.clips import ClipNotFound, resolve_clip  # numpy (60 ms): not for `modb --help`

    if args.action is not None:
        if args.steps or args.segment or args.remove or args.version:
            print("modb annotate: --action goes alone (no --steps, --segment, --remove, --version)",
                  file=sys.stderr)  # fmt: skip
            return 2
        return action(args)
    if args.steps:
        if args.segment or args.remove or args.version:
            print("modb annotate: --steps goes alone (no --segment, --remove, --version)",
                  file=sys.stderr)  # fmt: skip
            return 2
        return steps(args)
    if len(args.sources) != 1:
        print("modb annotate: name one clip (several go with --steps or --action)",
              file=sys.stderr)  # fmt: skip
        return 2
    with connect(args) as conn:
        try:
            stored = read_meta(conn, resolve_clip(conn, args.sources[0]), args.version)
            segments = segments_of(stored.meta)
            for spec in args.remove:
                gone = parse_segment(spec) if ":" in spec else None
                kept = [
                    s
                    for s in segments
                    if ((s.start, s.end, s.name) != (gone.start, gone.end, gone.name) if gone
                        else s.name != spec)
                ]  # fmt: skip
                if len(kept) == len(segments):
                    raise AnnotationError(f"no segment {spec!r} to remove")
                segments = kept
            added = [parse_segment(spec) for spec in args.segment]
            segments = checked([*segments, *added], stored.n_frames)
            if args.segment or args.remove:
                meta = with_segments(stored.meta, segments)
                stored = write_meta(conn, stored.clip_id, stored.version, meta, stored.etag)
        except (ClipNotFound, MetaNotFound, AnnotationError, StaleMeta) as e:
            print(f"modb annotate: {e}", file=sys.stderr)
            return 2
    print(
        f"clip {stored.clip_id} version {stored.version} ({stored.n_frames} frames): "
        f"{len(segments)} segment{'' if len(segments) == 1 else 's'}"
    )
    for s in segments:
        extra = (f"  keyframes {','.join(map(str, s.keyframes))}" if s.keyframes else "") + (
            "  (found automatically)" if s.auto else "")  # fmt: skip
        print(f"  {s.name}:{s.start}-{s.end}{extra}")
    return 0
