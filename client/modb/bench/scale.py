"""`modb bench scale` (make bench): select_next_snippet at several database sizes, beside in the
same run
(a) the paper's formulation: one flat query scoring every snippet (no box, so no index: a
    sequential scan), its continuity ratio by modb.continuity_ratio, the C function the tests tie
    to 0.6.0's arithmetic over the terminator columns to the last bit (that arithmetic in SQL is
    about 4.5x slower: the ratio to (a) here is the conservative one) (the same rows as the
    function),
(b) a vectorised numpy brute force in this process over the same stored terminators (the same
    rows),
(c) scipy's cKDTree in this process (the box as a Chebyshev ball of the scaled features) plus one
    `SELECT 1` round trip: what an in-memory index in the client costs (the same rows).
(a), (b) and (c) are in modb.bench.baselines. The index is rebuilt (REINDEX, timed) before the
queries, so every size is measured on a fresh build. Also: candidates examined per query
(modb.candidates_examined), the GiST index's build time and size, bytes per snippet, and
throughput with pgbench and the shipped script at 1, 2 and 8 clients.
"""

from __future__ import annotations

import os
import re
import statistics
import subprocess
import time
from pathlib import Path

import numpy as np
import psycopg


from .baselines import FLAT, Snapshot
from .resampled import add_resampled_clips, resampled_snippets
from modb.database.connection import configure_for_selection, connect, selection_pgoptions

PGBENCH = "/usr/lib/postgresql/15/bin/pgbench"  # postgresql-15's own (Debian keeps it off PATH)
PGBENCH_SCRIPT = Path(__file__).with_name("select_next_snippet.pgbench")  # package data
FUNCTION = "SELECT snippet_id, relax_level FROM modb.select_next_snippet(%s, %s, %s)"


def _with_dbname(dsn: str, name: str) -> str:
    return psycopg.conninfo.make_conninfo(dsn, dbname=name)


def sized_database(dsn: str, size: int, seed: int, progress=print) -> str:
    """A copy of the database at `dsn` with about `size` snippets, made once and kept; its conninfo.

    Smaller: whole clips drawn in a seeded order, compacted as after a load of that size. Larger:
    speed-resampled copies of its clips added (modb.bench.resampled; an interrupted run resumes).
    """
    source = psycopg.conninfo.conninfo_to_dict(dsn).get("dbname") or "modb"
    name = f"{source}_{size}"
    with psycopg.connect(_with_dbname(dsn, "postgres"), autocommit=True) as admin:
        made = (
            admin.execute("SELECT 1 FROM pg_database WHERE datname = %s", [name]).fetchone() is None
        )
        if made:
            # Needs no other session on the source.
            admin.execute(f'CREATE DATABASE "{name}" TEMPLATE "{source}"')
    with connect(_with_dbname(dsn, name)) as conn:
        clips = conn.execute(
            "SELECT clip_id, count(*) FROM modb.snippets GROUP BY clip_id ORDER BY clip_id"
        ).fetchall()
        # Resample into a database made now, or an interrupted run's.
        if size > sum(n for _, n in clips) and (made or resampled_snippets(conn)):
            progress(f"  adding speed-resampled copies of the clips up to {size:,} snippets (once)")
            add_resampled_clips(conn, size, seed, progress)
            conn.execute("VACUUM ANALYZE modb.snippets, modb.terminators")
        elif made:
            order = np.random.default_rng(seed).permutation(len(clips))
            kept, total = set(), 0
            for k in order:
                if total + clips[k][1] <= size:
                    kept.add(clips[k][0])
                    total += clips[k][1]
            conn.execute("DELETE FROM modb.clips WHERE NOT id = ANY (%s)", [sorted(kept)])
            conn.execute("VACUUM (FULL, ANALYZE) modb.snippets")
            conn.execute("VACUUM (FULL, ANALYZE) modb.terminators")
    return _with_dbname(dsn, name)


