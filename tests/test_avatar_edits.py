"""An avatar walking while someone edits the clip it is playing: the edit rebuilds that clip's
snippets (the snippet the chain continues from is gone), and the walk goes on from where it was."""

from __future__ import annotations

import os

import psycopg
import pytest
from support.data import mocap
from support.databases import scratch_database
from test_cli_hardening import WALKS, modb

from modb.database.connection import connect
from modb.synthesis.avatar import Avatar
from modb.synthesis.chain import Settings


@pytest.fixture(scope="module")
def walks(cluster):
    files = [mocap("bandai-1", "data", name) for name in WALKS]
    with scratch_database(cluster, f"avatar_edits_{os.getpid()}") as dsn:
        r = modb(dsn, "load", *files, "--collection", "walks", "-q")
        assert r.returncode == 0, r.stderr
        yield dsn


def test_the_walk_goes_on_when_an_edit_drops_the_snippet_it_continues_from(walks):
    with connect(walks) as conn, psycopg.connect(walks, autocommit=True) as editor:
        editor.execute(
            "INSERT INTO modb.edit_scripts (name, commands) "
            """VALUES ('smooth', '[{"op": "smooth", "seconds": 0.05}]')"""
        )
        # as the web view's avatar: the readout counts the candidates each choice examined
        avatar = Avatar(conn, goals=[(0.0, 30.0)], settings=Settings(count_candidates=True))
        edited = None
        for _ in avatar.frames():
            if edited is None:  # the first snippet is playing: its clip gets a new version
                first = avatar.choices[0]
                editor.execute(
                    "SELECT * FROM modb.apply_edit_script('smooth', %s)", [[first.clip_id]]
                )
                (gone,) = editor.execute(
                    "SELECT NOT EXISTS (SELECT FROM modb.snippets WHERE id = %s)",
                    [first.snippet_id],
                ).fetchone()
                assert gone, "the edit should have dropped the playing clip's old snippets"
                edited = first.snippet_id
            if len(avatar.choices) == 4:
                break
    assert [c.step for c in avatar.choices] == [0, 1, 2, 3]
    assert any(f"snippet {edited} was rebuilt" in note for note in avatar.notes), avatar.notes
