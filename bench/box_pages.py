"""How much of the feature index a selection's level-0 box reads: EXPLAIN (ANALYZE, BUFFERS) of the
box query alone (`begin_features <@ match_box(...)`) for seeded previous snippets, reporting index
pages visited, rows found and the index scan's time. Pages visited do not depend on the machine's
load: compare index builds (operator classes, splits) with them.

    .venv/bin/python bench/box_pages.py "host=... dbname=..." [queries] [profile]
"""

import random
import sys

import numpy as np
import psycopg

BOX = (
    "SELECT modb.match_box(t.features, modb.match_plan(%s), 1.0)::text "
    "FROM modb.snippets s JOIN modb.terminators t ON t.id = s.end_terminator WHERE s.id = %s"
)
SCAN = (
    "EXPLAIN (ANALYZE, BUFFERS, FORMAT JSON) "
    "SELECT id FROM modb.snippets WHERE begin_features <@ %s::cube"
)


def nodes(plan: dict):
    yield plan
    for child in plan.get("Plans", []):
        yield from nodes(child)


def main(dsn: str, queries: int, profile: str) -> None:
    with psycopg.connect(dsn, autocommit=True) as conn:
        conn.execute("SET jit = off")
        # A wide box might otherwise be read by a sequential scan.
        conn.execute("SET enable_seqscan = off")
        ids = [r[0] for r in conn.execute("SELECT id FROM modb.snippets ORDER BY id")]
        index_pages = conn.execute(
            "SELECT pg_relation_size('modb.snippets_begin_features_idx') / 8192"
        ).fetchone()[0]
        rng = random.Random(1)
        pages, rows, ms = [], [], []
        for prev in (rng.choice(ids) for _ in range(queries)):
            box = conn.execute(BOX, [profile, prev]).fetchone()[0]
            plan = conn.execute(SCAN, [box]).fetchone()[0][0]["Plan"]
            scan = next(
                n for n in nodes(plan) if n.get("Index Name") == "snippets_begin_features_idx"
            )
            pages.append(scan["Shared Hit Blocks"] + scan["Shared Read Blocks"])
            rows.append(scan["Actual Rows"])
            ms.append(scan["Actual Total Time"])
    p = lambda v, q: np.percentile(v, q)  # noqa: E731
    print(
        f"{len(ids):,} snippets, index {index_pages:,} pages; {queries} level-0 boxes ({profile}): "
        f"pages visited p50 {p(pages, 50):.0f} p90 {p(pages, 90):.0f} max {max(pages)}; "
        f"rows p50 {p(rows, 50):.0f} p90 {p(rows, 90):.0f}; index scan p50 {p(ms, 50):.2f} ms, p90 "
        f"{p(ms, 90):.2f} ms"
    )


if __name__ == "__main__":
    main(
        sys.argv[1],
        int(sys.argv[2]) if len(sys.argv) > 2 else 40,
        sys.argv[3] if len(sys.argv) > 3 else "default",
    )
