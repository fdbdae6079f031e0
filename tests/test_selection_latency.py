"""Selection latency as the tools report it: `modb bench tail`'s selection kinds without a graph
and with the one --graph names (its default the newest, `none`, a name the database lacks), and the
slowest selection of a walk in the synthesis report (`modb demo`, `modb synth`, `modb bench
synth`: format_summary), the first and the last beside it."""

from __future__ import annotations

import os
import re

import numpy as np
import psycopg
import pytest
from support.commands import run_modb
from support.data import mocap
from support.databases import scratch_database

from modb.bench.tail import (
    KINDS,
    NO_GRAPH,
    UnknownGraph,
    _graph_requests,
    _kind_runs,
    graph_in_force,
    kinds,
    requests_for,
)
from modb.cli.synth_report import format_summary
from modb.database.connection import connect
from modb.synthesis.avatar import Settings
from modb.synthesis.synth import report, synthesize

GRAPH, OLDER = "cmu", "older"  # GRAPH built last: the newest
COLLECTION = "cmu/131"
GRAPH_OPTIONS = ["--collection", COLLECTION, "--profile", "locomotion", "--min-turn", "0", "-q"]
PLAIN_ROWS = [f"graph {GRAPH}, cost-to-go", f"graph {GRAPH}, no cost-to-go"]


@pytest.fixture(scope="module")
def graphs(cluster):
    """CMU 131_01 and its mirror image, with two transition graphs over them."""
    with scratch_database(cluster, f"selection_latency_{os.getpid()}") as dsn:
        trial = mocap("cmu", "131", "131_01.amc")
        r = run_modb(
            dsn, "load", trial, "--collection", COLLECTION, "--mirror", "-q", process=False
        )
        assert r.returncode == 0, r.stderr
        for name in (OLDER, GRAPH):
            r = run_modb(dsn, "graph", "build", name, *GRAPH_OPTIONS, process=False)
            assert r.returncode == 0, r.stderr
        yield dsn


def _requests(dsn: str, n: int = 6) -> list:
    with psycopg.connect(dsn) as conn:
        return requests_for(conn, n, seed=1)


def test_kinds_run_without_a_graph_and_with_the_newest_by_default(graphs):
    times = kinds(graphs, _requests(graphs), seed=1, progress=pytest.fail)
    with_graph = [f"{name}, graph {GRAPH}" for name in KINDS]
    assert list(times) == [*KINDS, *with_graph, *PLAIN_ROWS]
    assert all(len(ms) == 6 and min(ms) > 0 for ms in times.values())


def test_graph_none_times_the_kinds_without_a_graph_only(graphs):
    for none in (NO_GRAPH, "None"):
        assert list(kinds(graphs, _requests(graphs), seed=1, graph=none)) == list(KINDS)


def test_a_named_graph_is_in_force_and_the_requests_start_in_it(graphs):
    requests = _requests(graphs, 20)
    with psycopg.connect(graphs, autocommit=True) as conn:
        assert graph_in_force(conn, OLDER) == OLDER
        kept = {
            r[0]
            for r in conn.execute(
                "SELECT snippet_id FROM modb.graph_snippets s JOIN modb.graphs g "
                "ON g.id = s.graph_id WHERE g.name = %s",
                [OLDER],
            )
        }
        in_graph = _graph_requests(conn, OLDER, requests, np.random.default_rng(1))
        runs = _kind_runs(requests, OLDER, in_graph)
        assert [r.name for r in runs] == [
            *KINDS,
            *(f"{name}, graph {OLDER}" for name in KINDS),
            f"graph {OLDER}, cost-to-go",
            f"graph {OLDER}, no cost-to-go",
        ]
        for run in runs:
            named = run.name.endswith(f"graph {OLDER}") or run.name.startswith("graph ")
            assert run.settings["modb.graph"] == (OLDER if named else NO_GRAPH), run.name
            assert run.requests == (in_graph if named else requests), run.name
        assert {prev for prev, _ in in_graph} <= kept
        assert [t for _, t in in_graph] == [t for _, t in requests]
        assert runs[-1].settings["modb.graph_cost_to_go"] == "off"
        # in force: the plain call with the graph's setting chooses among its snippets
        plain = next(r for r in runs if r.name == f"graph {OLDER}, cost-to-go")
        conn.execute("SELECT set_config('modb.graph', %s, false)", [OLDER])
        chosen = {
            conn.execute(plain.sql, plain.params(prev, target, [])).fetchone()[0]
            for prev, target in in_graph
        }
        assert chosen <= kept
    times = kinds(graphs, requests[:4], seed=1, graph=OLDER)
    assert f"coming to rest, graph {OLDER}" in times and f"graph {GRAPH}, cost-to-go" not in times


def test_an_unknown_graph_is_refused_naming_the_databases_graphs(graphs):
    with pytest.raises(
        UnknownGraph, match=f"--graph nope: .* its transition graphs: {GRAPH}, {OLDER}$"
    ):
        kinds(graphs, _requests(graphs), seed=1, graph="nope")
    # the command: before anything is timed (no progress past the check), exit status 2
    r = run_modb(
        graphs,
        "bench",
        "tail",
        "--sizes",
        "all",
        "--queries",
        "10",
        "--graph",
        "nope",
        process=False,
    )
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.startswith("modb bench tail: --graph nope: database ") and GRAPH in r.stderr
    assert "first calls" not in r.stderr


def test_bench_tail_reports_each_kind_with_the_named_graph(graphs):
    r = run_modb(
        graphs,
        "bench",
        "tail",
        "--sizes",
        "all",
        "--queries",
        "10",
        "--exact",
        "0",
        "--kinds",
        "10",
        "--pgbench-seconds",
        "1",
        "--graph",
        GRAPH,
        process=False,
    )
    assert r.returncode == 0, r.stderr
    assert f"each selection kind on 10 of them, without a graph and with graph {GRAPH}" in r.stderr
    rows = re.findall(r"^\| (.+?) \(10, prepared\) \|", r.stdout, re.M)
    assert rows == [*KINDS, *(f"{name}, graph {GRAPH}" for name in KINDS), *PLAIN_ROWS]


def test_the_synthesis_report_gives_the_slowest_selection_first_and_last(graphs):
    with connect(graphs) as conn:
        result = synthesize(conn, [(0.0, 4.0), (0.0, 0.0)], 4.0, Settings(collection=COLLECTION))
        summary = format_summary(result, report(conn, result))
    latencies = [c.latency_ms for c in result.chain]
    assert len(latencies) >= 3 and None not in latencies  # the first choice's too
    expected = (
        f"selection max {max(latencies):.1f} ms (first {latencies[0]:.1f} ms, "
        f"last {latencies[-1]:.1f} ms)"
    )
    (line,) = [x for x in summary.splitlines() if x.startswith("query latency: ")]
    assert line.endswith(expected), line
