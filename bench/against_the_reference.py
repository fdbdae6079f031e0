"""select_next_snippets (C) against select_next_snippets_reference (the 0.9.0 SQL, the rule) in one
psycopg session with the server's default settings, alternating call by call on the same seeded
arguments: p50 and p99 of each, the median per-call ratio, and that both return the same rows.

    .venv/bin/python bench/against_the_reference.py "host=/var/lib/modb/run dbname=modb_100000" 30
"""

import statistics
import sys
import time

import numpy as np
import psycopg


def main(dsn: str, n: int) -> None:
    conn = psycopg.connect(dsn, autocommit=True)
    ids = [r[0] for r in conn.execute("SELECT id FROM modb.snippets ORDER BY id")]
    rng = np.random.default_rng(5)
    fast, reference = [], []
    for _ in range(n):
        prev = int(rng.choice(ids))
        target = [float(v) for v in rng.uniform(-5, 5, 2)]
        rows = []
        for function, times in (
            ("select_next_snippets", fast),
            ("select_next_snippets_reference", reference),
        ):
            t = time.perf_counter()
            rows.append(
                conn.execute(
                    f"SELECT snippet_id, relax_level FROM modb.{function}(%s, %s, 1)",
                    [prev, target],
                ).fetchall()
            )
            times.append((time.perf_counter() - t) * 1000)
        assert rows[0] == rows[1], (prev, target, rows)
    ratio = statistics.median(b / a for a, b in zip(fast, reference))
    print(f"{len(ids):,} snippets, {n} calls each, one session with the server's defaults:")
    for name, times in (("select_next_snippets", fast), ("reference", reference)):
        print(f"{name}: p50 {statistics.median(times):.2f} p99 {np.percentile(times, 99):.2f} ms")
    print(f"median ratio reference / C {ratio:.1f}x; the same rows {n}/{n}")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 30)
