"""select_next_snippet with 0.6.0's continuity ratio (SQL) against 0.7.0's (C), on the same queries.

0.6.0's SQL expression (as the upgrade script to 0.2.0 created it: no script changed it before
0.7.0) is put in place inside a transaction that is rolled back. Both run the same seeded queries in
one session, alternating query by query; each timed call follows one that plans it.

    .venv/bin/python bench/continuity_ratio_sql_vs_c.py "host=... dbname=..." 30
"""

import statistics
import sys
import time
from pathlib import Path

import numpy as np
import psycopg

from modb.database.connection import configure_for_selection

RELEASED = Path(__file__).resolve().parents[1] / "extension" / "sql" / "released"
FROZEN = RELEASED / "modb--0.1.0--0.2.0.sql"
QUERY = "SELECT snippet_id FROM modb.select_next_snippet(%s, %s)"


def sql_ratio() -> str:
    text = FROZEN.read_text()
    start = text.index("CREATE FUNCTION modb.continuity_ratio(a modb.terminators")
    return text[start : text.index("COMMENT ON FUNCTION modb.continuity_ratio(", start)].replace(
        "CREATE FUNCTION", "CREATE OR REPLACE FUNCTION", 1
    )


def main(dsn: str, queries: int) -> None:
    with psycopg.connect(dsn, autocommit=True) as conn:
        configure_for_selection(conn)
        ids = [r[0] for r in conn.execute("SELECT id FROM modb.snippets ORDER BY id")]
        rng = np.random.default_rng(7)
        requests = [
            (int(rng.choice(ids)), [float(v) for v in rng.uniform(-5, 5, 2)])
            for _ in range(queries)
        ]

        def timed(prev, target):
            conn.execute(QUERY, [prev, target], prepare=True).fetchone()
            t = time.perf_counter()
            row = conn.execute(QUERY, [prev, target], prepare=True).fetchone()
            return (time.perf_counter() - t) * 1000, row

        sql_ms, c_ms, same = [], [], 0
        for prev, target in requests:
            with conn.transaction():
                conn.execute(sql_ratio())
                ms, a = timed(prev, target)
                sql_ms.append(ms)
                raise psycopg.Rollback()
            ms, b = timed(prev, target)
            c_ms.append(ms)
            same += a == b
    print(
        f"{queries} queries: SQL ratio p50 {statistics.median(sql_ms):.1f} ms, p99 "
        f"{np.percentile(sql_ms, 99):.1f}; "
        f"C ratio p50 {statistics.median(c_ms):.1f} ms, p99 {np.percentile(c_ms, 99):.1f}; median "
        f"per-query "
        f"speed-up {statistics.median(x / y for x, y in zip(sql_ms, c_ms)):.1f}x; same snippet "
        f"{same}/{queries}"
    )


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]))
