"""`modb bench tail`: select_next_snippet's tail on the user's path (0.18.0: every term of the
rule bounded where the scan reads). Per database, with the server's settings and no SET but
the selection kinds' (below):

- 10,000 seeded requests (a random previous snippet, a target within 5 m, the default profile)
  on each client path: psql one call per statement (\\timing), psycopg not prepared, psycopg
  prepared: p50, p99, p99.9, max and calls over 20 ms, the first call of five new sessions apart,
  and the share of requests each relaxation level answered;
- pgbench with the shipped script at 1, 2 and 8 clients prepared, and 2 clients -M simple;
- modb.explain_selection's stages (blocks met and read, candidates, rows read) on 500 requests;
- every other selection kind on the same requests (k-best, exclusion list, coming to rest,
  setting off, an annotation spec), each without a graph (SET modb.graph = 'none') and with the
  transition graph --graph names (SET modb.graph; the previous snippets drawn from the graph's),
  labelled "coming to rest, graph NAME", and the plain call with that graph with and without its
  cost-to-go. --graph defaults to the database's newest transition graph (none: no graph rows
  when it has none); `--graph none` times the kinds without a graph only; a name the database
  lacks stops the run before anything is timed, naming the graphs it has;
- exactness: seeded requests, every shipped profile and one of odd user thresholds, thresholds
  scaled down to reach every relaxation level, against the reference function (the rule), whose
  time per call is the baseline of the same run;
- what the scan reads per snippet (the blocks' live bytes and the directory's index) and a
  session's memory (its block directory).

    modb --dsn DSN bench tail --sizes 100000,all,1000000 [--graph NAME|none]
"""

from __future__ import annotations

import random
import re
import statistics
import subprocess
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import psycopg

from .scale import PSQL, FUNCTION, pgbench, sized_database

PROFILES = ("default", "strict", "locomotion")
ODD = {
    "joints": "left_wrist,right_wrist,left_ankle,right_ankle",
    "norm": "l1",
    "velocity_terms": "off",
}
THRESHOLDS = {
    "position_threshold": 0.12,
    "angle_threshold": 0.3,
    "velocity_threshold": 0.6,
    "angular_velocity_threshold": 4.0,
}
CALL = "SELECT * FROM modb.{}(%s, %s, %s, %s)"


def requests_for(conn: psycopg.Connection, n: int, seed: int) -> list[tuple[int, list[float]]]:
    ids = np.array([r[0] for r in conn.execute("SELECT id FROM modb.snippets ORDER BY id")])
    rng = np.random.default_rng(seed)
    return [
        (int(rng.choice(ids)), [float(v) for v in rng.uniform(-5, 5, size=2)]) for _ in range(n)
    ]


def _psql_ms(dsn: str, requests: list, profile: str) -> list[float]:
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


def _psycopg_ms(dsn: str, requests: list, profile: str, prepare: bool) -> tuple[list[float], list]:
    """Times after the session's first call (which warms its directory and plan)."""
    ms, levels = [], []
    with psycopg.connect(dsn, autocommit=True) as conn:
        prev, target = requests[0]
        conn.execute(FUNCTION, [prev, target, profile], prepare=prepare).fetchone()
        for prev, target in requests:
            t = time.perf_counter()
            row = conn.execute(FUNCTION, [prev, target, profile], prepare=prepare).fetchone()
            ms.append((time.perf_counter() - t) * 1000)
            levels.append(row[1])
    return ms, levels


def _first_calls(dsn: str, requests: list, profile: str, sessions: int = 5) -> list[float]:
    times = []
    for prev, target in requests[:sessions]:
        with psycopg.connect(dsn, autocommit=True) as conn:
            t = time.perf_counter()
            conn.execute(FUNCTION, [prev, target, profile]).fetchone()
            times.append((time.perf_counter() - t) * 1000)
    return times


