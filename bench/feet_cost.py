"""What holding the feet costs (issue 59): the same course synthesized with the hold and without, in
turns, both families, ROUNDS times each; medians and the ratio, wall seconds per second walked.

    .venv/bin/python bench/feet_cost.py DSN COLLECTION GRAPH_OF_MODELS [ROUNDS]
"""

import sys
import time

import numpy as np
import psycopg

from modb.database import pgarray
from modb.synthesis.chain import Settings
from modb.synthesis.from_models import synthesize as synthesize_models
from modb.synthesis.synth import synthesize

COURSE = [(0.0, 6.0), (5.0, 8.0), (5.0, 2.0)]
SECONDS = 20.0


def main(dsn, collection, graph, rounds="5"):
    with psycopg.connect(dsn, autocommit=True) as conn:
        pgarray.register(conn)
        times = {}
        for _ in range(int(rounds)):
            for hold in (False, True):
                t = time.perf_counter()
                synthesize(conn, COURSE, SECONDS, Settings(collection=collection, foot_hold=hold))
                times.setdefault(("motion matching", hold), []).append(time.perf_counter() - t)
                conn.execute("SELECT set_config('modb.foot_hold', %s, false)",
                             ["on" if hold else "off"])  # fmt: skip
                t = time.perf_counter()
                synthesize_models(conn, graph, COURSE, SECONDS)
                times.setdefault(("models", hold), []).append(time.perf_counter() - t)
    print("| family | seams only, s per s walked (p50 / max) | held | ratio of medians |")
    print("|---|---|---|---|")
    for family in ("motion matching", "models"):
        off, on = (np.array(times[(family, h)]) / SECONDS for h in (False, True))
        print(f"| {family} | {np.median(off):.3f} / {off.max():.3f} | {np.median(on):.3f} / "
              f"{on.max():.3f} | {np.median(on) / np.median(off):.2f} |")


if __name__ == "__main__":
    main(*sys.argv[1:])
