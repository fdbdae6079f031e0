"""`modb bench scale` (make bench): select_next_snippet at several database sizes, as a user calls
it (the server's default settings: psql one call per statement, psycopg with and without prepare,
the first call of a new session), beside in the same run
(a) the paper's formulation: one flat query scoring every snippet (no box, so no index: a
    sequential scan), its continuity ratio by modb.continuity_ratio (the same rows as the function),
(b) a vectorised numpy brute force in this process over the same stored terminators (the same
    rows),
(c) scipy's cKDTree in this process (the box as a Chebyshev ball of the scaled features) plus one
    `SELECT 1` round trip: what an in-memory index in the client costs (the same rows),
(d) a vectorised numpy test of the level-0 box against every snippet of the pose, plus one round
    trip: the least an in-process scan of the same data does (no continuity check, no objective).
(a)-(d) are in modb.bench.baselines. The databases are measured as the loader left them (no REINDEX
or VACUUM). Also: the snippet blocks' size, bytes per snippet, and throughput with pgbench and the
shipped script at 1, 2 and 8 clients.
"""

from __future__ import annotations

import re
import statistics
import subprocess
import time
from pathlib import Path

import numpy as np
import psycopg


from .baselines import FLAT, Snapshot
from .resampled import add_resampled_clips, resampled_snippets
from modb.database.connection import connect
from modb.loader.ingest import PACK_SHARE, pack_blocks

PGBENCH = "/usr/lib/postgresql/15/bin/pgbench"  # postgresql-15's own (Debian keeps it off PATH)
PSQL = "/usr/lib/postgresql/15/bin/psql"
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
        conn.execute("ALTER EXTENSION modb UPDATE")  # a copy kept from an earlier release
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
        # As a load leaves them: packed (a new copy's blocks named the deleted clips' snippets too).
        pack_blocks(conn, 0.0 if made else PACK_SHARE)
    return _with_dbname(dsn, name)