def stages(dsn: str, requests: list) -> dict[str, list[float]]:
    patterns = {
        "blocks met": r"(\d+) blocks met it",
        "blocks read": r"blocks: (\d+) read",
        "snippets in the codes' box": r"snippets in the codes' box: (\d+)",
        "rejected by term codes": r"rejected by term codes: (\d+)",
        "rows read": r"(\d+) rows read",
        "block search ms": r"block search ([\d.]+) ms",
    }
    out: dict[str, list[float]] = {k: [] for k in (*patterns, "whole call ms")}
    with psycopg.connect(dsn, autocommit=True) as conn:
        for prev, target in requests:
            lines = [
                r[0]
                for r in conn.execute(
                    "SELECT * FROM modb.explain_selection(%s, %s)", [prev, target]
                )
            ]
            text = "\n".join(lines)
            for name, pattern in patterns.items():
                out[name].append(sum(float(v) for v in re.findall(pattern, text)))
            out["whole call ms"].append(float(re.search(r"rows in ([\d.]+) ms", lines[0])[1]))
    return out


def _exactness(dsn: str, n: int, seed: int) -> dict:
    """The fast path against the reference on seeded requests (every level, every profile, odd
    thresholds); the reference's time per call is the run's baseline."""
    rng = random.Random(seed)
    levels: dict[int, int] = {}
    same = 0
    fast_ms, reference_ms = [], []
    with psycopg.connect(dsn, autocommit=True) as conn:
        ids = [r[0] for r in conn.execute("SELECT id FROM modb.snippets ORDER BY id")]
        for i in range(n):
            odd = i % 4 == 3
            for knob, value in ODD.items():
                conn.execute(
                    "SELECT set_config(%s, %s, false)", [f"modb.{knob}", value if odd else ""]
                )
            f = rng.choice((None, 1.0, 0.5, 0.25, 0.12))
            for knob, value in THRESHOLDS.items():
                conn.execute(
                    "SELECT set_config(%s, %s, false)",
                    [f"modb.{knob}", "" if f is None else repr(value * f)],
                )
            args = [
                rng.choice(ids),
                [round(rng.uniform(-6, 6), 3), round(rng.uniform(-6, 6), 3)],
                rng.choice((1, 1, 5)),
                rng.choice(PROFILES),
            ]
            t = time.perf_counter()
            fast = conn.execute(CALL.format("select_next_snippets"), args).fetchall()
            fast_ms.append((time.perf_counter() - t) * 1000)
            t = time.perf_counter()
            reference = conn.execute(CALL.format("select_next_snippets_reference"), args).fetchall()
            reference_ms.append((time.perf_counter() - t) * 1000)
            same += fast == reference
            if reference:
                levels[reference[0][7]] = levels.get(reference[0][7], 0) + 1
    return {
        "n": n,
        "same": same,
        "levels": dict(sorted(levels.items())),
        "ratio": statistics.median(r / f for r, f in zip(reference_ms, fast_ms)) if n else 0.0,
    }


# Every selection a user triggers (besides the plain call above), on the same requests: SQL per
# kind, its parameters from (prev, target, excluded ids), and its session settings.
Params = Callable[[int, list[float], list[int]], list]
PLAIN: tuple[str, Params] = (
    "SELECT snippet_id FROM modb.select_next_snippet(%s, %s)",
    lambda prev, target, excluded: [prev, target],
)
KINDS: dict[str, tuple[str, Params, dict[str, str]]] = {
    "k-best (k = 5)": (
        "SELECT snippet_id FROM modb.select_next_snippets(%s, %s, 5)",
        lambda prev, target, excluded: [prev, target],
        {},
    ),
    "exclusion list (20 snippets)": (
        "SELECT snippet_id FROM modb.select_next_snippet(%s, %s, 'default', NULL, %s)",
        lambda prev, target, excluded: [prev, target, excluded],
        {},
    ),
    "coming to rest": (
        "SELECT snippet_id FROM modb.select_synthesis_step(%s, '{0,0,0}', 0, %s, 'default', NULL, "
        "NULL, true)",
        lambda prev, target, excluded: [prev, target],
        {},
    ),
    "setting off": (
        "SELECT snippet_id FROM modb.select_synthesis_step(%s, '{0,0,0}', 0, %s, 'default', NULL, "
        "NULL, false)",
        lambda prev, target, excluded: [prev, target],
        {},
    ),
    "annotations '!fall'": (*PLAIN, {"modb.annotations": "!fall"}),
}
NO_GRAPH = "none"  # --graph none: the kinds without a graph only (as SET modb.graph = 'none')


