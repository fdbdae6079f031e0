"""select_next_snippet in two databases holding the same snippets under different extension versions
(say a copy kept at 0.7.0 and one updated to 0.8.0), on the same seeded queries, alternating query
by query, each on its own prepared, generic-plan connection: the latency of each, the median
per-query ratio, and whether both chose the same snippet.

    .venv/bin/python bench/versions_ab.py "host=... dbname=old" "host=... dbname=new" 100
"""

import random
import statistics
import sys
import time

import numpy as np
import psycopg

from modb.database.connection import configure_for_selection

QUERY = "SELECT snippet_id, relax_level FROM modb.select_next_snippet(%s, %s)"


def session(dsn: str) -> psycopg.Connection:
    conn = psycopg.connect(dsn, autocommit=True)
    configure_for_selection(conn)
    return conn


def main(old_dsn: str, new_dsn: str, queries: int) -> None:
    old, new = session(old_dsn), session(new_dsn)
    ids = [r[0] for r in new.execute("SELECT id FROM modb.snippets ORDER BY id")]
    if ids != [r[0] for r in old.execute("SELECT id FROM modb.snippets ORDER BY id")]:
        sys.exit("the two databases do not hold the same snippets: compare copies of one database")
    versions = [
        c.execute("SELECT extversion FROM pg_extension WHERE extname = 'modb'").fetchone()[0]
        for c in (old, new)
    ]
    rng = random.Random(1)
    seeded = [(rng.choice(ids), [rng.uniform(-5, 5), rng.uniform(-5, 5)]) for _ in range(queries)]
    times: dict[str, list[float]] = {"old": [], "new": []}
    same = 0
    for conn in (old, new):
        conn.execute(QUERY, seeded[0], prepare=True).fetchall()  # plan once before timing
    for k, (prev, target) in enumerate(seeded):
        chosen = {}
        pair = (("old", old), ("new", new))
        for name, conn in pair if k % 2 == 0 else pair[::-1]:  # which goes first alternates too
            start = time.perf_counter()
            chosen[name] = conn.execute(QUERY, [prev, target], prepare=True).fetchall()
            times[name].append((time.perf_counter() - start) * 1e3)
        same += chosen["old"] == chosen["new"]
    for name, version in zip(("old", "new"), versions):
        print(
            f"{version}: p50 {statistics.median(times[name]):.2f} ms, p99 "
            f"{np.percentile(times[name], 99):.2f} ms"
        )
    ratios = [a / b for a, b in zip(times["old"], times["new"])]
    print(
        f"median per-query {versions[0]} / {versions[1]}: {statistics.median(ratios):.1f}x; "
        f"same snippet and level: {same}/{queries}"
    )


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]) if len(sys.argv) > 3 else 100)
