"""What the first select_next_snippet of a new session costs (issue 61: the block directory and the
resolved profile shared by the server where it preloads modb): 40 new sessions, each one seeded
request timed twice (the first call, then the same call again); their difference is what a new
session pays. The connection is not counted.

    .venv/bin/python bench/first_selection.py "host=$MODB_HOME/run user=postgres dbname=DB"
"""

from __future__ import annotations

import sys
import time

import numpy as np
import psycopg

CALL = "SELECT snippet_id FROM modb.select_next_snippet(%s, %s, 'default')"


def first_and_again(dsn: str, prev: int, target: list[float]) -> tuple[float, float]:
    with psycopg.connect(dsn, autocommit=True) as conn:
        times = []
        for _ in range(2):
            t = time.perf_counter()
            conn.execute(CALL, [prev, target]).fetchone()
            times.append((time.perf_counter() - t) * 1000)
    return times[0], times[1]


def main(dsn: str, sessions: int = 40, seed: int = 3) -> None:
    with psycopg.connect(dsn) as conn:
        ids = [r[0] for r in conn.execute("SELECT id FROM modb.snippets ORDER BY id")]
    rng = np.random.default_rng(seed)
    requests = [
        (int(rng.choice(ids)), [float(v) for v in rng.uniform(-5, 5, 2)]) for _ in range(sessions)
    ]
    first, again = (np.array(v) for v in zip(*(first_and_again(dsn, *r) for r in requests)))
    for name, values in (
        ("first call", first),
        ("same call again", again),
        ("difference", first - again),
    ):
        p50, p90 = np.percentile(values, [50, 90])
        print(f"{name}: p50 {p50:.2f}, p90 {p90:.2f}, max {values.max():.2f} ms ({len(values)})")


if __name__ == "__main__":
    main(sys.argv[1])