class UnknownGraph(ValueError):
    """--graph names no transition graph of the database."""


@dataclass(frozen=True)
class KindRun:
    """One row of the kinds' table: a kind's query, its settings and its requests."""

    name: str
    sql: str
    params: Params
    settings: dict[str, str]
    requests: list[tuple[int, list[float]]]


def transition_graphs(conn: psycopg.Connection) -> list[str]:
    """The database's transition graphs, newest first."""
    rows = conn.execute("SELECT name FROM modb.graphs WHERE kind = 'transitions' ORDER BY id DESC")
    return [r[0] for r in rows]


def graph_in_force(conn: psycopg.Connection, graph: str | None) -> str | None:
    """The graph `--graph graph` times the kinds with: None (not given) the database's newest
    transition graph, or no graph when it has none; NO_GRAPH no graph; a name that graph, which
    the database must have (UnknownGraph names those it has)."""
    names = transition_graphs(conn)
    if graph is None:
        return names[0] if names else None
    if graph.strip().lower() == NO_GRAPH:
        return None
    if graph not in names:
        has = ", ".join(names) if names else "none (`modb graph build NAME` builds one)"
        raise UnknownGraph(
            f"--graph {graph}: database {conn.info.dbname} has no transition graph of that name; "
            f"its transition graphs: {has}"
        )
    return graph


def _graph_requests(
    conn: psycopg.Connection, graph: str, requests: list, rng: np.random.Generator
) -> list[tuple[int, list[float]]]:
    """The requests' targets, each after a random snippet the graph keeps (none if it keeps
    none here)."""
    kept = np.array(
        [
            r[0]
            for r in conn.execute(
                "SELECT snippet_id FROM modb.graph_snippets s JOIN modb.graphs g"
                " ON g.id = s.graph_id WHERE g.name = %s AND g.kind = 'transitions' ORDER BY 1",
                [graph],
            )
        ]
    )
    if not len(kept):
        return []
    return [(int(rng.choice(kept)), target) for _, target in requests]


def _kind_runs(requests: list, graph: str | None, graph_requests: list) -> list[KindRun]:
    """Every kind without a graph (SET modb.graph = 'none'), then, given a graph and requests
    from its snippets, every kind with it ("coming to rest, graph cmu") and the plain call with
    and without its cost-to-go."""
    runs = [
        KindRun(name, sql, params, {**settings, "modb.graph": NO_GRAPH}, requests)
        for name, (sql, params, settings) in KINDS.items()
    ]
    if graph is None or not graph_requests:
        return runs
    in_force = {"modb.graph": graph}
    runs += [
        KindRun(f"{name}, graph {graph}", sql, params, {**settings, **in_force}, graph_requests)
        for name, (sql, params, settings) in KINDS.items()
    ]
    off = {**in_force, "modb.graph_cost_to_go": "off"}
    runs.append(KindRun(f"graph {graph}, cost-to-go", *PLAIN, in_force, graph_requests))
    runs.append(KindRun(f"graph {graph}, no cost-to-go", *PLAIN, off, graph_requests))
    return runs


