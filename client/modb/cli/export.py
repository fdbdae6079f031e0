"""`modb export`: a stored clip written as BVH or glTF."""

from __future__ import annotations

import argparse
import dataclasses
import sys

from .common import FPS, VERSION, connect, motion_format, writable, write_motion_file


def add_parser(sub: argparse._SubParsersAction) -> None:
    export = sub.add_parser("export", help="write a clip as BVH or glTF")
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
    export.add_argument(
        "--format",
        choices=["bvh", "gltf"],
        help="bvh, or gltf (a skinned character with the animation; .gltf JSON, else .glb "
        "binary); default: by the --out name (.glb, .gltf), else bvh",
    )
    export.add_argument("--fps", type=FPS, help=f"resample to this frame rate ({FPS.span})")
    export.add_argument(
        "--root-motion",
        action="store_true",
        help="carry the travel on the top joint as engines take it (default: the source's own "
        "layout)",
    )
    export.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    # numpy and scipy (about 260 ms): not for `modb --help`
    from modb.clips import ClipNotFound, read_motion, resolve_clip
    from modb.provenance import as_meta, strip_sources
    from modb.resample import at_fps
    from modb.synthesis.root_motion import with_root_motion

    if not writable("export", args.out):
        return 1
    with connect(args) as conn:
        try:
            clip_id = resolve_clip(conn, args.clip)
            motion = read_motion(conn, clip_id, args.version)
        except ClipNotFound as e:
            print(f"modb export: {e}", file=sys.stderr)
            return 1
        # a clip cut at a segment has its source version's frames: that version's origin
        cut = motion.meta.get("cut_from")
        version = (cut["clip_id"], cut["version"]) if cut else (clip_id, motion.meta["version"])
        sources = as_meta(strip_sources(conn, [version]))
    motion = dataclasses.replace(motion, meta={**motion.meta, "sources": sources})
    if args.root_motion:
        motion = with_root_motion(motion)
    if args.fps:
        motion = at_fps(motion, args.fps)
    if not write_motion_file("export", motion, args.out, motion_format(args.out, args.format)):
        return 1
    if args.out != "-":
        print(
            f"wrote {args.out}: clip {motion.name} version {motion.meta['version']}, "
            f"{motion.n_frames} frames at {motion.fps:g} fps",
            file=sys.stderr,
        )
    return 0