def pgbench(dsn: str, clients: int, seconds: int) -> float:
    """Selections per second: the shipped script, prepared, with generic plans and no JIT.

    Each call draws a random prev and target.
    """
    with psycopg.connect(dsn) as conn:
        low, high = conn.execute("SELECT min(id), max(id) FROM modb.snippets").fetchone()
    env = {**os.environ, "PGOPTIONS": selection_pgoptions()}
    out = subprocess.run(
        [
            PGBENCH,
            "-n",
            "-M",
            "prepared",
            "-T",
            str(seconds),
            "-c",
            str(clients),
            "-j",
            str(min(clients, 2)),
            "-f",
            str(PGBENCH_SCRIPT),
            "-D",
            f"low={low}",
            "-D",
            f"high={high}",
            dsn,
        ],  # pgbench takes a conninfo string where a database name goes
        capture_output=True,
        text=True,
        env=env,
    )
    if out.returncode != 0:
        raise RuntimeError(f"pgbench failed: {out.stderr.strip()}")
    out = out.stdout
    return float(re.search(r"tps = ([0-9.]+) \(without initial connection time\)", out).group(1))


def bench_database(
    dsn: str,
    queries: int,
    baseline_queries: int,
    seed: int,
    profile: str,
    pgbench_seconds: int,
    progress=print,
) -> dict:
    """Every figure of one database (see the module's docstring)."""
    with psycopg.connect(dsn, autocommit=True) as conn:
        configure_for_selection(conn)
        progress("  reading the snippets into memory (for numpy and the k-d tree)")
        t = time.perf_counter()
        snap = Snapshot.load(conn, profile)
        load_s = time.perf_counter() - t
        t = time.perf_counter()
        conn.execute("REINDEX INDEX modb.snippets_begin_features_idx")
        index_s = time.perf_counter() - t
        rng = np.random.default_rng(seed)
        requests = [
            (int(rng.choice(snap.ids)), [float(v) for v in rng.uniform(-5, 5, size=2)])
            for _ in range(queries)
        ]
        conn.execute(
            FUNCTION, [requests[0][0], requests[0][1], profile], prepare=True
        ).fetchone()  # plans once
        out = {
            k: []
            for k in ("function_ms", "flat_ms", "numpy_ms", "kdtree_ms", "candidates", "levels")
        }
        same_flat = same_numpy = same_kdtree = 0
        progress(f"  {queries} seeded queries ({baseline_queries} also by the flat query)")
        for k, (prev, target) in enumerate(requests):
            t = time.perf_counter()
            chosen = conn.execute(FUNCTION, [prev, target, profile], prepare=True).fetchone()
            out["function_ms"].append((time.perf_counter() - t) * 1000)
            out["levels"].append(chosen[1])
            out["candidates"].append(
                conn.execute(
                    "SELECT modb.candidates_examined(%s, %s, %s)",
                    [prev, chosen[1], profile],
                    prepare=True,
                ).fetchone()[0]
            )
            t = time.perf_counter()
            mine = snap.brute_force(prev, target)
            out["numpy_ms"].append((time.perf_counter() - t) * 1000)
            same_numpy += mine == tuple(chosen)
            t = time.perf_counter()
            tree_choice = snap.kd_tree(prev, target)
            conn.execute("SELECT 1", prepare=True).fetchone()
            out["kdtree_ms"].append((time.perf_counter() - t) * 1000)
            same_kdtree += tree_choice == tuple(chosen)
            if k < baseline_queries:
                t = time.perf_counter()
                flat = conn.execute(
                    FLAT, {"prev": prev, "target": target, "profile": profile}, prepare=True
                ).fetchone()
                out["flat_ms"].append((time.perf_counter() - t) * 1000)
                same_flat += tuple(flat) == tuple(chosen)
        resampled = resampled_snippets(conn)
        index_bytes, table_bytes = conn.execute(
            "SELECT pg_relation_size('modb.snippets_begin_features_idx'), "
            "sum(pg_total_relation_size(c)) "
            "FROM unnest(ARRAY['modb.snippets', 'modb.terminators', "
            "'modb.snippet_sources']::regclass[]) AS c"
        ).fetchone()
    progress("  pgbench")
    tps = {c: pgbench(dsn, c, pgbench_seconds) for c in (1, 2, 8)}
    return {
        **out,
        "snippets": len(snap.ids),
        "resampled": resampled,
        "same_flat": same_flat,
        "same_numpy": same_numpy,
        "same_kdtree": same_kdtree,
        "baseline_queries": baseline_queries,
        "queries": queries,
        "index_s": index_s,
        "index_bytes": index_bytes,
        "bytes_per_snippet": table_bytes / len(snap.ids),
        "snapshot_s": load_s,
        "tps": tps,
    }


