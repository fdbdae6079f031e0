"""Good motion by default (issue 24): synthesis chooses among the newest current transition graph
over its data without being told (modb.synthesize, the Avatar, `modb synth`), draws from the largest
skeleton-and-rate pool when given no collection, says when there is no graph, and `modb synth`
builds one where the role can; `none` keeps the paper's plain rule."""

from __future__ import annotations

import os

import psycopg
from support.commands import run_modb
from support.data import mocap
from support.databases import COLLECTION, GRAPH, scratch_database

from modb.database.connection import connect
from modb.demo.data import locomotion_files
from modb.synthesis.avatar import Settings
from modb.synthesis.graphs import auto_graph_name, list_graphs
from modb.synthesis.synth import synthesize

COURSE = [[0.0, 6.0], [6.0, 6.0], [6.0, 0.0]]
CHAIN = "SELECT snippet_id FROM modb.synthesize(%s, 30)"


def chain(conn: psycopg.Connection, graph: str | None) -> list[int]:
    conn.execute("SELECT set_config('modb.graph', %s, false)", [graph or ""])
    return [r[0] for r in conn.execute(CHAIN, [COURSE])]


def test_synthesize_chooses_among_the_newest_current_graph_unless_told_none(locomotion):
    with connect(locomotion) as conn:
        notices: list[str] = []
        conn.add_notice_handler(lambda d: notices.append(d.message_primary or ""))
        default, named, plain = chain(conn, None), chain(conn, GRAPH), chain(conn, "none")
        kept = {
            r[0]
            for r in conn.execute(
                "SELECT snippet_id FROM modb.graph_snippets gs JOIN modb.graphs g "
                "ON g.id = gs.graph_id WHERE g.name = %s",
                [GRAPH],
            )
        }
        # the demo's graph covers its collection of Bandai clips, the largest pool synthesis draws
        # from when not told which
        assert (
            conn.execute("SELECT modb.default_graph('default', %s)", [COLLECTION]).fetchone()[0]
            == GRAPH
        )
        python = synthesize(conn, [tuple(g) for g in COURSE], 20.0, Settings())
    assert default == named and default != plain
    assert set(default) <= kept and not set(plain) <= kept
    assert not [n for n in notices if "no current transition graph" in n]
    # the graph: nothing to say about it (the pool it draws from, the largest, and the rest at the
    # goal have notes of their own)
    assert not [n for n in python.notes if "graph" in n], python.notes
    n = min(len(python.chain), len(default))
    assert [c.snippet_id for c in python.chain][:n] == default[:n] and n >= 20


def test_without_a_graph_synthesis_says_so_and_uses_the_plain_rule(cmu):
    with connect(cmu) as conn:
        notices: list[str] = []
        conn.add_notice_handler(lambda d: notices.append(d.message_primary or ""))
        default, plain = chain(conn, None), chain(conn, "none")
        result = synthesize(conn, [tuple(g) for g in COURSE], 5.0, Settings())
    assert default == plain
    assert [n for n in notices if "no current transition graph" in n] == [
        'modb: no current transition graph of profile "default" over collection cmu/131: '
        "choosing among all its snippets"
    ]
    assert len(result.notes) == 1 and "no current transition graph" in result.notes[0]


def test_modb_synth_builds_the_graph_once_and_a_load_makes_it_stale(cluster, tmp_path):
    files = locomotion_files(mocap("bandai-2-dev", "data"))
    # active walks: straight, and turning each way (a graph keeps a part that turns both ways)
    walks = [
        f
        for kind in ("walk", "walk-turn-left", "walk-turn-right")
        for f in [f for f in files if f.name.startswith(f"dataset-2_{kind}_active_")][:8]
    ]
    cmu_trial = mocap("cmu", "131", "131_01.amc")
    with scratch_database(cluster, f"default_graph_{os.getpid()}") as dsn:
        for paths, collection in ((walks[:-1], "walks"), ([cmu_trial], "cmu")):
            r = run_modb(dsn, "load", *paths, "--collection", collection, "-q")
            assert r.returncode == 0, r.stderr
        synth = ["synth", "--to", "0,4", "--to", "4,4", "--seconds", "8", "-q"]
        r = run_modb(dsn, *synth, "--out", tmp_path / "a.bvh")
        assert r.returncode == 0, r.stderr
        # the largest pool is the walks', and the graph is built over them
        assert "drawing from collection walks: the largest of 2 skeleton-and-rate pools" in r.stderr
        name = auto_graph_name("default", "walks")
        assert f"building transition graph {name!r}" in r.stderr, r.stderr
        assert "built in" in r.stderr, r.stderr
        r = run_modb(dsn, *synth, "--out", tmp_path / "b.bvh")
        assert r.returncode == 0 and "building" not in r.stderr, r.stderr
        assert (tmp_path / "a.bvh").read_bytes() == (tmp_path / "b.bvh").read_bytes()
        r = run_modb(dsn, "load", walks[-1], "--collection", "walks")
        assert r.returncode == 0, r.stderr
        assert f"transition graph {name!r} no longer covers its data" in r.stderr
        with connect(dsn) as conn:
            assert [g.current for g in list_graphs(conn) if g.name == name] == [False]
        r = run_modb(dsn, *synth, "--no-graph", "--out", tmp_path / "c.bvh")
        assert r.returncode == 0 and "building" not in r.stderr, r.stderr
        r = run_modb(dsn, *synth, "--out", tmp_path / "d.bvh")
        assert r.returncode == 0 and f"building transition graph {name!r}" in r.stderr, r.stderr
