"""`modb export`: a stored clip written as BVH."""

from __future__ import annotations

import argparse
import sys

from .common import connect, whole, writable, write_bvh_file

VERSION = whole(1, 2**31 - 1)  # clip versions are int


def add_parser(sub: argparse._SubParsersAction) -> None:
    export = sub.add_parser("export", help="write a clip as BVH")
    export.add_argument("clip", metavar="CLIP", help="clip id, name, or collection/name")
    export.add_argument(
        "--version", type=VERSION, dest="version", help="clip version (default: newest)"
    )
    export.add_argument(
        "--out",
        default="-",
        help="output file, - for standard output (the default); a device, FIFO or symlink's "
        "target is written into, a regular file replaced whole",
    )
    export.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from modb.clips import ClipNotFound, read_motion, resolve_clip

    if not writable("export", args.out):
        return 1
    with connect(args) as conn:
        try:
            motion = read_motion(conn, resolve_clip(conn, args.clip), args.version)
        except ClipNotFound as e:
            print(f"modb export: {e}", file=sys.stderr)
            return 1
    if not write_bvh_file("export", motion, args.out):
        return 1
    if args.out != "-":
        print(
            f"wrote {args.out}: clip {motion.name} version {motion.meta['version']}, "
            f"{motion.n_frames} frames at {motion.fps:g} fps",
            file=sys.stderr,
        )
    return 0
