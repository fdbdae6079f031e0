"""`modb split CLIP --by-annotation`: a clip per annotated segment, on the source's frames."""

from __future__ import annotations

import argparse
import sys

from . import as_job
from .common import connect


def add_parser(sub: argparse._SubParsersAction) -> None:
    split = sub.add_parser(
        "split",
        help="cut a clip into a clip per annotated segment (no snippets of their own: the "
        "source's cover those frames)",
    )
    split.add_argument("clip", metavar="CLIP", help="clip id, name, or collection/name")
    split.add_argument(
        "--by-annotation",
        action="store_true",
        required=True,
        help="cut at the current version's annotation segments (the one way to split so far)",
    )
    split.add_argument("--only", metavar="NAME", help="only the segments named NAME")
    split.add_argument(
        "--collection", metavar="PATH", help="where the new clips go (default: the source's)"
    )
    as_job.add_options(split, "split")  # a split itself is quick: it waits for nothing else
    split.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    # numpy, and the loader's snippet cutting (90 ms): not for `modb --help`
    from modb.clips import ClipNotFound, resolve_clip
    from modb.editing.catalog import split_by_annotation

    with connect(args) as conn:
        try:
            clip_id = resolve_clip(conn, args.clip)
        except ClipNotFound as e:
            print(f"modb split: {e}", file=sys.stderr)
            return 2
        if args.background or args.after:
            if not as_job.usable(conn, args, "split", "0.20.0"):
                return 2
            arguments = {"clips": [clip_id], "annotation": args.only, "collection": args.collection}
            return as_job.run(conn, args, "split", "split_by_annotation", arguments) or 0
        with conn.transaction():
            segments = split_by_annotation(conn, clip_id, args.only, args.collection)
    if not segments:
        print(
            f"modb split: clip {clip_id} has no annotation segments"
            + (f" named {args.only!r}" if args.only else "")
            + " (`modb annotate CLIP --segment NAME:START-END` adds one)",
            file=sys.stderr,
        )
        return 1
    made = sum(s.created for s in segments)
    print(f"clip {clip_id}: {len(segments)} segment clips ({made} new)")
    for s in segments:
        frames = s.last_frame - s.first_frame + 1
        print(
            f"  {s.clip_id}  {s.name}  ({s.annotation}, frames {s.first_frame}-{s.last_frame}, "
            f"{frames} frames){'' if s.created else '  (kept)'}"
        )
    return 0
