"""`modb retarget SOURCE... --to SKELETON`: clips onto another skeleton, as new clips, one
transaction per clip: a job (computed by a worker, or by this process when none runs) where the
database has job tables, else modb.retarget in the server."""

from __future__ import annotations

import argparse
import sys

from tqdm import tqdm

from . import as_job
from .common import FPS, connect


def add_parser(sub: argparse._SubParsersAction) -> None:
    retarget = sub.add_parser(
        "retarget",
        help="retarget clips onto another skeleton (new clips, linked to their source)",
    )
    retarget.add_argument(
        "sources",
        nargs="+",
        metavar="SOURCE",
        help="a clip (id, name, collection/name) or a collection",
    )
    retarget.add_argument(
        "--to",
        required=True,
        metavar="SKELETON",
        help="a skeleton id, or a clip whose skeleton to use",
    )
    retarget.add_argument(
        "--collection", help="where the new clips go (default: SOURCE_COLLECTION on skeleton N)"
    )
    retarget.add_argument(
        "--fps", type=FPS, help="frame rate (default: the rate most of the skeleton's clips have)"
    )
    retarget.add_argument("--mirror", action="store_true", help="cut mirrored snippets too")
    retarget.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    as_job.add_options(retarget, "retarget")
    retarget.set_defaults(func=run)


def _skeleton(conn, spec: str) -> int:
    from modb.clips import resolve_clip  # numpy (60 ms): not for `modb --help`

    if (
        spec.isdigit()
        and conn.execute("SELECT 1 FROM modb.skeletons WHERE id = %s", [int(spec)]).fetchone()
    ):
        return int(spec)
    clip = resolve_clip(conn, spec)
    return conn.execute(
        "SELECT skeleton_id FROM modb.current_clips WHERE clip_id = %s", [clip]
    ).fetchone()[0]


def _made(source: int, made: dict) -> str:
    return (
        f"clip {source} -> {made['clip']} (clip {made['clip_id']} version {made['version']}, "
        f"{made['n_frames']} frames at {made['fps']:g} fps, {made['snippets']} snippets)"
    )


def run(args: argparse.Namespace) -> int:
    from modb.clips import ClipNotFound, clips_in  # numpy (60 ms): not for `modb --help`
    from modb.jobs.clip_jobs import clip_now

    with connect(args) as conn:
        try:
            skeleton = _skeleton(conn, args.to)
            # A clip named twice, or named and in a named collection, is retargeted once.
            clips = list(dict.fromkeys(c for spec in args.sources for c in clips_in(conn, spec)))
        except ClipNotFound as e:
            print(f"modb retarget: {e}", file=sys.stderr)
            return 2
        as_a_job = as_job.usable(conn, args, "retarget", "0.20.0")
        if as_a_job is None:
            return 2
        if as_a_job:
            arguments = {"clips": clips, "skeleton": skeleton, "collection": args.collection,
                         "fps": args.fps, "mirrored": args.mirror}  # fmt: skip
            done = as_job.run(conn, args, "retarget", "retarget", arguments)
            if done is None or isinstance(done, int):
                return done or 0
            if not args.quiet:
                for made in done.result["clips"]:
                    print(_made(made["source"], made))
                print(f"{len(clips)} clips retargeted onto skeleton {skeleton}")
            return 0
        with tqdm(clips, unit="clip", disable=args.quiet or len(clips) < 2, file=sys.stderr) as bar:
            for clip in bar:
                with conn.transaction():
                    (made,) = conn.execute(
                        "SELECT modb.retarget(%s, %s, %s, %s, %s)",
                        [clip, skeleton, args.collection, args.fps, args.mirror],
                    ).fetchone()
                if not args.quiet:
                    bar.write(_made(clip, clip_now(conn, made)))
    if not args.quiet:
        print(f"{len(clips)} clips retargeted onto skeleton {skeleton}")
    return 0
