"""Motion models prepared once per process (issue 62), on a copy of CMU 16's graph of models:
modb.synthesize_from_models reads a graph's models' documents once per server backend (its
modb.prepared_models() counts the reads) and walks the same strip from them as a first call does; a
model whose row changed (its tree rebuilt, its skeleton edited, a new version put in the graph) is
read again, never served stale; the web server's process (the kernel in the client) keeps them
across avatar sessions, shared by syntheses in threads, within its bounds."""

from __future__ import annotations

import json
import os
import sys
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from modb_kernel import model_synthesis as MS
from modb_kernel import prepared_models

from psycopg.types.json import Jsonb

from modb.database.connection import connect
from modb.jobs.kernel_database import WorkerDatabase
from modb.models.tree import build_tree
from modb.synthesis.model_avatar import ModelAvatar

GRAPH = "walk"
GOALS = [[0.0, 4.0], [3.0, 6.0]]
SECONDS = 2.0


@pytest.fixture(scope="module")
def dsn(cmu16_walks):
    with cmu16_walks(f"prepared_models_{os.getpid()}") as dsn:
        yield dsn


def strip(conn) -> tuple:
    """The strip's frames (as md5s of their text: exact) and report of a short walk."""
    return conn.execute(
        "SELECT md5(rotations::text), md5(translations::text), report "
        "FROM modb.synthesize_from_models(%s, %s::float8[], %s)",
        [GRAPH, GOALS, SECONDS],
    ).fetchone()


def held(conn) -> dict[int, tuple[int, int]]:
    """model id -> (reads, served) of the models this session's backend holds prepared."""
    rows = conn.execute("SELECT model_id, reads, served FROM modb.prepared_models()").fetchall()
    return {ident: (reads, served) for ident, reads, served in rows}


def nodes(conn) -> dict[str, int]:
    """node -> model id of the graph."""
    rows = conn.execute(
        "SELECT n.key, (n.value->>'model_id')::bigint FROM modb.graphs g, "
        "jsonb_each(g.data->'nodes') n WHERE g.name = %s AND g.kind = 'models'",
        [GRAPH],
    ).fetchall()
    return dict(rows)


def test_a_second_call_reads_no_document_and_walks_the_same_strip(dsn):
    with connect(dsn) as conn:
        ids = sorted(set(nodes(conn).values()))
        assert held(conn) == {}
        first = strip(conn)
        assert held(conn) == {i: (1, 0) for i in ids}
        second = strip(conn)
        assert held(conn) == {i: (1, 1) for i in ids}  # served, not read again
        assert second == first
    with connect(dsn) as conn:  # another backend prepares its own, alike
        assert strip(conn) == first
        assert held(conn) == {i: (1, 0) for i in ids}


def new_tree(conn, ident: int, seed: int) -> None:
    """A tree drawn again for the model, as `modb model tree` does (fewer samples: quicker)."""
    (data,) = conn.execute("SELECT data FROM modb.models WHERE id = %s", [ident]).fetchone()
    conn.execute(
        "UPDATE modb.models SET meta = meta || jsonb_build_object('tree', %s::jsonb) WHERE id = %s",
        [Jsonb(build_tree(data, samples=1000, seed=seed)), ident],
    )


def test_a_model_changed_is_read_again_never_served_stale(dsn):
    def fresh() -> tuple:
        """The strip a new backend walks (nothing prepared before)."""
        with connect(dsn) as other:
            return strip(other)

    with connect(dsn) as conn:
        graph = nodes(conn)
        left = graph["left_step"]
        (skeleton,) = conn.execute(
            "SELECT skeleton_id FROM modb.models WHERE id = %s", [left]
        ).fetchone()
        before = strip(conn)
        reads = held(conn)

        # its tree rebuilt (meta, in place: the same id and version)
        new_tree(conn, left, seed=1)
        rebuilt = strip(conn)
        assert rebuilt != before and rebuilt == fresh()
        assert held(conn)[left] == (reads[left][0] + 1, 0)
        assert all(held(conn)[i][0] == reads[i][0] for i in graph.values() if i != left)

        # its skeleton's row changed: every model of it read again
        conn.execute("UPDATE modb.skeletons SET meta = meta WHERE id = %s", [skeleton])
        reads = held(conn)
        assert strip(conn) == rebuilt
        assert all(held(conn)[i][0] == reads[i][0] + 1 for i in graph.values())

        # a new version (a new row) put in the graph, its own tree drawn
        (new,) = conn.execute(
            "INSERT INTO modb.models (name, kind, skeleton_id, collection_id, data, meta) "
            "SELECT name, kind, skeleton_id, collection_id, data, meta - 'tree' "
            "FROM modb.models WHERE id = %s RETURNING id",
            [left],
        ).fetchone()
        new_tree(conn, new, seed=2)
        conn.execute(
            "UPDATE modb.graphs SET data = jsonb_set(data, '{nodes,left_step,model_id}', "
            "to_jsonb(%s::bigint)) WHERE name = %s AND kind = 'models'",
            [new, GRAPH],
        )
        replaced = strip(conn)
        assert replaced != rebuilt and replaced == fresh()
        assert held(conn)[new] == (1, 0)


