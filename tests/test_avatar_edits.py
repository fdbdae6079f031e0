"""An avatar walking while someone edits the clip it is playing: the edit rebuilds that clip's
snippets (the snippet the chain continues from is gone). The walk goes on from the new version's
nearest snippet, or, where the new version has none at the walk's rate, stops saying why."""

from __future__ import annotations

import json
import os

import psycopg
import pytest
from support.data import mocap
from support.databases import scratch_database
from test_cli_hardening import WALKS, modb

from modb.database.connection import connect
from modb.synthesis.avatar import Avatar, NoContinuation
from modb.synthesis.chain import Settings


@pytest.fixture(scope="module")
def walks(cluster):
    files = [mocap("bandai-1", "data", name) for name in WALKS]
    with scratch_database(cluster, f"avatar_edits_{os.getpid()}") as dsn:
        r = modb(dsn, "load", *files, "--collection", "walks", "-q")
        assert r.returncode == 0, r.stderr
        yield dsn


def walk_while_editing(dsn: str, script: str, commands: list[dict]) -> tuple[Avatar, int]:
    """Four choices of a walk whose first snippet's clip is edited as it starts playing."""
    with connect(dsn) as conn, psycopg.connect(dsn, autocommit=True) as editor:
        editor.execute(
            "INSERT INTO modb.edit_scripts (name, commands) VALUES (%s, %s)",
            [script, json.dumps(commands)],
        )
        # as the web view's avatar: the readout counts the candidates each choice examined
        avatar = Avatar(conn, goals=[(0.0, 30.0)], settings=Settings(count_candidates=True))
        edited = None
        for _ in avatar.frames():
            if edited is None:  # the first snippet is playing: its clip gets a new version
                first = avatar.choices[0]
                editor.execute(
                    "SELECT * FROM modb.apply_edit_script(%s, %s)", [script, [first.clip_id]]
                )
                (gone,) = editor.execute(
                    "SELECT NOT EXISTS (SELECT FROM modb.snippets WHERE id = %s)",
                    [first.snippet_id],
                ).fetchone()
                assert gone, "the edit should have dropped the playing clip's old snippets"
                edited = first.snippet_id
            if len(avatar.choices) == 4:
                break
    return avatar, edited


def test_the_walk_goes_on_when_an_edit_drops_the_snippet_it_continues_from(walks):
    avatar, edited = walk_while_editing(walks, "smooth", [{"op": "smooth", "seconds": 0.05}])
    assert [c.step for c in avatar.choices] == [0, 1, 2, 3]
    assert len({c.fps for c in avatar.choices}) == 1
    assert any(f"snippet {edited} was rebuilt" in n for n in avatar.notes), avatar.notes


def test_an_edit_that_changes_the_rate_stops_the_walk_saying_why(walks):
    with pytest.raises(NoContinuation, match="new version has no snippet at 30 fps"):
        walk_while_editing(walks, "to 60 fps", [{"op": "resample", "fps": 60}])
