"""`modb list`: the stored clips, newest versions; with --skeletons, the skeletons and their joint
maps."""

from __future__ import annotations

import argparse

from .common import connect


def add_parser(sub: argparse._SubParsersAction) -> None:
    lst = sub.add_parser("list", help="list stored clips (newest versions)")
    lst.add_argument(
        "--skeletons",
        action="store_true",
        help="list the stored skeletons instead, each with its joint map (standard name: joint)",
    )
    lst.set_defaults(func=run)


def _skeletons(args: argparse.Namespace) -> int:
    from modb.motion import STANDARD_JOINTS

    with connect(args) as conn:
        rows = conn.execute(
            "SELECT s.id, s.name, s.joint_map, count(v.clip_id) FROM modb.skeletons s "
            "LEFT JOIN modb.clip_versions v ON v.skeleton_id = s.id GROUP BY s.id ORDER BY s.id"
        ).fetchall()
    if not rows:
        print("no skeletons stored yet: `modb load PATH` loads BVH files")
        return 0
    for skeleton_id, name, joint_map, versions in rows:
        print(f"{skeleton_id:>6}  {name} ({versions} clip versions)")
        mapped = [f"{s}: {joint_map[s]}" for s in STANDARD_JOINTS if s in joint_map]
        missing = [s for s in STANDARD_JOINTS if s not in joint_map]
        print("        " + ", ".join(mapped))
        if missing:
            print("        not mapped: " + ", ".join(missing))
    print(f"{len(rows)} skeletons")
    return 0


def run(args: argparse.Namespace) -> int:
    if getattr(args, "skeletons", False):
        return _skeletons(args)
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
