"""`modb list`: the stored clips, newest versions."""

from __future__ import annotations

import argparse

from .common import connect


def add_parser(sub: argparse._SubParsersAction) -> None:
    lst = sub.add_parser("list", help="list stored clips (newest versions)")
    lst.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    with connect(args) as conn:
        rows = conn.execute(
            "SELECT clip_id, collection, name, version, n_frames, fps, round(seconds::numeric, 1) "
            "FROM modb.current_clips ORDER BY collection, name"
        ).fetchall()
    if not rows:
        print("no clips stored yet: `modb load PATH` loads BVH files")
        return 0
    print(f"{'id':>6}  {'version':>7}  {'frames':>7}  {'fps':>5}  {'seconds':>7}  clip")
    for clip_id, collection, name, version, n_frames, fps, seconds in rows:
        print(
            f"{clip_id:>6}  {version:>7}  {n_frames:>7}  {fps:>5g}  {seconds:>7}  "
            f"{collection}/{name}"
        )
    print(f"{len(rows)} clips, {sum(r[4] for r in rows):,} frames")
    return 0