def time_run(conn: psycopg.Connection, run: KindRun, excluded: list[list[int]]) -> list[float]:
    """A kind's times over its requests, prepared, after a first call, its settings in force."""
    for knob, value in run.settings.items():
        conn.execute("SELECT set_config(%s, %s, false)", [knob, value])
    prev, target = run.requests[0]
    conn.execute(run.sql, run.params(prev, target, excluded[0]), prepare=True).fetchall()
    ms = []
    for (prev, target), x in zip(run.requests, excluded):
        t = time.perf_counter()
        conn.execute(run.sql, run.params(prev, target, x), prepare=True).fetchall()
        ms.append((time.perf_counter() - t) * 1000)
    for knob in run.settings:
        conn.execute(f"RESET {knob}")
    return ms


def kinds(
    dsn: str,
    requests: list,
    seed: int,
    graph: str | None = None,
    progress: Callable[[str], None] = print,
) -> dict[str, list[float]]:
    """Each kind's times over the requests, prepared, after a first call (psycopg): KINDS without
    a graph, then with the graph `graph` names (graph_in_force: by default the newest transition
    graph, NO_GRAPH none), the previous snippets drawn from its snippets, and the plain call with
    and without its cost-to-go."""
    rng = np.random.default_rng(seed)
    with psycopg.connect(dsn, autocommit=True) as conn:
        in_force = graph_in_force(conn, graph)
        ids = np.array([r[0] for r in conn.execute("SELECT id FROM modb.snippets ORDER BY id")])
        excluded = [[int(v) for v in rng.choice(ids, 20)] for _ in requests]
        graph_requests = [] if in_force is None else _graph_requests(conn, in_force, requests, rng)
        if in_force is not None and not graph_requests:
            progress(f"  graph {in_force} keeps no snippet in this database: no rows with it")
        runs = _kind_runs(requests, in_force, graph_requests)
        return {run.name: time_run(conn, run, excluded) for run in runs}


def _costs(dsn: str) -> dict:
    with psycopg.connect(dsn, autocommit=True) as conn:
        snippets, blocks, block_bytes, index_bytes = conn.execute(
            "SELECT (SELECT count(*) FROM modb.snippets), count(*), sum(pg_column_size(b.*)), "
            "coalesce(pg_relation_size(to_regclass('modb.snippet_blocks_directory_idx')), 0)"
            " FROM modb.snippet_blocks b"
        ).fetchone()
        prev = conn.execute("SELECT min(id) FROM modb.snippets").fetchone()[0]
        conn.execute(FUNCTION, [prev, [1.0, 2.0], "default"]).fetchone()
        (memory,) = conn.execute(
            "SELECT coalesce(sum(total_bytes), 0) FROM pg_backend_memory_contexts "
            "WHERE name = 'modb block directory'"
        ).fetchone()
    return {
        "snippets": snippets,
        "blocks": blocks,
        "block_bytes_per_snippet": float(block_bytes) / snippets,
        "index_bytes_per_snippet": index_bytes / snippets,
        "directory_bytes": memory,
    }


def _graph_words(graph: str | None) -> str:
    return "without a graph only" if graph is None else f"without a graph and with graph {graph}"


def bench_database(
    dsn: str,
    queries: int,
    exact: int,
    kind_queries: int,
    seed: int,
    pgbench_seconds: int,
    progress=print,
    graph: str | None = None,
) -> dict:
    with psycopg.connect(dsn, autocommit=True) as conn:
        in_force = graph_in_force(conn, graph)  # before the timings: an unknown name stops here
        requests = requests_for(conn, queries, seed)
    progress("  first calls of new sessions")
    first = _first_calls(dsn, requests, "default")
    progress(f"  {queries:,} requests: psycopg prepared, not prepared, psql")
    prepared, levels = _psycopg_ms(dsn, requests, "default", True)
    plain, _ = _psycopg_ms(dsn, requests, "default", False)
    psql = _psql_ms(dsn, requests, "default")
    progress("  stages (explain_selection) on 500 of them")
    stage_figures = stages(dsn, requests[:500])
    progress(f"  each selection kind on {kind_queries:,} of them, {_graph_words(in_force)}")
    kind_ms = (
        kinds(dsn, requests[:kind_queries], seed, in_force or NO_GRAPH, progress)
        if kind_queries
        else {}
    )
    progress("  pgbench")
    tps = {f"{c} prepared": pgbench(dsn, c, pgbench_seconds) for c in (1, 2, 8)}
    tps["2 simple"] = pgbench(dsn, 2, pgbench_seconds, mode="simple")
    progress(f"  exactness: {exact} requests against the reference")
    return {
        "first": first,
        "paths": {
            "psql, one call per statement": psql,
            "psycopg, not prepared": plain,
            "psycopg, prepared": prepared,
        },
        "levels": {lvl: levels.count(lvl) for lvl in sorted(set(levels))},
        "stages": stage_figures,
        "kinds": kind_ms,
        "tps": tps,
        "exact": _exactness(dsn, exact, seed),
        "costs": _costs(dsn),
    }


