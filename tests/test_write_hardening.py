"""Writes that must hold under concurrency and bad input (issue 39, parts 2 to 5), checked in the
database so every writer (SQL, REST, the command line) meets them: two sessions editing one clip
both succeed in turn; block packing never deadlocks with writers; a clip named twice is edited
once; one frame-rate range and a cap on a result's size, checked before any work; stored
documents (joint axes, joint maps, edit scripts, collection names) checked by type; and the errors
of these say what, which object and what to do, never a constraint's name."""

from __future__ import annotations

import json
import os
import threading

import psycopg
import pytest
from support.commands import run_modb
from support.data import mocap

WALK = ("bandai-1", "data", "dataset-1_walk_active_001.bvh")  # 146 frames at 30 fps


@pytest.fixture
def walk(fresh_db) -> tuple[str, int]:
    """A database holding one short walk, cut into snippets; (conninfo, its clip id)."""
    r = run_modb(fresh_db, "load", mocap(*WALK), "--collection", "walks", "-q")
    assert r.returncode == 0, r.stderr
    with psycopg.connect(fresh_db) as conn:
        (clip,) = conn.execute("SELECT clip_id FROM modb.current_clips").fetchone()
    return fresh_db, clip


def save_script(dsn: str, name: str, commands: list) -> None:
    with psycopg.connect(dsn, autocommit=True) as conn:
        conn.execute(
            "INSERT INTO modb.edit_scripts (name, commands) VALUES (%s, %s)",
            [name, json.dumps(commands)],
        )


def refusal(dsn: str, sql: str, params=()) -> str:
    """The message of the error the statement raises (the test fails when it raises none), which
    must read in words: no Python exception names before it."""
    with psycopg.connect(dsn, autocommit=True) as conn:
        with pytest.raises(psycopg.Error) as raised:
            conn.execute(sql, params)
    message = raised.value.diag.message_primary or ""
    assert not message.startswith(("plpy.", "spiexceptions.")), message
    return message


def versions(dsn: str, clip: int) -> int:
    with psycopg.connect(dsn) as conn:
        return conn.execute(
            "SELECT count(*) FROM modb.clip_versions WHERE clip_id = %s", [clip]
        ).fetchone()[0]


def in_threads(*loops) -> list[BaseException]:
    """Runs the callables side by side; the exceptions they raised."""
    errors: list[BaseException] = []

    def guarded(loop):
        try:
            loop()
        except BaseException as e:  # noqa: BLE001 - collected for the assertion
            errors.append(e)

    threads = [threading.Thread(target=guarded, args=(loop,)) for loop in loops]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return errors


def test_two_sessions_editing_one_clip_both_succeed_in_turn(walk):
    dsn, clip = walk
    save_script(dsn, "mirror", [{"op": "mirror"}])
    rounds = 3

    def edits():
        with psycopg.connect(dsn, autocommit=True) as conn:
            for _ in range(rounds):
                conn.execute("SELECT * FROM modb.apply_edit_script('mirror', %s)", [[clip]])

    assert in_threads(edits, edits) == []
    assert versions(dsn, clip) == 1 + 2 * rounds
    with psycopg.connect(dsn) as conn:  # each edit started from the one before it
        froms = conn.execute(
            "SELECT (load_params->'edit_script'->>'from_version')::int FROM modb.clip_versions "
            "WHERE clip_id = %s AND version > 1 ORDER BY version",
            [clip],
        ).fetchall()
    assert [f for (f,) in froms] == list(range(1, 1 + 2 * rounds))


def test_packing_blocks_never_deadlocks_with_a_writer_of_a_new_frame_rate(walk):
    """The order that deadlocked: a packing holds the blocks' generation row while a writer deletes
    the clip's old blocks (a new version at another rate, the old one's blocks not packed yet); the
    packing then deletes that pool's blocks. Each waits where it would, so the result does not
    depend on timing."""
    dsn, clip = walk
    save_script(dsn, "at 25", [{"op": "resample", "fps": 25}])
    save_script(dsn, "at 24", [{"op": "resample", "fps": 24}])
    with psycopg.connect(dsn) as conn:  # version 2, in blocks of consecutive snippets (unpacked)
        conn.execute("SELECT * FROM modb.apply_edit_script('at 25', %s)", [[clip]])
    with psycopg.connect(dsn) as packer, psycopg.connect(dsn, autocommit=True) as writer:
        packer.execute("SELECT FROM modb.generations WHERE name = 'snippet_blocks' FOR UPDATE")
        writer_pid = writer.info.backend_pid

        errors: list[BaseException] = []

        def write():
            errors.extend(
                in_threads(
                    lambda: writer.execute(
                        "SELECT * FROM modb.apply_edit_script('at 24', %s)", [[clip]]
                    )
                )
            )

        thread = threading.Thread(target=write)
        thread.start()
        with psycopg.connect(dsn, autocommit=True) as watcher:  # until the writer waits on a lock
            while (
                thread.is_alive()
                and not watcher.execute(
                    "SELECT wait_event_type = 'Lock' FROM pg_stat_activity WHERE pid = %s",
                    [writer_pid],
                ).fetchone()[0]
            ):
                watcher.execute("SELECT pg_sleep(0.05)")
        packer.execute("SELECT * FROM modb.pack_snippet_blocks(0)")
        packer.commit()
        thread.join()
    assert errors == []
    assert versions(dsn, clip) == 3