def pgbench(dsn: str, clients: int, seconds: int, mode: str = "prepared") -> float:
    """Selections per second: the shipped script (-M mode), with the server's default settings.

    Each call draws a random prev and target.
    """
    with psycopg.connect(dsn) as conn:
        low, high = conn.execute("SELECT min(id), max(id) FROM modb.snippets").fetchone()
    out = subprocess.run(
        [
            PGBENCH,
            "-n",
            "-M",
            mode,
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
    )
    if out.returncode != 0:
        raise RuntimeError(f"pgbench failed: {out.stderr.strip()}")
    out = out.stdout
    return float(re.search(r"tps = ([0-9.]+) \(without initial connection time\)", out).group(1))


def psql_times(dsn: str, requests: list, profile: str) -> list[float]:
    """psql, one call per statement (\\timing: the client's time around each), default settings."""
    lines = ["\\timing on"] + [
        f"SELECT snippet_id, relax_level FROM modb.select_next_snippet({prev}, "
        f"'{{{target[0]!r}, {target[1]!r}}}', '{profile}');"
        for prev, target in requests
    ]
    out = subprocess.run(
        [PSQL, "-X", "-q", "-A", "-t", "-d", dsn],
        input="\n".join(lines),
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    return [float(m) for m in re.findall(r"^Time: ([0-9.]+) ms", out, re.M)]


def first_call_ms(dsn: str, requests: list, profile: str, sessions: int = 5) -> list[float]:
    """The first call in a new session (its connection opened before the clock starts)."""
    times = []
    for prev, target in requests[:sessions]:
        with psycopg.connect(dsn, autocommit=True) as conn:
            t = time.perf_counter()
            conn.execute(FUNCTION, [prev, target, profile]).fetchone()
            times.append((time.perf_counter() - t) * 1000)
    return times


def bench_database(
    dsn: str,
    queries: int,
    baseline_queries: int,
    seed: int,
    profile: str,
    pgbench_seconds: int,
    progress=print,
) -> dict:
    """Every figure of one database (see the module's docstring), with the server's defaults."""
    with (
        psycopg.connect(dsn, autocommit=True) as conn,
        psycopg.connect(dsn, autocommit=True) as prepared,
    ):
        progress("  reading the snippets into memory (for numpy and the k-d tree)")
        t = time.perf_counter()
        snap = Snapshot.load(conn, profile)
        load_s = time.perf_counter() - t
        rng = np.random.default_rng(seed)
        requests = [
            (int(rng.choice(snap.ids)), [float(v) for v in rng.uniform(-5, 5, size=2)])
            for _ in range(queries)
        ]
        out = {
            k: []
            for k in (
                "plain_ms",
                "prepared_ms",
                "flat_ms",
                "numpy_ms",
                "kdtree_ms",
                "scan_ms",
                "levels",
            )
        }
        progress("  the first call of new sessions")
        out["first_ms"] = first_call_ms(dsn, requests, profile)
        same_flat = same_numpy = same_kdtree = 0
        progress(f"  {queries} seeded queries ({baseline_queries} also by the flat query)")
        for k, (prev, target) in enumerate(requests):
            t = time.perf_counter()
            chosen = conn.execute(FUNCTION, [prev, target, profile], prepare=False).fetchone()
            out["plain_ms"].append((time.perf_counter() - t) * 1000)
            t = time.perf_counter()
            again = prepared.execute(FUNCTION, [prev, target, profile], prepare=True).fetchone()
            out["prepared_ms"].append((time.perf_counter() - t) * 1000)
            assert again == chosen, (prev, target)
            out["levels"].append(chosen[1])
            t = time.perf_counter()
            mine = snap.brute_force(prev, target)
            out["numpy_ms"].append((time.perf_counter() - t) * 1000)
            same_numpy += mine == tuple(chosen)
            t = time.perf_counter()
            tree_choice = snap.kd_tree(prev, target)
            conn.execute("SELECT 1", prepare=True).fetchone()
            out["kdtree_ms"].append((time.perf_counter() - t) * 1000)
            same_kdtree += tree_choice == tuple(chosen)
            t = time.perf_counter()
            snap.box_scan(prev)
            conn.execute("SELECT 1", prepare=True).fetchone()
            out["scan_ms"].append((time.perf_counter() - t) * 1000)
            if k < baseline_queries:
                t = time.perf_counter()
                flat = conn.execute(
                    FLAT, {"prev": prev, "target": target, "profile": profile}
                ).fetchone()
                out["flat_ms"].append((time.perf_counter() - t) * 1000)
                same_flat += tuple(flat) == tuple(chosen)
        resampled = resampled_snippets(conn)
        blocks_bytes, blocks, table_bytes = conn.execute(
            "SELECT pg_relation_size('modb.snippet_blocks'), "
            "(SELECT count(*) FROM modb.snippet_blocks), sum(pg_total_relation_size(c)) "
            "FROM unnest(ARRAY['modb.snippets', 'modb.terminators', 'modb.snippet_sources', "
            "'modb.snippet_blocks']::regclass[]) AS c"
        ).fetchone()
        (directory_bytes,) = conn.execute(  # this session's, after its calls
            "SELECT coalesce(sum(total_bytes), 0) FROM pg_backend_memory_contexts "
            "WHERE name = 'modb block directory'"
        ).fetchone()
    progress("  psql, one call per statement")
    out["psql_ms"] = psql_times(dsn, requests, profile)
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
        "blocks": blocks,
        "blocks_bytes": blocks_bytes,
        "directory_bytes": directory_bytes,
        "bytes_per_snippet": table_bytes / len(snap.ids),
        "snapshot_s": load_s,
        "tps": tps,
    }


def report(name: str, r: dict) -> str:
    def row(label: str, ms: list[float]) -> str:
        return f"| {label} | {statistics.median(ms):.3f} | {np.percentile(ms, 99):.3f} |"

    n = r["baseline_queries"]
    flat_ratio = (
        statistics.median(a / b for a, b in zip(r["flat_ms"], r["plain_ms"][:n]))
        if n
        else float("nan")
    )
    kd_ratio = statistics.median(a / b for a, b in zip(r["plain_ms"], r["kdtree_ms"]))
    np_ratio = statistics.median(a / b for a, b in zip(r["plain_ms"], r["numpy_ms"]))
    scan_ratio = statistics.median(a / b for a, b in zip(r["plain_ms"], r["scan_ms"]))
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
            "| select_next_snippet, server defaults | p50 ms | p99 ms |",
            "|---|---|---|",
            row("psql, one call per statement (\\timing)", r["psql_ms"]),
            row("psycopg, not prepared", r["plain_ms"]),
            row("psycopg, prepared", r["prepared_ms"]),
            row(f"first call of a new session ({len(r['first_ms'])} sessions)", r["first_ms"]),
            row(f"(a) flat query, sequential scan ({n} of the queries)", r["flat_ms"])
            if n
            else "| (a) | - | - |",
            row("(b) numpy brute force, in process", r["numpy_ms"]),
            row("(c) cKDTree in process + SELECT 1", r["kdtree_ms"]),
            row("(d) numpy box scan in process (no checks) + SELECT 1", r["scan_ms"]),
            "",
            f"- Per query, median: (a) / psycopg {flat_ratio:.1f}x; psycopg / (b) {np_ratio:.2f}x; "
            f"psycopg / (c) {kd_ratio:.2f}x; psycopg / (d) {scan_ratio:.2f}x.",
            f"- Same snippet and level as the function: (a) {r['same_flat']}/{n}, (b) "
            f"{r['same_numpy']}/{r['queries']}, "
            f"(c) {r['same_kdtree']}/{r['queries']}; relaxation levels {levels}.",
            f"- Snippet blocks: {r['blocks']:,} ({r['blocks_bytes'] / 2**20:.1f} MiB, "
            f"{r['blocks_bytes'] / r['snippets']:.0f} bytes a snippet; the session's directory of "
            f"them {r['directory_bytes'] / 2**20:.1f} MiB); "
            f"{r['bytes_per_snippet']:,.0f} bytes per snippet in all (snippets, terminators, "
            f"sources, blocks and their indexes).",
            "- pgbench (shipped script, prepared, server defaults): "
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
