"""A hand meeting a target (issue 63, item 4: modb_kernel.reach) over tests/test_reach.py's grid on
held-out Bandai raises: per target group, how often the wrist meets the target, the error after
IK, the pose checks (the tests' own FK) and the compute time.

    .venv/bin/python bench/reach_grid.py [--clips N]

Limits and the peak box from the first 60 clips of each raise (right, left, both hands); the
reach tried at the keyframe of N held-out clips each (default 10) at every grid target (the box's
centre, 10, 20 and 30 cm beyond it in six directions, 1.5 m above it). "by len": the target
within the arm's length less 2 cm of the shoulder. Errors in mm ("unmet mm": the median
distance of the nearest point reached); "past deg": the most a moved joint
turns past the examples' range (allowed: 10 degrees); "reversed": cases with an elbow bent past
straight (more than the clip itself); "jump/p99.9": the largest per-frame joint displacement over
the source clip's p99.9.
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from modb_kernel import reach

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from support import reach_grid as grid  # noqa: E402

GROUPS = ("inside", *grid.DIRECTIONS, "out of reach")


def run(clips):
    rows = []
    for name in grid.ACTIONS:
        action = grid.action(name)
        for motion in action.held_out[:clips]:
            frame = grid.keyframe(motion, action.sides)
            per_side = {s: action.targets(s) for s in action.sides}
            for k, (group, distance, _) in enumerate(per_side[action.sides[0]]):
                targets = {s: per_side[s][k][2] for s in action.sides}
                sk = motion.skeleton
                t0 = time.perf_counter()
                result = reach.reach(sk.parents, sk.offsets, sk.translated, sk.names,
                                     sk.joint_map, motion.rotations, motion.translations, frame,
                                     targets, limits=action.limits)  # fmt: skip
                seconds = time.perf_counter() - t0
                seen = grid.checks(motion, result, action.sides, frame, targets, action.limits)
                for s in action.sides:
                    rows.append({
                        "action": name, "group": group, "distance": distance,
                        "by_length": grid.reachable_by_length(motion, s, frame, targets[s]),
                        "met": result.met[s], "error": seen["error"][s],
                        "past": seen["past_range_deg"], "reversed": seen["least_bend_deg"] < -0.01,
                        "jump": seen["jump_m"] / seen["jump_bound_m"], "ms": seconds * 1e3,
                    })  # fmt: skip
    return rows


def table(rows):
    head = (
        "| group | n | by len | met | met/by len | met mm p50/max | unmet mm "
        "| past deg | reversed | jump/p99.9 | ms p50/p99 |"
    )
    lines = [head, "|" + "---|" * 11]
    for label, pick in [(g, lambda r, g=g: r["group"] == g) for g in GROUPS] + [
        ("all", lambda r: True)
    ]:
        rs = [r for r in rows if pick(r)]
        if not rs:
            continue
        met = [r["error"] * 1e3 for r in rs if r["met"]]
        unmet = [r["error"] * 1e3 for r in rs if not r["met"]]
        by_length = [r for r in rs if r["by_length"]]
        ms = np.array([r["ms"] for r in rs])
        lines.append(
            f"| {label} | {len(rs)} | {len(by_length)} | {len(met)} "
            f"| {sum(r['met'] for r in by_length)}/{len(by_length)} "
            f"| {_pair(met, '.2f')} | {_one(unmet)} | {max(r['past'] for r in rs):.1f} "
            f"| {sum(r['reversed'] for r in rs)} | {max(r['jump'] for r in rs):.2f} "
            f"| {np.median(ms):.0f}/{np.percentile(ms, 99):.0f} |"
        )
    return "\n".join(lines)


def _pair(values, fmt):
    if not values:
        return "-"
    return f"{np.median(values):{fmt}}/{max(values):{fmt}}"


def _one(values):
    return f"{np.median(values):.0f}" if values else "-"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clips", type=int, default=10, help="held-out clips per action")
    args = parser.parse_args()
    t0 = time.perf_counter()
    rows = run(args.clips)
    print(table(rows))
    print(f"\n{len(rows)} wrist targets, {time.perf_counter() - t0:.0f} s in all")


if __name__ == "__main__":
    main()