def test_a_clip_named_twice_is_edited_once(walk):
    dsn, clip = walk
    save_script(dsn, "slower", [{"op": "time_stretch", "factor": 2}])
    with psycopg.connect(dsn) as conn:
        rows = conn.execute(
            "SELECT clip_id, version, n_frames FROM modb.apply_edit_script('slower', %s)",
            [[clip, clip]],
        ).fetchall()
    assert rows == [(clip, 2, 291)]  # 146 frames twice as long once: (146 - 1) * 2 + 1
    assert versions(dsn, clip) == 2


def test_results_past_the_cap_are_refused_before_any_work(walk):
    dsn, clip = walk
    save_script(dsn, "huge", [{"op": "time_stretch", "factor": 20}] * 3)
    e = refusal(dsn, "SELECT * FROM modb.apply_edit_script('huge', %s)", [[clip]])
    # (146 - 1) * 20 ** 3 + 1 frames: the would-be size and the cap, in the message
    assert "1,160,001 frames" in e and "50,000 frames" in e, e
    # as large on the way and trimmed back: the largest step counts, not only the result
    save_script(
        dsn,
        "huge between",
        [{"op": "time_stretch", "factor": 20}] * 3 + [{"op": "trim", "start": 0, "end": 60}],
    )
    e = refusal(dsn, "SELECT * FROM modb.apply_edit_script('huge between', %s)", [[clip]])
    assert "a step would have 1,160,001 frames" in e, e
    assert versions(dsn, clip) == 1
    with psycopg.connect(dsn) as conn:
        (skeleton,) = conn.execute("SELECT skeleton_id FROM modb.current_clips").fetchone()
    for fps in (9999, 0.01):  # one frame-rate range: the loader's 1 to 1000
        e = refusal(dsn, "SELECT modb.retarget(%s, %s, fps => %s)", [clip, skeleton, fps])
        assert "from 1 to 1000" in e, e


def test_a_rate_too_low_for_snippets_says_so(walk):
    dsn, clip = walk
    save_script(dsn, "one fps", [{"op": "resample", "fps": 1}])
    e = refusal(dsn, "SELECT * FROM modb.apply_edit_script('one fps', %s)", [[clip]])
    assert "snippets need 2" in e and "2 fps or more" in e, e
    assert "check" not in e, e
    assert versions(dsn, clip) == 1


def test_retargeting_from_a_skeleton_without_length_says_so(walk):
    dsn, clip = walk
    with psycopg.connect(dsn) as conn:
        # the walk's skeleton with every bone of length 0 (a key of its own: another identity),
        # and the walk on it
        (flat,) = conn.execute(
            """INSERT INTO modb.skeletons (name, hierarchy, joint_map, mirror_pairs)
               SELECT 'flat', jsonb_set(s.hierarchy || '{"test": "flat"}', '{joints}', (
                          SELECT jsonb_agg(jsonb_set(j, '{offset}', '[0, 0, 0]') ORDER BY n)
                            FROM jsonb_array_elements(s.hierarchy->'joints')
                                 WITH ORDINALITY AS t(j, n))),
                      s.joint_map, s.mirror_pairs
                 FROM modb.skeletons s RETURNING id"""
        ).fetchone()
        (copy,) = conn.execute(
            """INSERT INTO modb.clips (collection_id, name)
               SELECT collection_id, 'flat walk' FROM modb.clips WHERE id = %s RETURNING id""",
            [clip],
        ).fetchone()
        conn.execute(
            """INSERT INTO modb.clip_versions (clip_id, skeleton_id, fps, n_frames, rotations,
                                               translations)
               SELECT %s, %s, fps, n_frames, rotations, translations FROM modb.clip_versions
                WHERE clip_id = %s""",
            [copy, flat, clip],
        )
        (skeleton,) = conn.execute(
            "SELECT skeleton_id FROM modb.current_clips WHERE clip_id = %s", [clip]
        ).fetchone()
    e = refusal(dsn, "SELECT modb.retarget(%s, %s)", [copy, skeleton])
    assert "legs have no length" in e and f"clip {copy}" in e, e
    assert "finite_check" not in e, e


@pytest.mark.parametrize(
    "axes, says",
    [
        (
            {"joints": {"pelvis": {"joint": "Hips", "twist": ["a", "b", "c"], "swing": [0, 1, 0]}}},
            "lists of three numbers",
        ),
        (
            {"joints": {"pelvis": {"joint": "Hips", "twist": [[1], [0], [0]], "swing": [0, 1, 0]}}},
            "lists of three numbers",
        ),
        ({"joints": {}, "pose": ["a"]}, '"pose" must be null or a list'),
    ],
)
def test_joint_axes_must_be_numbers(walk, axes, says):
    dsn, _ = walk
    e = refusal(dsn, "UPDATE modb.skeletons SET joint_axes = %s", [json.dumps(axes)])
    assert says in e and "skeleton" in e, e