def walk(graph, models, rig, seed: int) -> tuple[np.ndarray, np.ndarray]:
    return MS.Synthesis(graph, models, rig, GOALS, SECONDS, seed).run().frames()


def test_the_web_servers_sessions_share_prepared_models_in_threads_within_bounds(dsn):
    prepared = prepared_models.PREPARED  # the process's, as the web server's
    prepared.clear()
    with connect(dsn) as conn:
        ModelAvatar(conn, GRAPH)  # a page's mode switch to the graph
        read = {row[0]: row[3:5] for row in prepared.rows()}
        ModelAvatar(conn, GRAPH)  # another page's: served, not read again
        assert {row[0]: row[3:5] for row in prepared.rows()} == {i: (1, 1) for i in read}
        assert set(read.values()) == {(1, 0)}
        database = WorkerDatabase(conn)
        graph, models, rig = MS.load(database, GRAPH)

        # read-only: a synthesis that wrote into a shared model would fail here, not corrupt it
        model = models["left_step"]
        with pytest.raises(ValueError, match="read-only"):
            model.mixture_means[0, 0] = 0.0
        with pytest.raises(ValueError, match="read-only"):
            model.tree["root"]["children"][0]["mean"][0] = 0.0

        # walks at once give what each gives alone, and leave the models as they were
        state = [(dict(vars(m)), json.dumps(m.model)) for m in models.values()]
        alone = [walk(graph, models, rig, seed) for seed in (1, 2)]
        interval = sys.getswitchinterval()
        sys.setswitchinterval(1e-5)  # threads take turns far more often than by default
        try:
            with ThreadPoolExecutor(2) as pool:
                together = list(pool.map(lambda seed: walk(graph, models, rig, seed), (1, 2)))
        finally:
            sys.setswitchinterval(interval)
        for (r, t), (r2, t2) in zip(alone, together, strict=True):
            assert np.array_equal(r, r2) and np.array_equal(t, t2)
        for m, (attributes, document) in zip(models.values(), state, strict=True):
            assert vars(m).keys() == attributes.keys()
            assert all(vars(m)[k] is v for k, v in attributes.items())
            assert json.dumps(m.model) == document

        # bounded: the least recently used dropped, read again when wanted
        ids = sorted(set(nodes(conn).values()))
        keys = {row["id"]: row for row in database.run(prepared_models.KEYS, [ids])}
        first, second, third = ids[:3]
        small = prepared_models.PreparedModels(max_models=2)
        small.step_models(database, {i: keys[i] for i in (first, second)})
        small.step_models(database, {third: keys[third]})
        assert [row[0] for row in small.rows()] == [second, third] and small.evicted == 1
        small.step_models(database, {first: keys[first]})
        assert [row[0] for row in small.rows()] == [first, third]
        assert small.rows()[0][3:5] == (1, 0)  # read, not served: it had been dropped
        # a call's models are kept even past the bounds (another call would read them again),
        # until another call needs the room
        tight = prepared_models.PreparedModels(max_megabytes=0.001)
        tight.step_models(database, {first: keys[first], second: keys[second]})
        assert [row[0] for row in tight.rows()] == [first, second] and tight.evicted == 0
        tight.step_models(database, {first: keys[first], second: keys[second]})
        assert [row[3:5] for row in tight.rows()] == [(1, 1), (1, 1)]  # served, not read again
        tight.step_models(database, {third: keys[third]})
        assert [row[0] for row in tight.rows()] == [third] and tight.evicted == 2


def test_a_server_prepares_its_first_graph_of_models_as_it_starts(dsn):
    """`modb serve` prepares the graph the avatar page offers first while it answers, so the page's
    first switch to it is served, as the next ones are."""
    import asyncio

    from modb.web import models_at_start
    from modb.web.app import create_app

    prepared = prepared_models.PREPARED
    prepared.clear()
    app = create_app(dsn).app  # the Starlette app inside its Host/Origin guard

    async def started() -> dict:
        async with app.router.lifespan_context(app):  # as the server starts and stops
            await asyncio.to_thread(models_at_start.wait_for, GRAPH)
            return {row[0]: row[3:5] for row in prepared.rows()}

    read = asyncio.run(started())
    with connect(dsn) as conn:
        assert set(read) == set(nodes(conn).values()) and set(read.values()) == {(1, 0)}
        ModelAvatar(conn, GRAPH)  # the page's first switch to it
    assert {row[0]: row[3:5] for row in prepared.rows()} == {i: (1, 1) for i in read}
