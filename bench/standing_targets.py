"""Issue 60's targets for graphs of models, measured the way the client's synth report measures
(modb.synthesis.from_models, against the capture the graph's models learnt from): after the last
goal the pelvis's drift from where it came to rest, how far apart the feet end, whether the body
keeps moving while it stands, the worst pose jump through the settle and idle against the capture's
p99.9; and the planner's goals (behind, beside) against 2x the straight line at the capture's pace.

    .venv/bin/python bench/standing_targets.py DSN GRAPH [GRAPH ...]
"""

import sys

import numpy as np
import psycopg

from modb.synthesis.from_models import Source, synthesize
from modb.synthesis.quality import pose_jumps

COURSE = [(0.0, 6.0), (-6.0, 8.0), (-6.0, 2.0)]
PLANNER = {"behind 4 m": (0.0, -4.0), "behind and aside": (1.0, -3.5),
           "1.5 m to the right": (-1.5, 0.3), "1 m to the left": (1.0, 0.0)}  # fmt: skip


def standing(strip, source) -> str:
    m, report = strip.motion, strip.report
    rested = report["rested_from_frame"]
    if rested is None or rested >= m.n_frames - 3 * m.fps:
        return "did not come to rest 3 s before the end: " + "; ".join(report["notes"])
    p = m.world_positions()
    at = {k: m.skeleton.index(v) for k, v in m.skeleton.joint_map.items()
          if v in m.skeleton.names}  # fmt: skip
    pelvis = p[rested:, at["pelvis"]][:, [0, 2]]
    drift = np.linalg.norm(pelvis - pelvis[0], axis=1).max()
    feet = np.linalg.norm((p[-1, at["left_ankle"]] - p[-1, at["right_ankle"]])[[0, 2]])
    last = p[-int(3 * m.fps):] - p[-int(3 * m.fps):, at["pelvis"]][:, None] * [1, 0, 1]
    moving = np.linalg.norm(last - last[0], axis=-1).max()
    walked = [s for s in report["steps"] if not s.get("rest")]
    settle = walked[-1]["first_frame"] + walked[-1]["n_frames"] - 1
    tail = m.__class__(m.skeleton, m.fps, m.rotations[settle:], m.translations[settle:], "tail")
    jump = pose_jumps(tail).max()
    return (f"rests at {rested / m.fps:.1f} s; pelvis drift {100 * drift:.1f} cm (<= 15); feet "
            f"{100 * feet:.0f} cm apart (<= 45); moves {100 * moving:.1f} cm in the last 3 s; "
            f"worst jump from the settle on {100 * jump:.1f} cm (p99.9 "
            f"{100 * source.natural.pose_jump_p999:.1f})")  # fmt: skip


def main() -> None:
    dsn, graphs = sys.argv[1], sys.argv[2:]
    with psycopg.connect(dsn) as conn:
        for graph in graphs:
            source = Source.of(conn, graph)
            strip = synthesize(conn, graph, COURSE, 40.0, 3)
            print(f"{graph}, course {COURSE}: {standing(strip, source)}")
            for name, goal in PLANNER.items():
                strip = synthesize(conn, graph, [goal], 14.0, 1)
                reached = strip.report["reached"].get("1")
                distance = float(np.hypot(*goal))
                limit = 2 * distance / source.walking_speed
                when = (f"reached in {reached / strip.motion.fps:.2f} s" if reached is not None
                        else "not reached")  # fmt: skip
                aim = f" (2x the straight line: {limit:.2f} s)" if distance >= 3 else ""
                print(f"  {name} {goal}: {when}{aim}; {standing(strip, source)}")


if __name__ == "__main__":
    main()
