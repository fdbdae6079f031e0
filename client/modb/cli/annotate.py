"""`modb annotate`: a clip version's annotation segments (named frame ranges): list, add, remove."""

from __future__ import annotations

import argparse
import sys

from modb.editing.meta import MetaNotFound, StaleMeta, read_meta, write_meta
from modb.loader.annotations import (
    AnnotationError,
    checked,
    parse_segment,
    segments_of,
    with_segments,
)

from .common import VERSION, connect


def add_parser(sub: argparse._SubParsersAction) -> None:
    annotate = sub.add_parser(
        "annotate", help="list, add or remove a clip's annotation segments (named frame ranges)"
    )
    annotate.add_argument("clip", metavar="CLIP", help="clip id, name, or collection/name")
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
    annotate.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from modb.clips import ClipNotFound, resolve_clip  # numpy (60 ms): not for `modb --help`

    with connect(args) as conn:
        try:
            stored = read_meta(conn, resolve_clip(conn, args.clip), args.version)
            segments = segments_of(stored.meta)
            for spec in args.remove:
                gone = parse_segment(spec) if ":" in spec else None
                kept = [s for s in segments if (s != gone if gone else s.name != spec)]
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
        print(f"  {s.name}:{s.start}-{s.end}")
    return 0
