"""Sessions share the block directory and the resolved match plans where modb.so is preloaded
(0.29.0: src/shared_directory.c, src/shared_plans.c; the test clusters preload it as the embedded
one does): a new session maps what another read at the generation its snapshot reads, a new
generation is read once and shared, a transaction that wrote keeps its own;
modb.explain_selection says which served. Every comparison with the reference elsewhere in the
suite runs with sharing on."""

from __future__ import annotations

import os

import psycopg
import pytest
from support import shared
from support.data import mocap

from modb.cli.main import main as modb_main

EXPLAIN = "SELECT line FROM modb.explain_selection(%s, '{1, 2}', 1, %s, NULL, NULL) AS line"
CALL = "SELECT * FROM modb.select_next_snippets{}(%s, %s, 1, 'default', NULL, NULL)"


@pytest.fixture(scope="module")
def walk(cluster):
    """A database of its own with three CMU 131 trials and their mirror images."""
    name = f"shared_directory_{os.getpid()}"
    dsn = shared.create_database(cluster, name)
    trials = sorted(mocap("cmu", "131").glob("*.amc"))[:3]
    assert modb_main(["--dsn", dsn, "load", *map(str, trials), "--mirror", "--quiet"]) == 0
    yield dsn
    shared.drop_database(cluster, name)


def _first_snippet(dsn: str) -> int:
    with psycopg.connect(dsn) as conn:
        return conn.execute("SELECT min(id) FROM modb.snippets").fetchone()[0]


def _explained(conn: psycopg.Connection, prev: int, profile: str = "default") -> tuple[str, str]:
    """The call's profile line and its level-0 line."""
    lines = [r[0] for r in conn.execute(EXPLAIN, [prev, profile])]
    profile_line = next(line for line in lines if line.startswith("  Profile:"))
    return profile_line, next(line for line in lines if line.startswith("  Level 0"))


def _in_new_session(dsn: str, prev: int, settings: dict | None = None) -> tuple[str, str]:
    with psycopg.connect(dsn, autocommit=True) as conn:
        for knob, value in (settings or {}).items():
            conn.execute("SELECT set_config(%s, %s, false)", [knob, value])
        return _explained(conn, prev)


def test_the_test_cluster_preloads_the_library(walk):
    with psycopg.connect(walk) as conn:
        preloaded = conn.execute("SHOW shared_preload_libraries").fetchone()[0]
    assert "modb" in preloaded.split(","), preloaded


def test_a_new_session_maps_the_directory_and_plan_another_read(walk):
    prev = _first_snippet(walk)
    _in_new_session(walk, prev)  # whoever reads the generation first shares it
    profile, level0 = _in_new_session(walk, prev)
    assert "(shared directory)" in level0, level0
    assert "the server's shared plan" in profile, profile
    # Knobs are part of a plan's key: a new value is resolved once, then shared.
    knobs = {"modb.position_threshold": "0.17"}
    assert "resolved by modb.match_plan" in _in_new_session(walk, prev, knobs)[0]
    assert "the server's shared plan" in _in_new_session(walk, prev, knobs)[0]


def test_a_new_generation_is_read_once_and_shared_and_answers_as_the_rule(walk):
    prev = _first_snippet(walk)
    with psycopg.connect(walk, autocommit=True) as older:
        _explained(older, prev)  # maps the current generation
        with psycopg.connect(walk, autocommit=True) as writer:
            # new blocks, a new generation
            writer.execute("SELECT * FROM modb.pack_snippet_blocks(0)")
        assert "(shared directory, read now)" in _in_new_session(walk, prev)[1]
        assert "(shared directory)" in _in_new_session(walk, prev)[1]
        # The session that mapped the old generation maps the new one, read by another.
        assert "(shared directory)" in _explained(older, prev)[1]
        ids = [r[0] for r in older.execute("SELECT id FROM modb.snippets ORDER BY id")]
        for p in ids[:: max(1, len(ids) // 25)]:
            fast = older.execute(CALL.format(""), [p, [1.0, 2.0]]).fetchall()
            rule = older.execute(CALL.format("_reference"), [p, [1.0, 2.0]]).fetchall()
            assert fast == rule, p


def test_a_transaction_that_wrote_keeps_its_own_directory_and_shares_nothing(walk):
    prev = _first_snippet(walk)
    _in_new_session(walk, prev)
    with psycopg.connect(walk) as writer:  # one transaction, rolled back
        writer.execute("SELECT * FROM modb.pack_snippet_blocks(0)")
        level0 = _explained(writer, prev)[1]
        assert "(session's directory, read now)" in level0, level0
        writer.rollback()
    # The committed generation's image is still the one shared: nothing replaced it.
    assert "(shared directory)" in _in_new_session(walk, prev)[1]
