"""`modb export`: a stored clip written as BVH."""

from __future__ import annotations

import argparse
import sys

from .common import connect, write_bvh_file


def add_parser(sub: argparse._SubParsersAction) -> None:
    export = sub.add_parser("export", help="write a clip as BVH")
    export.add_argument("clip", metavar="CLIP", help="clip id, name, or collection/name")
    export.add_argument(
        "--version", type=int, dest="version", help="clip version (default: newest)"
    )
    export.add_argument("--out", help="output file (default: standard output)")
    export.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from modb.bvh_export import write_bvh
    from modb.clips import ClipNotFound, read_motion, resolve_clip

    with connect(args) as conn:
        try:
            motion = read_motion(conn, resolve_clip(conn, args.clip), args.version)
        except ClipNotFound as e:
            print(f"modb export: {e}", file=sys.stderr)
            return 1
    if args.out in (None, "-"):
        write_bvh(motion, sys.stdout)
    else:
        if not write_bvh_file("export", motion, args.out):
            return 1
        print(
            f"wrote {args.out}: clip {motion.name} version {motion.meta['version']}, "
            f"{motion.n_frames} frames at {motion.fps:g} fps",
            file=sys.stderr,
        )
    return 0