def report(name: str, r: dict) -> str:
    def row(label: str, ms: list[float]) -> str:
        return f"| {label} | {statistics.median(ms):.2f} | {np.percentile(ms, 99):.2f} |"

    n = r["baseline_queries"]
    flat_ratio = (
        statistics.median(a / b for a, b in zip(r["flat_ms"], r["function_ms"][:n]))
        if n
        else float("nan")
    )
    kd_ratio = statistics.median(a / b for a, b in zip(r["function_ms"], r["kdtree_ms"]))
    np_ratio = statistics.median(a / b for a, b in zip(r["function_ms"], r["numpy_ms"]))
    c = r["candidates"]
    levels = {lvl: r["levels"].count(lvl) for lvl in sorted(set(r["levels"]))}
    return "\n".join(
        [
            f"### {name}: {r['snippets']:,} snippets",
            "",
            *(
                [
                    f"{r['resampled']:,} of them are speed-resampled copies of the real clips "
                    "(modb.bench.resampled).",
                    "",
                ]
                if r["resampled"]
                else []
            ),
            "| | p50 ms | p99 ms |",
            "|---|---|---|",
            row("select_next_snippet (prepared, generic plan)", r["function_ms"]),
            row(f"(a) flat query, sequential scan ({n} of the queries)", r["flat_ms"])
            if n
            else "| (a) | - | - |",
            row("(b) numpy brute force, in process", r["numpy_ms"]),
            row("(c) cKDTree in process + SELECT 1", r["kdtree_ms"]),
            "",
            f"- Per query, median: (a) / function {flat_ratio:.1f}x; function / (b) "
            f"{np_ratio:.2f}x; "
            f"function / (c) {kd_ratio:.2f}x.",
            f"- Same snippet and level as the function: (a) {r['same_flat']}/{n}, (b) "
            f"{r['same_numpy']}/{r['queries']}, "
            f"(c) {r['same_kdtree']}/{r['queries']}.",
            f"- Candidates examined: p50 {np.percentile(c, 50):.0f}, p90 "
            f"{np.percentile(c, 90):.0f}, "
            f"p99 {np.percentile(c, 99):.0f}, max {max(c)}; relaxation levels {levels}.",
            f"- GiST index: {r['index_bytes'] / 2**20:.1f} MiB, rebuilt in {r['index_s']:.1f} s; "
            f"{r['bytes_per_snippet']:,.0f} bytes per snippet (snippets, terminators, sources and "
            f"their indexes).",
            "- pgbench (shipped script, prepared): "
            + ", ".join(f"{k} client{'s' if k > 1 else ''} {v:,.0f}/s" for k, v in r["tps"].items())
            + ".",
        ]
    )


def bench_scale(
    dsn: str,
    sizes: list[int | None],
    queries: int,
    baseline_queries: int,
    seed: int,
    profile: str,
    pgbench_seconds: int,
    progress=print,
) -> list[tuple[str, dict]]:
    """Every size (None: the database at `dsn` itself, all it holds), smallest first."""
    out = []
    for size in sizes:
        where = dsn if size is None else sized_database(dsn, size, seed, progress)
        name = "all the data" if size is None else f"about {size:,}"
        progress(f"{name}:")
        out.append(
            (
                name,
                bench_database(
                    where, queries, baseline_queries, seed, profile, pgbench_seconds, progress
                ),
            )
        )
    return out
