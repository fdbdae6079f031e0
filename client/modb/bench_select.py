"""`modb bench select`: latency of select_next_snippet on the stored snippets, beside a sequential scan.

Both run the same seeded queries in the same session, alternating query by query; the sequential scan is
the same function with index scans switched off, so both must return the same snippet.
"""
from __future__ import annotations

import statistics
import time

import numpy as np
import psycopg


def _p50_p99(ms: list[float]) -> tuple[float, float]:
    return statistics.median(ms), float(np.percentile(ms, 99))


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


def bench_select_graph(conn: psycopg.Connection, queries: int, seed: int, profile: str, graph: str) -> dict:
    """From the graph's snippets: level 0 read from its stored transitions, against the same query on a copy
    of the graph that has none stored (made for the run, then dropped), so it searches the feature box.
    Generic plans, no JIT, no graph_lookahead (the box path has none): both must return the same snippet."""
    ids = [r[0] for r in conn.execute(
        "SELECT s.snippet_id FROM modb.graph_snippets s JOIN modb.graphs g ON g.id = s.graph_id "
        "WHERE g.name = %s AND g.kind = 'transitions' ORDER BY 1", [graph]).fetchall()]
    if not ids:
        raise RuntimeError(f'no transition graph "{graph}" with snippets: `modb graph build {graph}` builds it')
    box_graph = f"{graph} (bench select: no stored transitions)"
    with conn.transaction():
        (copy_id,) = conn.execute(
            "INSERT INTO modb.graphs (name, kind, data) SELECT %s, kind, data - 'transition_key' FROM modb.graphs "
            "WHERE name = %s AND kind = 'transitions' RETURNING id", [box_graph, graph]).fetchone()
        conn.execute("INSERT INTO modb.graph_snippets (graph_id, snippet_id) SELECT %s, unnest(%s::bigint[])",
                     [copy_id, ids])
    try:
        for name, value in (("plan_cache_mode", "force_generic_plan"), ("jit", "off"),
                            ("modb.graph_lookahead", "off")):
            conn.execute("SELECT set_config(%s, %s, false)", [name, value])
        rng = np.random.default_rng(seed)
        sql = "SELECT snippet_id, relax_level FROM modb.select_next_snippet(%s, %s, %s)"
        use = "SELECT set_config('modb.graph', %s, false)"
        conn.execute(sql, [int(ids[0]), [0.0, 1.0], profile], prepare=True).fetchone()
        stored_ms, box_ms, levels, mismatches = [], [], [], 0
        for _ in range(queries):
            args = [int(rng.choice(ids)), [float(v) for v in rng.uniform(-5, 5, size=2)], profile]
            conn.execute(use, [graph])
            a_ms, a = _timed(conn, sql, args)
            conn.execute(use, [box_graph])
            b_ms, b = _timed(conn, sql, args)
            stored_ms.append(a_ms)
            box_ms.append(b_ms)
            levels.append(a[1])
            mismatches += a[0] != b[0]
    finally:
        conn.execute("DELETE FROM modb.graphs WHERE id = %s", [copy_id])
    size = conn.execute("SELECT pg_total_relation_size('modb.graph_transitions')").fetchone()[0]
    return {"snippets": len(ids), "queries": queries, "stored_ms": stored_ms, "box_ms": box_ms, "levels": levels,
            "mismatches": mismatches, "bytes_per_snippet": size / len(ids)}


def report_graph(result: dict, profile: str, graph: str) -> str:
    (a50, a99), (b50, b99) = _p50_p99(result["stored_ms"]), _p50_p99(result["box_ms"])
    ratios = [b / a for a, b in zip(result["stored_ms"], result["box_ms"])]
    return "\n".join([
        f"transition graph {graph!r}: {result['snippets']:,} snippets, {result['queries']} seeded queries from them "
        f"(target within 5 m), profile {profile!r}, generic plans, no JIT; its stored transitions take "
        f"{result['bytes_per_snippet']:,.0f} bytes per snippet.",
        "",
        "| level 0 from | p50 ms | p99 ms |",
        "|---|---|---|",
        f"| the stored transitions | {a50:.1f} | {a99:.1f} |",
        f"| the GiST box (a copy of the graph without them; baseline) | {b50:.1f} | {b99:.1f} |",
        "",
        f"Median per-query speed-up: {statistics.median(ratios):.1f}x. "
        f"Same snippet from both: {result['queries'] - result['mismatches']}/{result['queries']}.",
    ])


def report(result: dict, profile: str) -> str:
    (i50, i99), (s50, s99) = _p50_p99(result["index_ms"]), _p50_p99(result["seq_ms"])
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
