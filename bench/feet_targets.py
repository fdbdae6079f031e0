"""Issue 59's targets on a collection, both synthesis families, feet held (the default) and not:
stance sliding, the lowest toe against the capture's, swing clearance, pose jumps against the
capture's p99.9 and the share of frames over its p99, by the test's own kinematics and contact rule
(tests/support/feet_oracle.py), on two courses fixed before any tuning. A Markdown table.

    .venv/bin/python bench/feet_targets.py DSN COLLECTION GRAPH_OF_MODELS [CLIP_NAMES_LEFT_OUT]

CLIP_NAMES_LEFT_OUT: clips of the collection not in the capture judged against (comma-separated;
CMU 16's runs 16_08,16_57 beside its walks).
"""

import sys
from pathlib import Path

import psycopg

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from support.feet_oracle import Body, Capture  # noqa: E402

from modb.clips import read_motion  # noqa: E402
from modb.database import pgarray  # noqa: E402
from modb.synthesis.chain import Settings  # noqa: E402
from modb.synthesis.from_models import synthesize as synthesize_models  # noqa: E402
from modb.synthesis.synth import synthesize  # noqa: E402

COURSES = {"turns": [(0.0, 6.0), (5.0, 8.0), (5.0, 2.0)],
           "about-turns": [(0.0, 8.0), (1.0, 1.0), (2.0, 9.0), (3.0, 2.0)]}  # fmt: skip
SECONDS = 30.0


def main(dsn, collection, graph, left_out=""):
    names = [n for n in left_out.split(",") if n]
    with psycopg.connect(dsn, autocommit=True) as conn:
        pgarray.register(conn)
        rows = conn.execute(
            "SELECT c.clip_id, c.version FROM modb.current_clips c JOIN modb.clips k "
            "ON k.id = c.clip_id WHERE k.collection_id = ANY (modb.collection_subtree(%s)) "
            "AND k.name <> ALL (%s) ORDER BY 1", [collection, names]).fetchall()  # fmt: skip
        clips = [read_motion(conn, c, v) for c, v in rows]
        body = Body.of(clips[0].skeleton)
        capture = Capture.of(body, [(m.rotations, m.translations, m.fps) for m in clips])
        print(f"{collection}: {len(clips)} clips; capture: lowest toe {100 * capture.floor:.1f} cm,"
              " "
              f"sliding {100 * capture.sliding:.1f} cm/s, clearance {100 * capture.clearance:.1f} "
              f"cm, pose jump p99 {100 * capture.jump_p99:.1f} cm, p99.9 "
              f"{100 * capture.jump_p999:.1f} cm\n")  # fmt: skip
        print("| course | family | feet | sliding, x | toe below capture's, cm | clearance, x "
              "| worst jump, cm | over p99 |")
        print("|---|---|---|---|---|---|---|---|")
        for course, goals in COURSES.items():
            for family in ("motion matching", "models"):
                for hold in (False, True):
                    motion = strip(conn, family, collection, graph, goals, hold)
                    p = body.positions(motion.rotations, motion.translations)
                    f = capture.judge(body, p, motion.fps)
                    print(f"| {course} | {family} | {'held' if hold else 'seams only'} | "
                          f"{f['sliding_x']:.2f} | {f['dip_cm']:.1f} | {f['clearance_x']:.2f} | "
                          f"{f['jump_max_cm']:.1f} | {100 * f['above_p99']:.2f}% |")  # fmt: skip


def strip(conn, family, collection, graph, goals, hold):
    if family == "motion matching":
        settings = Settings(collection=collection, foot_hold=hold)
        return synthesize(conn, goals, SECONDS, settings).strip
    conn.execute("SELECT set_config('modb.foot_hold', %s, false)", ["on" if hold else "off"])
    return synthesize_models(conn, graph, goals, SECONDS).motion


if __name__ == "__main__":
    main(*sys.argv[1:])