def test_a_joint_map_cannot_be_emptied(walk):
    dsn, _ = walk
    e = refusal(dsn, "UPDATE modb.skeletons SET joint_map = '{}'")
    assert "cannot be emptied" in e, e


def test_edit_scripts_are_lists_of_known_commands(walk):
    dsn, _ = walk
    e = refusal(
        dsn, "INSERT INTO modb.edit_scripts (name, commands) VALUES ('bad', '[1, \"x\", null]')"
    )
    assert 'edit script "bad"' in e and "command 1" in e, e
    e = refusal(
        dsn,
        "INSERT INTO modb.edit_scripts (name, commands) VALUES "
        '(\'typed\', \'[{"op": "resample", "fps": "30"}]\')',
    )
    assert '"fps" must be a number from 1 to 1000' in e, e


def test_scripts_stored_before_the_check_are_listed_and_refused_in_words(walk):
    dsn, clip = walk
    with psycopg.connect(dsn, autocommit=True) as conn:  # as a row of 0.16.0 would be
        conn.execute("ALTER TABLE modb.edit_scripts DISABLE TRIGGER edit_scripts_check_commands")
        conn.execute(
            "INSERT INTO modb.edit_scripts (name, commands) VALUES ('old', '[1, \"x\", null]')"
        )
        conn.execute("ALTER TABLE modb.edit_scripts ENABLE TRIGGER edit_scripts_check_commands")
    r = run_modb(dsn, "edit", "list")
    assert r.returncode == 0 and "old: ?, ?, ?" in r.stdout, r.stderr
    e = refusal(dsn, "SELECT * FROM modb.apply_edit_script('old', %s)", [[clip]])
    assert 'edit script "old" cannot run' in e, e


@pytest.mark.parametrize("path", ["../..", "walks/./x", "a/../b"])
def test_collection_paths_are_names(walk, path):
    dsn, _ = walk
    e = refusal(dsn, "SELECT modb.ensure_collection(%s)", [path])
    assert "cannot be named" in e, e


def test_the_update_repairs_rows_the_checks_would_refuse(cluster):
    """Rows 0.16.0 stored that 0.17.0's checks refuse do not stop ALTER EXTENSION UPDATE: each is
    repaired with a WARNING saying what was done (else a dump of the database would not restore)."""
    name = f"write_hardening_update_{os.getpid()}"
    with psycopg.connect(cluster.dsn("postgres"), autocommit=True) as admin:
        admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        admin.execute(f'CREATE DATABASE "{name}"')
    try:
        with psycopg.connect(cluster.dsn(name), autocommit=True) as conn:
            conn.execute("CREATE EXTENSION modb VERSION '0.16.0' CASCADE")
            conn.execute(
                """INSERT INTO modb.skeletons (name, hierarchy, joint_axes)
                   VALUES ('one', '{"unit_m": 1,
                     "joints": [{"name": "Hips", "parent": -1, "offset": [0, 0, 0]}]}',
                   '{"joints": {"pelvis": {"joint": "Hips", "twist": ["a", "b", "c"],
                                           "swing": [0, 1, 0]}}}')"""
            )
            conn.execute("SELECT modb.ensure_collection('../..')")
            conn.execute(
                "INSERT INTO modb.edit_scripts (name, commands) VALUES ('bad', '[1, \"x\", null]')"
            )
            notices: list[str] = []
            conn.add_notice_handler(lambda d: notices.append(d.message_primary or ""))
            conn.execute("ALTER EXTENSION modb UPDATE")
            assert conn.execute("SELECT joint_axes FROM modb.skeletons").fetchone()[0] == {}
            assert conn.execute(
                "SELECT array_agg(name ORDER BY id) FROM modb.collections"
            ).fetchone()[0] == ["renamed 1", "renamed 2"]
            assert conn.execute("SELECT count(*) FROM modb.edit_scripts").fetchone()[0] == 0
            kept = conn.execute(
                "SELECT table_name, old_value FROM modb.repaired_rows ORDER BY id"
            ).fetchall()  # nothing lost: every old value kept
            tables = [t for t, _ in kept]
            assert tables == ["skeletons", "collections", "collections", "edit_scripts"]
            assert kept[0][1]["joint_axes"]["joints"]["pelvis"]["twist"] == ["a", "b", "c"]
            assert [v["name"] for _, v in kept[1:3]] == ["..", ".."]
            assert kept[3][1]["commands"] == [1, "x", None]
        said = "\n".join(notices)
        assert "joint_axes" in said and 'collection "../.."' in said, said
        assert 'edit script "bad" is deleted' in said and '[1, "x", null]' in said, said
    finally:
        with psycopg.connect(cluster.dsn("postgres"), autocommit=True) as admin:
            admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
