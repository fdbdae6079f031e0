"""`modb bench select`: latency of select_next_snippet on the stored snippets, beside a sequential scan.

Both run the same seeded queries in the same session, alternating query by query; the sequential scan is
the same function with index scans switched off, so both must return the same snippet.
"""
from __future__ import annotations

import statistics
import time

import numpy as np
import psycopg


def _timed(conn: psycopg.Connection, sql: str, args: list) -> tuple[float, tuple]:
    t = time.perf_counter()
    row = conn.execute(sql, args, prepare=True).fetchone()
    return (time.perf_counter() - t) * 1000, row


def bench_select(conn: psycopg.Connection, queries: int, seed: int, profile: str) -> dict:
    ids = [r[0] for r in conn.execute("SELECT id FROM modb.snippets ORDER BY id").fetchall()]
    if not ids:
        raise RuntimeError("no snippets stored: `modb load` builds them (or SELECT modb.build_snippets())")
    rng = np.random.default_rng(seed)
    sql = "SELECT snippet_id, relax_level FROM modb.select_next_snippet(%s, %s, %s)"
    conn.execute(sql, [int(ids[0]), [0.0, 1.0], profile]).fetchone()  # first call: plans, PL/pgSQL caches
    index_ms, seq_ms, levels, mismatches = [], [], [], 0
    for _ in range(queries):
        args = [int(rng.choice(ids)), [float(v) for v in rng.uniform(-5, 5, size=2)], profile]
        a_ms, a = _timed(conn, sql, args)
        with conn.transaction():
            conn.execute("SET LOCAL enable_indexscan = off")
            conn.execute("SET LOCAL enable_bitmapscan = off")
            b_ms, b = _timed(conn, sql, args)
        index_ms.append(a_ms)
        seq_ms.append(b_ms)
        levels.append(a[1])
        mismatches += a[0] != b[0]
    size = conn.execute(
        "SELECT sum(pg_total_relation_size(c)) FROM unnest(ARRAY['modb.snippets', 'modb.terminators', "
        "'modb.snippet_sources']::regclass[]) AS c").fetchone()[0]
    return {"snippets": len(ids), "queries": queries, "index_ms": index_ms, "seq_ms": seq_ms, "levels": levels,
            "mismatches": mismatches, "bytes_per_snippet": size / len(ids)}


def report(result: dict, profile: str) -> str:
    def stats(ms):
        return statistics.median(ms), float(np.percentile(ms, 99))

    (i50, i99), (s50, s99) = stats(result["index_ms"]), stats(result["seq_ms"])
    ratios = [s / i for i, s in zip(result["index_ms"], result["seq_ms"])]
    share = {lvl: result["levels"].count(lvl) / len(result["levels"]) for lvl in sorted(set(result["levels"]))}
    return "\n".join([
        f"{result['snippets']:,} snippets, {result['queries']} seeded queries (random prev snippet, target within 5 m), "
        f"profile {profile!r}; {result['bytes_per_snippet']:,.0f} bytes per snippet (snippets, terminators and "
        f"their indexes).",
        "",
        "| plan | p50 ms | p99 ms |",
        "|---|---|---|",
        f"| select_next_snippet (GiST box) | {i50:.1f} | {i99:.1f} |",
        f"| same query, sequential scan (baseline) | {s50:.1f} | {s99:.1f} |",
        "",
        f"Median per-query speed-up over the sequential scan: {statistics.median(ratios):.1f}x. "
        f"Same snippet from both plans: {result['queries'] - result['mismatches']}/{result['queries']}. "
        "Relaxation levels chosen: " + ", ".join(f"{lvl}: {100 * v:.0f}%" for lvl, v in share.items()) + ".",
    ])
