"""`modb bench select`: select_next_snippet's latency on stored snippets, beside a sequential scan.

Both run the same seeded queries in the same session, alternating query by query; the sequential
scan is the same function with index scans switched off, so both must return the same snippet. With
--graph: level 0 from the graph's stored transitions beside the box (bench_select_graph).
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable

import numpy as np
import psycopg

from modb.database.connection import configure_for_selection

SELECT = "SELECT snippet_id, relax_level FROM modb.select_next_snippet(%s, %s, %s)"


def _p50_p99(ms: list[float]) -> tuple[float, float]:
    return statistics.median(ms), float(np.percentile(ms, 99))


def _timed(conn: psycopg.Connection, args: list) -> tuple[float, tuple]:
    t = time.perf_counter()
    row = conn.execute(SELECT, args, prepare=True).fetchone()
    return (time.perf_counter() - t) * 1000, row


Timed = Callable[[list], tuple[float, tuple]]


def _alternate(
    ids: list[int], queries: int, seed: int, profile: str, first: Timed, second: Timed
) -> tuple[list[float], list[float], list[int], int]:
    """Seeded queries, each run by `first` then `second`: their times and how their choices compare.

    A query is a random prev among ids and a target within 5 m. Returned: the times of each, the
    levels `first` chose, and how often the two chose different snippets.
    """
    rng = np.random.default_rng(seed)
    first_ms, second_ms, levels, mismatches = [], [], [], 0
    for _ in range(queries):
        args = [int(rng.choice(ids)), [float(v) for v in rng.uniform(-5, 5, size=2)], profile]
        a_ms, a = first(args)
        b_ms, b = second(args)
        first_ms.append(a_ms)
        second_ms.append(b_ms)
        levels.append(a[1])
        mismatches += a[0] != b[0]
    return first_ms, second_ms, levels, mismatches


def bench_select(conn: psycopg.Connection, queries: int, seed: int, profile: str) -> dict:
    ids = [r[0] for r in conn.execute("SELECT id FROM modb.snippets ORDER BY id").fetchall()]
    if not ids:
        raise RuntimeError(
            "no snippets stored: `modb load` builds them (or SELECT modb.build_snippets())"
        )
    conn.execute(
        SELECT, [int(ids[0]), [0.0, 1.0], profile]
    ).fetchone()  # first call: plans, PL/pgSQL caches

    def sequential(args: list) -> tuple[float, tuple]:
        with conn.transaction():
            conn.execute("SET LOCAL enable_indexscan = off")
            conn.execute("SET LOCAL enable_bitmapscan = off")
            return _timed(conn, args)

    index_ms, seq_ms, levels, mismatches = _alternate(
        ids, queries, seed, profile, lambda args: _timed(conn, args), sequential
    )
    size = conn.execute(
        "SELECT sum(pg_total_relation_size(c)) FROM unnest(ARRAY['modb.snippets', "
        "'modb.terminators', "
        "'modb.snippet_sources']::regclass[]) AS c"
    ).fetchone()[0]
    return {
        "snippets": len(ids),
        "queries": queries,
        "index_ms": index_ms,
        "seq_ms": seq_ms,
        "levels": levels,
        "mismatches": mismatches,
        "bytes_per_snippet": size / len(ids),
    }


def bench_select_graph(
    conn: psycopg.Connection, queries: int, seed: int, profile: str, graph: str
) -> dict:
    """From the graph's snippets: level 0 read from its stored transitions, against the same query
    on a copy of the graph that has none stored (made for the run, then dropped), so it searches the
    feature box. Generic plans, no JIT, no graph_lookahead nor cost-to-go (the box path has
    neither): both must return the same snippet."""
    ids = [
        r[0]
        for r in conn.execute(
            "SELECT s.snippet_id FROM modb.graph_snippets s JOIN modb.graphs g ON g.id = "
            "s.graph_id "
            "WHERE g.name = %s AND g.kind = 'transitions' ORDER BY 1",
            [graph],
        ).fetchall()
    ]
    if not ids:
        raise RuntimeError(
            f'no transition graph "{graph}" with snippets: `modb graph build {graph}` builds it'
        )
    box_graph = f"{graph} (bench select: no stored transitions)"
    with conn.transaction():
        conn.execute(
            "INSERT INTO modb.graph_names (name, kind) VALUES (%s, 'transitions')", [box_graph]
        )
        (copy_id,) = conn.execute(
            "INSERT INTO modb.graphs (name, kind, data) SELECT %s, kind, data - 'transition_key' "
            "FROM modb.graphs "
            "WHERE name = %s AND kind = 'transitions' RETURNING id",
            [box_graph, graph],
        ).fetchone()
        conn.execute(
            "INSERT INTO modb.graph_snippets (graph_id, snippet_id) SELECT %s, "
            "unnest(%s::bigint[])",
            [copy_id, ids],
        )
    try:
        configure_for_selection(conn)
        for name, value in (("modb.graph_lookahead", "off"), ("modb.graph_cost_to_go", "off")):
            conn.execute("SELECT set_config(%s, %s, false)", [name, value])
        conn.execute(SELECT, [int(ids[0]), [0.0, 1.0], profile], prepare=True).fetchone()

        def on(name: str) -> Timed:
            def run(args: list) -> tuple[float, tuple]:
                conn.execute("SELECT set_config('modb.graph', %s, false)", [name])
                return _timed(conn, args)

            return run

        stored_ms, box_ms, levels, mismatches = _alternate(
            ids, queries, seed, profile, on(graph), on(box_graph)
        )
    finally:
        conn.execute(
            "DELETE FROM modb.graph_names WHERE name = %s AND kind = 'transitions'", [box_graph]
        )
    size = conn.execute("SELECT pg_total_relation_size('modb.graph_transitions')").fetchone()[0]
    return {
        "snippets": len(ids),
        "queries": queries,
        "stored_ms": stored_ms,
        "box_ms": box_ms,
        "levels": levels,
        "mismatches": mismatches,
        "bytes_per_snippet": size / len(ids),
    }


def report_graph(result: dict, profile: str, graph: str) -> str:
    (a50, a99), (b50, b99) = _p50_p99(result["stored_ms"]), _p50_p99(result["box_ms"])
    ratios = [b / a for a, b in zip(result["stored_ms"], result["box_ms"])]
    return "\n".join(
        [
            f"transition graph {graph!r}: {result['snippets']:,} snippets, {result['queries']} "
            f"seeded queries from them "
            f"(target within 5 m), profile {profile!r}, generic plans, no JIT; its stored "
            f"transitions take "
            f"{result['bytes_per_snippet']:,.0f} bytes per snippet.",
            "",
            "| level 0 from | p50 ms | p99 ms |",
            "|---|---|---|",
            f"| the stored transitions | {a50:.1f} | {a99:.1f} |",
            f"| the GiST box (a copy of the graph without them; baseline) | {b50:.1f} | {b99:.1f} "
            f"|",
            "",
            f"Median per-query speed-up: {statistics.median(ratios):.1f}x. "
            f"Same snippet from both: "
            f"{result['queries'] - result['mismatches']}/{result['queries']}.",
        ]
    )


def report(result: dict, profile: str) -> str:
    (i50, i99), (s50, s99) = _p50_p99(result["index_ms"]), _p50_p99(result["seq_ms"])
    ratios = [s / i for i, s in zip(result["index_ms"], result["seq_ms"])]
    share = {
        lvl: result["levels"].count(lvl) / len(result["levels"])
        for lvl in sorted(set(result["levels"]))
    }
    return "\n".join(
        [
            f"{result['snippets']:,} snippets, {result['queries']} seeded queries (random prev "
            f"snippet, target within 5 m), "
            f"profile {profile!r}; {result['bytes_per_snippet']:,.0f} bytes per snippet (snippets, "
            f"terminators and "
            f"their indexes).",
            "",
            "| plan | p50 ms | p99 ms |",
            "|---|---|---|",
            f"| select_next_snippet (GiST box) | {i50:.1f} | {i99:.1f} |",
            f"| same query, sequential scan (baseline) | {s50:.1f} | {s99:.1f} |",
            "",
            f"Median per-query speed-up over the sequential scan: "
            f"{statistics.median(ratios):.1f}x. "
            f"Same snippet from both plans: "
            f"{result['queries'] - result['mismatches']}/{result['queries']}. "
            "Relaxation levels chosen: "
            + ", ".join(f"{lvl}: {100 * v:.0f}%" for lvl, v in share.items())
            + ".",
        ]
    )