def report(name: str, r: dict) -> str:
    def row(label: str, ms: list[float]) -> str:
        a = np.array(ms)
        p50, p99, p999 = np.percentile(a, [50, 99, 99.9])
        return (
            f"| {label} | {p50:.3f} | {p99:.3f} | {p999:.3f} | {a.max():.1f} | {(a > 20).sum()} |"
        )

    n = sum(r["levels"].values())
    c, e = r["costs"], r["exact"]
    lines = [
        f"### {name}: {c['snippets']:,} snippets",
        "",
        "| select_next_snippet, server defaults | p50 ms | p99 ms | p99.9 ms | max ms "
        "| over 20 ms |",
        "|---|---|---|---|---|---|",
        *(row(f"{label} ({len(ms):,})", ms) for label, ms in r["paths"].items()),
        row(f"first call of a new session ({len(r['first'])})", r["first"]),
        *(row(f"{kind} ({len(ms):,}, prepared)", ms) for kind, ms in r.get("kinds", {}).items()),
        "",
        "- Levels answering: "
        + ", ".join(f"{k}: {v:,} ({100 * v / n:.1f}%)" for k, v in r["levels"].items())
        + ".",
        "- pgbench (shipped script): "
        + ", ".join(f"{k} {v:,.0f}/s" for k, v in r["tps"].items())
        + ".",
        f"- Exact: {e['same']}/{e['n']} requests the reference's rows (levels {e['levels']}); "
        f"the reference takes {e['ratio']:.0f}x the fast path's time, median per request.",
        f"- The scan reads {c['block_bytes_per_snippet']:.0f} bytes of blocks per snippet "
        f"({c['blocks']:,} blocks) and {c['index_bytes_per_snippet']:.0f} of the directory's "
        f"index; a session's directory {c['directory_bytes'] / 2**20:.1f} MiB.",
        "",
        "| stage, per call (500 requests) | p50 | p90 | p99 |",
        "|---|---|---|---|",
    ]
    for stage, values in r["stages"].items():
        p = np.percentile(values, [50, 90, 99])
        lines.append(f"| {stage} | {p[0]:,.2f} | {p[1]:,.2f} | {p[2]:,.2f} |")
    return "\n".join(lines)


def bench_tail(
    dsn: str,
    sizes: list[int | None],
    queries: int,
    exact: int,
    kind_queries: int,
    seed: int,
    pgbench_seconds: int,
    progress=print,
    graph: str | None = None,
) -> list[tuple[str, dict]]:
    """Each size's figures; `graph` is --graph (kinds). A graph the database (or a kept copy of
    it) lacks raises UnknownGraph before anything is timed there."""
    with psycopg.connect(dsn, autocommit=True) as conn:
        graph_in_force(conn, graph)  # before the copies are made
    out = []
    for size in sizes:
        where = dsn if size is None else sized_database(dsn, size, seed, progress)
        name = "all the data" if size is None else f"about {size:,}"
        progress(f"{name}:")
        out.append(
            (
                name,
                bench_database(
                    where, queries, exact, kind_queries, seed, pgbench_seconds, progress, graph
                ),
            )
        )
    return out
