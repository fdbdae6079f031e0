"""ALTER EXTENSION modb UPDATE from every released 0.x.0: the data, the snippets, the graphs and the
user's profiles stay, and the updated catalogue is what a fresh install of today's version has.

Each old version is installed as users install it, `CREATE EXTENSION modb VERSION 'old'`: only
0.1.0's and the newest install script are shipped, so PostgreSQL runs 0.1.0's and the upgrade chain
(extension/compare_chain.py showed, for every release, that the chain installs what its own install
script did).

What a fresh install of today's version stores for the same files is the same for every old
version: it is loaded once for the module (`fresh_load`). Each test loads and processes the old
version's data by that version. The `modb` command runs in this process (`process=False`): these
tests are about the data, not the command's process."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import psycopg
from psycopg.types.json import Jsonb
import pytest
from support.commands import run_modb
from support.data import mocap
from support.databases import scratch_database

from modb.database.connection import connect
from modb.synthesis.graphs import list_graphs


SNIPPET_ROWS = (
    "SELECT id, clip_id, first_frame, begin_terminator, net_heading FROM modb.snippets "
    "WHERE NOT mirrored ORDER BY id"
)

FEATURES = (
    "SELECT c.name, t.mirrored || '/' || t.frame, "
    "       (SELECT array_agg(cube_ll_coord(t.features, i) ORDER BY i) FROM generate_series(1, "
    "cube_dim(t.features)) i) "
    "FROM modb.terminators t JOIN modb.clips c ON c.id = t.clip_id ORDER BY 1, 2"
)

MIRRORED_TERMINATORS = (
    "SELECT c.name, t.frame, md5(t.rotations::text), md5(t.positions::text) FROM modb.terminators "
    "t "
    "JOIN modb.clips c ON c.id = t.clip_id WHERE t.mirrored ORDER BY 1, 2"
)


def _files() -> list:
    """The two CMU 131 trials (120 fps) each version loads."""
    return [mocap("cmu", "131", "131_01.amc"), mocap("cmu", "131", "131_02.amc")]


@pytest.fixture(scope="module")
def fresh_load(cluster):
    """What a fresh install of today's version stores for the files loaded with --mirror: the mirror
    images' terminators (MIRRORED_TERMINATORS) and every terminator's features (FEATURES)."""
    with scratch_database(cluster, f"upgrade_fresh_{os.getpid()}") as dsn:
        r = run_modb(dsn, "load", *_files(), "--mirror", process=False)
        assert r.returncode == 0, r.stderr
        with connect(dsn) as conn:
            return conn.execute(MIRRORED_TERMINATORS).fetchall(), conn.execute(FEATURES).fetchall()


OLD_VERSIONS = [
    "0.1.0",
    "0.2.0",
    "0.3.0",
    "0.4.0",
    "0.5.0",
    "0.6.0",
    "0.7.0",
    "0.8.0",
    "0.9.0",
    "0.10.0",
    "0.11.0",
    "0.12.0",
    "0.13.0",
    "0.14.0",
    "0.15.0",
    "0.16.0",
    "0.17.0",
    "0.18.0",
    "0.19.0",
    "0.20.0",
    "0.21.0",
    "0.22.0",
    "0.23.0",
    "0.24.0",
    "0.25.0",
    "0.26.0",
    "0.27.0",
    "0.28.0",
    "0.29.0",
]

# What a retargeting, an edit script and a cut store, without ids (sequences differ between runs):
# each version's own columns, and its frames, terminators and snippets as numbers (numpy's sums may
# differ in the last bit from run to run, with the arrays' alignment in memory).
STORED = """
SELECT v.clip_id, v.version, v.fps, v.n_frames, v.load_params, v.meta,
       (SELECT array_agg(x) FROM unnest(v.rotations) x),
       (SELECT array_agg(x) FROM unnest(v.translations) x),
       (SELECT array_agg(array_cat(ARRAY[t.heading, t.pelvis_height, t.frame, t.mirrored::int],
                                  t.positions || t.rotations || t.velocities || t.angular_velocities
                                  || (SELECT array_agg(x) FROM unnest(t.configuration) x))::float8[]
                         || (SELECT array_agg(cube_ll_coord(t.features, i) ORDER BY i)
                               FROM generate_series(1, cube_dim(t.features)) i)
                         ORDER BY t.mirrored, t.frame)
          FROM modb.terminators t WHERE t.clip_id = v.clip_id AND t.version = v.version),
       (SELECT array_agg(ARRAY[s.mirrored::int, s.first_frame, s.n_frames, s.net_heading,
                               s.future_heading] || s.net_translation || s.net_rotation
                         || s.future_translation ORDER BY s.mirrored, s.first_frame)
          FROM modb.snippets s WHERE s.clip_id = v.clip_id AND s.version = v.version)
  FROM modb.clip_versions v
 WHERE (v.clip_id, v.version) NOT IN (SELECT clip_id, version FROM kept)
 ORDER BY v.clip_id <> (SELECT min(clip_id) FROM kept), v.version
"""


def _retarget_and_edit(db) -> list:
    """A retargeting (at another rate) and an edit script (of a clip with mirror images), rolled
    back: what they stored. Clip ids are the caller's to compare (a rolled-back clip's id is not
    used again)."""
    with db.transaction(force_rollback=True):
        db.execute(
            "CREATE TEMP TABLE kept ON COMMIT DROP AS "
            "SELECT clip_id, version FROM modb.clip_versions"
        )
        first, second = [r[0] for r in db.execute("SELECT id FROM modb.clips ORDER BY id LIMIT 2")]
        skeleton = db.execute("SELECT min(id) FROM modb.skeletons").fetchone()[0]
        # not mirrored: 0.19.0 cut a mirrored retargeting's mirror images only (0.20.0 cuts both)
        db.execute("SELECT modb.retarget(%s, %s, 'retargeted', 60, false)", [second, skeleton])
        db.execute(
            "INSERT INTO modb.edit_scripts (name, commands) VALUES ('t', "
            '\'[{"op": "mirror"}, {"op": "smooth", "seconds": 0.1}, '
            '{"op": "trim", "start": 10, "end": 200}]\')'
        )
        db.execute("SELECT * FROM modb.apply_edit_script('t', ARRAY[%s]::bigint[])", [first])
        rows = db.execute(STORED).fetchall()
    return [(row[0] == first, *row[1:]) for row in rows]


def _steps_aligned_and_a_model(db) -> list:
    """0.21.0's processed data of the stored clips' left steps and a model row by hand."""
    collection = db.execute(
        "SELECT modb.collection_path(collection_id) FROM modb.clips WHERE id = 1"
    )
    collection = collection.fetchone()[0]
    for (clip,) in db.execute("SELECT id FROM modb.clips ORDER BY id").fetchall():
        db.execute("SELECT * FROM modb.annotate_steps(%s)", [clip])
    db.execute("SELECT * FROM modb.align_primitive('left_step', %s)", [collection])
    db.execute("INSERT INTO modb.models (name, kind, data) VALUES ('by hand', 'notes', '[1]')")
    return db.execute(PROCESSED).fetchall()


PROCESSED = (
    "SELECT id, clip_id, version, segment, md5(rotations::text) FROM modb.processed_data "
    "ORDER BY id"
)


def _models_in_versions(db, dsn, processed_before) -> None:
    assert len(processed_before) >= 5
    assert db.execute(PROCESSED).fetchall() == processed_before
    assert db.execute("SELECT count(*) FROM modb.processed_data WHERE mirrored").fetchone() == (0,)
    assert db.execute(
        "SELECT m.version, m.collection_id, s.stale FROM modb.models m "
        "JOIN modb.model_status s USING (id)"
    ).fetchall() == [(1, None, None)]
    with db.transaction(force_rollback=True):
        with pytest.raises(psycopg.errors.ObjectNotInPrerequisiteState):
            db.execute("UPDATE modb.models SET data = '[2]'")
    db.execute("INSERT INTO modb.models (name, kind, data) VALUES ('by hand', 'notes', '[2]')")
    assert db.execute("SELECT max(version) FROM modb.models").fetchone() == (2,)
    collection = db.execute("SELECT DISTINCT collection FROM modb.processed_data_status").fetchone()
    r = run_modb(dsn, "model", "build", "kept", "--collection", collection[0], "--primitive",
                 "left_step", process=False)  # fmt: skip
    assert r.returncode == 0 and "model kept version 1" in r.stdout, r.stderr
    assert db.execute("SELECT count(*) FROM modb.sample_motion('kept', 2, 0)").fetchone() == (2,)


def _step_models(db, dsn) -> tuple[str, list]:
    """0.22.0's models of the stored clips' left and right steps."""
    collection = db.execute(
        "SELECT modb.collection_path(collection_id) FROM modb.clips WHERE id = 1"
    ).fetchone()[0]
    for (clip,) in db.execute("SELECT id FROM modb.clips ORDER BY id").fetchall():
        db.execute("SELECT * FROM modb.annotate_steps(%s)", [clip])
    db.commit()
    for side in ("left", "right"):
        r = run_modb(dsn, "model", "build", f"{side} steps", "--collection", collection,
                     "--primitive", f"{side}_step", "-q", process=False)  # fmt: skip
        assert r.returncode == 0, r.stderr
    return collection, db.execute(MODELS).fetchall()


# (0.26.0 stamps each tree with its mixture's md5: the rest of meta stays)
MODELS = (
    "SELECT id, name, version, md5(data::text), md5((meta #- '{tree,mixture_md5}')::text) "
    "FROM modb.models ORDER BY id"
)


def _models_and_their_outputs(db, dsn) -> list:
    """0.23.0's step models and their graph, and what sampling and synthesis from them give: with
    the same seeds, 0.24.0's installed kernel must give the same (0.23.0 ran the kernel pasted into
    its functions)."""
    collection, _ = _step_models(db, dsn)
    r = run_modb(dsn, "model", "graph", "steps", "--collection", collection, process=False)
    assert r.returncode == 0, r.stderr
    return _model_outputs(db)


def _model_outputs(db) -> list:
    """Two samples and a walk of the step models; the walk with modb.foot_hold off (0.27.0 holds
    stance feet by default; off, it walks as the versions before did)."""
    db.execute("SELECT set_config('modb.foot_hold', 'off', false)")
    samples = db.execute(
        "SELECT sample, fps, n_frames, rotations, translations "
        "FROM modb.sample_motion('left steps', 2, 7) ORDER BY sample"
    ).fetchall()
    synthesized = db.execute(
        "SELECT * FROM modb.synthesize_from_models('steps', ARRAY[[0, 3], [2, 4]]::float8[], 3, 5)"
    ).fetchall()
    db.execute("RESET modb.foot_hold")
    assert len(samples) == 2 and len(synthesized) == 1
    return samples + synthesized


def _feet_held_after_the_update(db, unheld) -> None:
    """0.27.0's walk with the feet held (the default) keeps the walk's course and length and
    changes its frames; the walk 0.26.0 made is what modb.foot_hold = off gives (_model_outputs)."""
    held = db.execute(
        "SELECT * FROM modb.synthesize_from_models('steps', ARRAY[[0, 3], [2, 4]]::float8[], 3, 5)"
    ).fetchone()
    assert held[:2] == unheld[:2]  # fps, n_frames
    r_held, r_unheld = np.asarray(held[2]), np.asarray(unheld[2])
    assert np.abs(r_held - r_unheld).max() > 1e-3
    assert len(held[4]["steps"]) == len(unheld[4]["steps"])
    # the same walk (placed on the frames as joined, so the travel is the same to the bit); the
    # hold turns the legs only: the joints from the hips down
    assert np.array_equal(np.asarray(held[3]), np.asarray(unheld[3]))
    hierarchy, joint_map = db.execute(
        "SELECT s.hierarchy, s.joint_map FROM modb.graphs g JOIN modb.skeletons s "
        "ON s.id = g.skeleton_id WHERE g.name = 'steps'").fetchone()  # fmt: skip
    names = [j["name"] for j in hierarchy["joints"]]
    legs = {names.index(joint_map[f"{side}_hip"]) for side in ("left", "right")}
    for k, j in enumerate(hierarchy["joints"]):
        if j["parent"] in legs:
            legs.add(k)
    changed = set(np.flatnonzero(np.abs(r_held - r_unheld).max(axis=(0, 2)) > 1e-6).tolist())
    assert changed and changed <= legs, (changed, legs)


def _planned_walk(after, before) -> None:
    """0.28.0's planner: the same models walk the same course, turned their own way, reported as
    before (every field a step had it has); the strip as long."""
    assert after[:2] == before[:2]  # fps, n_frames
    assert after[4]["goals"] == before[4]["goals"] and after[4]["steps"]
    assert set(before[4]["steps"][0]) <= set(after[4]["steps"][0])
    assert "rested_from_frame" in after[4]


WALK = "SELECT fps, n_frames, rotations, report FROM modb.synthesize_from_models('steps', %s, 3, 5)"
AN_ACTION_NODE = """
UPDATE modb.graphs SET data = jsonb_set(
         data, '{nodes,an action}', (data->'nodes'->'left_step') || '{"type": "action"}')
       || jsonb_build_object('transitions', (data->'transitions') || '[{"from": "right_step",
          "to": "an action"}, {"from": "an action", "to": "left_step"}]')
 WHERE name = 'steps'
"""


def _walk_of_step_models(db, dsn) -> tuple:
    """0.28.0's family graph of step models and its walk; a graph with an action node refused."""
    collection, _ = _step_models(db, dsn)
    r = run_modb(dsn, "model", "graph", "steps", "--collection", collection, process=False)
    assert r.returncode == 0, r.stderr
    with db.transaction(force_rollback=True), pytest.raises(psycopg.errors.CheckViolation):
        db.execute(AN_ACTION_NODE)
    return db.execute(WALK, [[[0.0, 3.0]]]).fetchone()


def _actions_after_the_update(db, walk_before) -> None:
    """0.29.0: the same call walks the same walk; the new argument (actions) is there, refusing
    an action the graph has not; a graph may now have an action node."""
    after = db.execute(WALK, [[[0.0, 3.0]]]).fetchone()
    assert after[:3] == walk_before[:3] and after[3]["steps"] == walk_before[3]["steps"]
    with db.transaction(force_rollback=True), pytest.raises(psycopg.errors.InvalidParameterValue,
                                                            match=r"its actions: none"):
        db.execute("SELECT * FROM modb.synthesize_from_models('steps', '{{0, 3}}', 3, 5, 0.5, "
                   """'[{"primitive": "wave", "target": [0, 1, 2]}]')""")  # fmt: skip
    with db.transaction(force_rollback=True):
        db.execute(AN_ACTION_NODE)


POSE_EDITS = [{"op": "ik", "joint": "right_wrist", "time": 1.0, "offset": [0.0, 0.1, 0.0],
               "before": 0.5, "after": 0.5},
              {"op": "rotate", "joint": "left_elbow", "time": 1.0, "rotation": [0.0, 0.0, 20.0],
               "before": 0.5, "after": 0.5}]  # fmt: skip
STORE_SCRIPT = "INSERT INTO modb.edit_scripts (name, commands) VALUES ('pose', %s)"


def _pose_edits_refused(db) -> None:
    """0.29.0 knows no ik or rotate command: a script of them is refused."""
    with db.transaction(force_rollback=True), pytest.raises(psycopg.Error, match='"ik"'):
        db.execute(STORE_SCRIPT, [Jsonb(POSE_EDITS)])


def _pose_edits_after_the_update(db) -> None:
    """0.30.0 stores the script and applies it: a new version of the clip whose recorded script
    holds both commands, the frames before the blend as they were (all rolled back after: the
    data is compared with what it was below)."""
    with db.transaction(force_rollback=True):
        db.execute(STORE_SCRIPT, [Jsonb(POSE_EDITS)])
        (clip, version, _, _) = db.execute(
            "SELECT * FROM modb.apply_edit_script('pose', ARRAY[1::bigint])"
        ).fetchone()
        stored, before, after = db.execute(
            "SELECT n.load_params->'edit_script'->'commands', o.rotations[1:10], n.rotations[1:10] "
            "FROM modb.clip_versions o JOIN modb.clip_versions n USING (clip_id) "
            "WHERE clip_id = %s AND o.version = %s - 1 AND n.version = %s",
            [clip, version, version]).fetchone()  # fmt: skip
    assert [c["op"] for c in stored] == ["ik", "rotate"] and before == after


def _family_after_the_update(db, dsn) -> None:
    """Steps found again find the primitives beyond them and leave the step segments as they were:
    the models built from them stay current; the family graph keeps them and builds what it can."""
    status = "SELECT name, stale FROM modb.model_status ORDER BY name"
    before = db.execute(status).fetchall()
    assert [name for name, _ in before] == ["left steps", "right steps"]
    annotations = "SELECT sum(jsonb_array_length(meta->'annotations')) FROM modb.clip_versions"
    counted = db.execute(annotations).fetchone()[0]
    for (clip,) in db.execute("SELECT id FROM modb.clips ORDER BY id").fetchall():
        db.execute("SELECT * FROM modb.annotate_steps(%s)", [clip])
    db.commit()
    assert db.execute(annotations).fetchone()[0] >= counted
    assert db.execute(status).fetchall() == before and all(s is None for _, s in before)
    collection = db.execute(
        "SELECT modb.collection_path(collection_id) FROM modb.clips WHERE id = 1"
    ).fetchone()[0]
    r = run_modb(dsn, "model", "graph", "family", "--collection", collection, process=False)
    assert r.returncode == 0, r.stderr
    assert "kept (current): left steps, right steps" in r.stdout, r.stdout
    fps, n_frames = db.execute(
        "SELECT fps, n_frames FROM modb.synthesize_from_models('family', "
        "ARRAY[[0, 3]]::float8[], 2)").fetchone()  # fmt: skip
    assert n_frames == round(2 * fps) + 1


def _models_0_26_0_refuses(db) -> None:
    """Two rows 0.25.0 stored and 0.26.0 refuses: a model with fps 0 (it broke sampling) and a
    model whose meta holds a tree of another mixture (one dimension short)."""
    db.execute(
        "INSERT INTO modb.models (name, kind, skeleton_id, data, meta) "
        "SELECT 'broken', kind, skeleton_id, jsonb_set(data, '{fps}', '0'), '{}' "
        "FROM modb.models WHERE name = 'left steps'"
    )
    db.execute(
        "INSERT INTO modb.models (name, kind, skeleton_id, data, meta) "
        "SELECT 'foreign tree', kind, skeleton_id, data, "
        "jsonb_set(meta, '{tree,root,mean}', (meta->'tree'->'root'->'mean') - 0) "
        "FROM modb.models WHERE name = 'left steps'"
    )


def _models_repaired(db) -> None:
    names = {n for (n,) in db.execute("SELECT name FROM modb.models").fetchall()}
    assert "broken" not in names and {"foreign tree", "left steps", "right steps"} <= names
    repaired = db.execute(
        "SELECT old_value, problem, repaired_by FROM modb.repaired_rows "
        "WHERE table_name = 'models' ORDER BY id"
    ).fetchall()
    assert len(repaired) == 2, repaired
    (broken, problem, by), (foreign, tree_problem, _) = repaired
    assert broken["name"] == "broken" and broken["data"]["fps"] == 0 and by == "0.26.0"
    assert '"fps" must be a number from 1 to 1000' in problem
    assert "tree" in foreign["meta"] and "another mixture" in tree_problem
    assert db.execute(
        "SELECT meta ? 'tree', has_tree FROM modb.models WHERE name = 'foreign tree'"
    ).fetchone() == (False, False)
    # every tree kept is stamped with its own mixture; each version's inputs are rows of their own
    assert db.execute(
        "SELECT bool_and(meta->'tree'->>'mixture_md5' = modb.model_mixture_md5(data)), count(*) "
        "FROM modb.models WHERE meta ? 'tree'"
    ).fetchone() == (True, 2)
    assert db.execute(
        "SELECT bool_and((SELECT count(*) FROM modb.model_inputs i WHERE i.model_id = m.id) "
        "= jsonb_array_length(m.data->'inputs')) FROM modb.models m"
    ).fetchone() == (True,)
    current = db.execute("SELECT count(*) FROM modb.model_status WHERE stale IS NULL").fetchone()
    assert current[0] >= 2


def _same_outputs(after, before) -> None:
    """Equal, numbers to 1e-6 (numpy's sums may differ in the last bit between runs)."""
    if isinstance(before, (list, tuple)) and not isinstance(before, str):
        assert isinstance(after, (list, tuple)) and len(after) == len(before)
        for value, expected in zip(after, before, strict=True):
            _same_outputs(value, expected)
    elif isinstance(before, dict):
        assert isinstance(after, dict) and sorted(after) == sorted(before)
        for key in before:
            _same_outputs(after[key], before[key])
    elif isinstance(before, float):
        assert after == pytest.approx(before, abs=1e-6)
    else:
        assert after == before


def _graph_of_the_models(db, dsn, collection, models_before) -> None:
    assert len(models_before) == 2 and db.execute(MODELS).fetchall() == models_before
    r = run_modb(dsn, "model", "graph", "steps", "--collection", collection, process=False)
    assert r.returncode == 0 and "steps (graph of models): 2 nodes" in r.stdout, r.stderr
    fps, n_frames = db.execute(
        "SELECT fps, n_frames FROM modb.synthesize_from_models('steps', ARRAY[[0, 3]]::float8[], 2)"
    ).fetchone()
    assert n_frames == round(2 * fps) + 1


def test_old_versions_install_through_the_chain(db):
    # An install script left from an earlier install of the project would stand in for the chain.
    sharedir = db.execute("SELECT setting FROM pg_config WHERE name = 'SHAREDIR'").fetchone()[0]
    scripts = {p.name for p in (Path(sharedir) / "extension").glob("modb--*.sql")}
    # The newest release's install script ships until the next release (docs/development.md).
    installed = [v for v in OLD_VERSIONS[:-1] if f"modb--{v}.sql" in scripts]
    assert installed == ["0.1.0"], (
        f"{installed}: `make setup` removes installed modb scripts the project no longer ships"
    )


ENDING = "SELECT * FROM modb.{}(%s, ARRAY[0, 0, 0]::float8[], 0.5, %s, 'default', NULL, NULL, %s)"


def _endings(db) -> list:
    """Coming to rest and setting off from every 40th snippet, by the reference (the rule)."""
    ids = [r[0] for r in db.execute("SELECT id FROM modb.snippets ORDER BY id")][::40]
    calls = [(i, [1.5 - k % 4, 2.0 + k % 3], k % 2 == 0) for k, i in enumerate(ids)]
    rule = ENDING.format("select_snippet_ending_reference")
    return [(c, db.execute(rule, c).fetchall()) for c in calls]


def _endings_after_the_update(db, before: list) -> None:
    """The blocks the update found have no end bounds and answer as before; derived again, every
    block has them, and the fast path answers as the rule did before the update."""
    unbounded = (
        "SELECT count(*) FILTER (WHERE end_bounds IS NULL), count(*) FROM modb.snippet_blocks"
    )
    missing, blocks = db.execute(unbounded).fetchone()
    assert blocks > 0 and missing == blocks
    for packed in (False, True):
        if packed:
            db.execute("SELECT * FROM modb.pack_snippet_blocks(0)")
            assert db.execute(unbounded).fetchone()[0] == 0
        for call, rows in before:
            assert db.execute(ENDING.format("select_snippet_ending"), call).fetchall() == rows, call
    assert sum(bool(rows) for _, rows in before) >= len(before) // 2


@pytest.mark.parametrize("old", OLD_VERSIONS)
def test_update_keeps_the_data(fresh_db, db, old, fresh_load):
    current = db.execute(
        "SELECT default_version FROM pg_available_extensions WHERE name = 'modb'"
    ).fetchone()[0]
    db.execute("DROP EXTENSION modb")
    db.execute(f"CREATE EXTENSION modb VERSION '{old}'")
    with_snippets = old != "0.1.0"  # snippets (and mirror images) came with 0.2.0
    files = _files()
    r = run_modb(fresh_db, "load", *files, *(["--mirror"] if with_snippets else ["--no-snippets"]),
                 process=False)  # fmt: skip
    assert r.returncode == 0, r.stderr
    db.execute('UPDATE modb.clip_versions SET meta = \'{"tags": ["kept"]}\'')
    if old == "0.21.0":  # 0.22.0: models in versions; processed data may hold mirrored examples
        processed_before = _steps_aligned_and_a_model(db)
    if old == "0.22.0":  # 0.23.0: graphs of those models, and synthesis from them
        collection, models_before = _step_models(db, fresh_db)
    # 0.24.0: the kernel installed beside modb.so, no longer pasted; 0.25.0: the kernel computes
    # faster (graphs, cuts) and models build on one thread; 0.26.0: the kernel lets cancels in and
    # gives memory back; 0.27.0 holds stance feet unless modb.foot_hold is off: what they give
    # stays the same (0.28.0's planner turns the walk its own way: its samples stay the same)
    if old in ("0.23.0", "0.24.0", "0.25.0", "0.26.0", "0.27.0"):
        outputs_before = _models_and_their_outputs(db, fresh_db)
    if old == "0.25.0":  # 0.26.0 checks model documents: what it refuses is repaired
        _models_0_26_0_refuses(db)
    if old == "0.28.0":  # 0.29.0: actions beside the walk
        walk_before = _walk_of_step_models(db, fresh_db)
    if old == "0.29.0":  # 0.30.0: the ik and rotate edit commands
        _pose_edits_refused(db)
    before = db.execute(
        "SELECT clip_id, version, n_frames, meta, md5(rotations::text) FROM modb.clip_versions "
        "ORDER BY 1"
    ).fetchall()
    positions = db.execute("SELECT sum(x + 2 * y + 3 * z) FROM modb.world_positions(1)").fetchone()[
        0
    ]
    snippets = db.execute(SNIPPET_ROWS).fetchall() if with_snippets else []
    old_mirrored = db.execute(MIRRORED_TERMINATORS).fetchall() if with_snippets else []
    if with_snippets:
        db.execute(
            "INSERT INTO modb.match_profiles (name, settings) "
            "SELECT 'mine', settings FROM modb.match_profiles WHERE name = 'default'"
        )
        mine = db.execute(
            "SELECT settings FROM modb.match_profiles WHERE name = 'mine'"
        ).fetchone()[0]
    # A graph built before 0.5.0 stored no transitions: it keeps working through the box. One built
    # by 0.5.0 has no cost-to-go: it keeps ranking by where the candidates lead. One built by 0.6.0
    # or later keeps its costs (0.8.0's wider feature cube changes no transition).
    if old in ("0.4.0", "0.5.0", "0.6.0", "0.7.0", "0.8.0", "0.9.0"):
        db.execute("SELECT modb.build_transition_graph('old', 'locomotion', NULL, 0)")
    if (
        old == "0.18.0"
    ):  # the last in-server build: the oracle for the build in three steps (0.19.0)
        db.execute("SELECT modb.build_transition_graph('before', 'locomotion', NULL, 0)")
    if old == "0.19.0":  # the last in-server code: the oracle for the kernel's that workers run too
        stored_before = _retarget_and_edit(db)
    if old == "0.28.0":  # 0.29.0: blocks' end bounds; the rule's level compared as float8
        endings_before = _endings(db)
    db.execute("ALTER EXTENSION modb UPDATE")
    if old == "0.28.0":
        _endings_after_the_update(db, endings_before)
        _actions_after_the_update(db, walk_before)
    if old == "0.29.0":
        _pose_edits_after_the_update(db)
    if old == "0.21.0":
        _models_in_versions(db, fresh_db, processed_before)
    if old == "0.22.0":
        _graph_of_the_models(db, fresh_db, collection, models_before)
    if old == "0.25.0":
        _models_repaired(db)
    if old in ("0.23.0", "0.24.0", "0.25.0", "0.26.0", "0.27.0"):
        after = _model_outputs(db)  # this session, after the update
        _same_outputs(after[:2], outputs_before[:2])  # the samples
        _planned_walk(after[2], outputs_before[2])
        if old == "0.26.0":  # 0.27.0: stance feet held by default, the legs alone turned
            _feet_held_after_the_update(db, after[2])
        with psycopg.connect(fresh_db) as new_session:
            _same_outputs(_model_outputs(new_session), after)
    if old == "0.19.0":
        stored_after = _retarget_and_edit(db)
        assert len(stored_before) == 2 and all(row[-1] for row in stored_before)
        for made, oracle_row in zip(stored_after, stored_before, strict=True):
            assert made[:6] == oracle_row[:6]
            for numbers, oracle in zip(made[6:], oracle_row[6:], strict=True):
                assert np.allclose(np.asarray(numbers), np.asarray(oracle), rtol=1e-9, atol=1e-12)
    if old == "0.20.0":  # 0.21.0: steps written as segments with keyframes, which the check allows
        with db.transaction(force_rollback=True):
            steps = db.execute("SELECT name, keyframes FROM modb.annotate_steps(1)").fetchall()
            # a step's keyframes are its ends; a start's and a stop's (0.28.0) three
            assert steps and all(len(k) == (2 if n.endswith("_step") else 3) for n, k in steps)
            marked = db.execute(
                "SELECT count(*) FROM modb.current_clips c "
                "JOIN modb.clip_versions v USING (clip_id, version), "
                "jsonb_array_elements(v.meta->'annotations') a "
                "WHERE c.clip_id = 1 AND (a->>'auto')::boolean"
            ).fetchone()[0]
            assert marked == len(steps)
    if old == "0.18.0":
        db.execute("SELECT modb.build_transition_graph('after', 'locomotion', NULL, 0)")
        graphs = [
            db.execute(
                "SELECT g.data - 'collection', "
                "array_agg((t.from_snippet, t.to_snippets, t.cost_to_go) ORDER BY t.from_snippet)"
                "  FROM modb.graphs g JOIN modb.graph_transitions t ON t.graph_id = g.id "
                " WHERE g.name = %s GROUP BY g.id",
                [name],
            ).fetchone()
            for name in ("before", "after")
        ]
        assert graphs[0] is not None and graphs[0] == graphs[1]
    if old in ("0.4.0", "0.5.0", "0.6.0", "0.7.0", "0.8.0", "0.9.0"):
        stored, costs = db.execute(
            "SELECT count(*), count(cost_to_go) FROM modb.graph_transitions"
        ).fetchone()
        assert (stored > 0) == (old != "0.4.0") and costs == (stored if old >= "0.6.0" else 0), (
            stored,
            costs,
        )
        db.execute("SET modb.graph = 'old'")
        chosen, in_graph = db.execute(
            "SELECT count(*), count(g.snippet_id) FROM modb.synthesize('{{0,3}}', 4) s "
            "LEFT JOIN modb.graph_snippets g USING (snippet_id)"
        ).fetchone()
        assert chosen == 4 and in_graph == chosen
        db.execute("RESET modb.graph")
        # else rebuild it
        assert next(g for g in list_graphs(db) if g.name == "old").current == (old >= "0.6.0")
    assert (
        db.execute("SELECT extversion FROM pg_extension WHERE extname = 'modb'").fetchone()[0]
        == current
    )
    assert (
        db.execute(
            "SELECT clip_id, version, n_frames, meta, md5(rotations::text) FROM modb.clip_versions "
            "ORDER BY 1"
        ).fetchall()
        == before
    )
    if old == "0.27.0":  # 0.28.0: the primitives beyond steps, the family graph over the models
        _family_after_the_update(db, fresh_db)
    assert (
        db.execute("SELECT sum(x + 2 * y + 3 * z) FROM modb.world_positions(1)").fetchone()[0]
        == positions
    )
    if with_snippets:
        assert db.execute(SNIPPET_ROWS).fetchall() == snippets
        # 0.2.0's mirror images had rotations in other joint frames: the update rebuilt them, as a
        # fresh install's load would (compared after the reinstall below).
        updated_mirrored = db.execute(MIRRORED_TERMINATORS).fetchall()
        updated_features = db.execute(FEATURES).fetchall()
        assert len(updated_mirrored) == len(old_mirrored)
        assert (updated_mirrored != old_mirrored) == (old == "0.2.0")
        assert db.execute("SELECT count(*) FROM modb.snippets WHERE mirrored").fetchone()[0] > 0
        # 0.10.0: every stored snippet is in a block, and the C selection answers as the reference
        assert db.execute(
            "SELECT count(*) FROM modb.snippets s WHERE NOT EXISTS "
            "(SELECT FROM modb.snippet_blocks b WHERE s.id = ANY (b.snippets))"
        ).fetchone() == (0,)
        # 0.11.0: the blocks a load left are packed; a load packed them already since 0.11.0
        # 0.18.0: the update leaves the blocks as they were (no term codes) and builds the
        # directory's index; they count as unpacked, so a load's packing derives them again
        uncoded = "SELECT count(*) FILTER (WHERE term_codes IS NULL) FROM modb.snippet_blocks"
        coded_before = OLD_VERSIONS[OLD_VERSIONS.index("0.18.0") :]  # 0.18.0 on coded them
        assert (db.execute(uncoded).fetchone()[0] > 0) == (old not in coded_before)
        assert db.execute("SELECT to_regclass('modb.snippet_blocks_directory_idx')").fetchone()[0]
        db.execute("SELECT * FROM modb.pack_snippet_blocks(0.2)")
        assert (
            db.execute(
                "SELECT count(*) FILTER (WHERE term_codes IS NULL OR term_bounds IS NULL"
                " OR octet_length(term_codes) <> 114 * cardinality(snippets)), count(*)"
                " FROM modb.snippet_blocks"
            ).fetchone()[0]
            == 0
        )
        assert db.execute(
            "SELECT count(*) FILTER (WHERE pack_order IS NULL) FROM modb.snippet_blocks"
        ).fetchone() == (0,)
        for (prev,) in db.execute("SELECT id FROM modb.snippets ORDER BY id LIMIT 5 OFFSET 200"):
            fast, reference = (
                db.execute(
                    f"SELECT snippet_id, relax_level FROM modb.{f}(%s, '{{1, 2}}', 3)", [prev]
                ).fetchall()
                for f in ("select_next_snippets", "select_next_snippets_reference")
            )
            assert fast == reference and fast, prev
        assert (
            db.execute(
                "SELECT count(*) FROM modb.snippets WHERE future_translation IS NULL"
            ).fetchone()[0]
            == 0
        )
        assert (
            db.execute("SELECT settings FROM modb.match_profiles WHERE name = 'mine'").fetchone()[0]
            == mine
        )
        # 0.3.0 retuned the shipped default; the copy the user made keeps 0.2.0's
        if old == "0.2.0":
            assert (
                mine
                != db.execute(
                    "SELECT settings FROM modb.match_profiles WHERE name = 'default'"
                ).fetchone()[0]
            )
    else:
        (added,) = db.execute("SELECT modb.build_snippets()").fetchone()
        assert added > 0
    assert (
        db.execute("SELECT count(*) FROM modb.select_next_snippet(NULL, '{0,2}')").fetchone()[0]
        == 1
    )
    assert db.execute("SELECT count(*) FROM modb.synthesize('{{0,3}}', 4)").fetchone()[0] == 4
    # Lower body, no turn asked for: under the default profile (tuned at 30 fps) these two 120 fps
    # clips have no component that turns 45 degrees each way.
    db.execute("SELECT modb.build_transition_graph('g', 'locomotion', NULL, 0)")
    stored, costs = db.execute(
        "SELECT count(*), count(e.cost_to_go) FROM modb.graph_transitions e "
        "JOIN modb.graphs g ON g.id = e.graph_id WHERE g.name = 'g'"
    ).fetchone()
    assert stored > 0 and costs == stored
    assert next(g for g in list_graphs(db) if g.name == "g").current
    db.execute("SET modb.graph = 'g'")
    chosen, in_graph = db.execute(
        "SELECT count(*), count(g.snippet_id) FROM modb.synthesize('{{0,3}}', 4) s "
        "LEFT JOIN modb.graph_snippets g USING (snippet_id)"
    ).fetchone()
    assert chosen > 0 and in_graph == chosen
    db.execute("RESET modb.graph")
    # What a fresh install of the current version has, the updated one has: same objects, same
    # definitions.
    objects = (
        "SELECT pg_describe_object(classid, objid, 0) FROM pg_depend WHERE refobjid = "
        "(SELECT oid FROM pg_extension WHERE extname = 'modb') AND deptype = 'e' ORDER BY 1"
    )
    updated = [r[0] for r in db.execute(objects).fetchall()]
    functions = (
        "SELECT p.oid::regprocedure::text, md5(pg_get_functiondef(p.oid)), obj_description(p.oid, "
        "'pg_proc') FROM pg_proc p "
        "WHERE pronamespace = 'modb'::regnamespace AND prokind = 'f' ORDER BY 1"
    )
    updated_functions = db.execute(functions).fetchall()
    acls = (
        "SELECT c.relname, c.relacl::text FROM pg_class c "
        "WHERE relnamespace = 'modb'::regnamespace ORDER BY 1"
    )
    column_acls = (
        "SELECT a.attrelid::regclass::text, a.attname, a.attacl::text FROM pg_attribute a "
        "JOIN pg_class c ON c.oid = a.attrelid "
        "WHERE c.relnamespace = 'modb'::regnamespace AND a.attacl IS NOT NULL ORDER BY 1, 2"
    )
    grants = (
        "SELECT p.oid::regprocedure::text, p.proacl::text FROM pg_proc p "
        "WHERE pronamespace = 'modb'::regnamespace ORDER BY 1"
    )
    # 0.11.0 altered a table: its columns (type, NOT NULL) and constraints are compared too.
    shapes = (
        "SELECT c.relname, a.attname, format_type(a.atttypid, a.atttypmod), a.attnotnull "
        "FROM pg_attribute a JOIN pg_class c ON c.oid = a.attrelid "
        "WHERE c.relnamespace = 'modb'::regnamespace AND c.relkind = 'r' AND a.attnum > 0 "
        "AND NOT a.attisdropped "
        "UNION ALL SELECT t.relname, o.conname, pg_get_constraintdef(o.oid), NULL "
        "FROM pg_constraint o JOIN pg_class t ON t.oid = o.conrelid "
        "WHERE t.relnamespace = 'modb'::regnamespace "
        "ORDER BY 1, 2"
    )
    updated_shapes = db.execute(shapes).fetchall()
    updated_acls, updated_grants = db.execute(acls).fetchall(), db.execute(grants).fetchall()
    updated_column_acls = db.execute(column_acls).fetchall()
    db.execute("DROP ROLE IF EXISTS t_updated_reader")
    db.execute("CREATE ROLE t_updated_reader LOGIN IN ROLE modb_reader")
    try:
        with psycopg.connect(
            psycopg.conninfo.make_conninfo(fresh_db, user="t_updated_reader")
        ) as reader:
            assert (
                reader.execute(
                    "SELECT count(*) FROM modb.select_next_snippet(NULL, '{0,2}')"
                ).fetchone()[0]
                == 1
            )
    finally:
        db.execute("DROP ROLE t_updated_reader")
    db.execute("DROP EXTENSION modb CASCADE")
    db.execute("CREATE EXTENSION modb")
    assert [r[0] for r in db.execute(objects).fetchall()] == updated
    assert db.execute(functions).fetchall() == updated_functions
    if old == "0.10.0":  # (earlier releases' own changes are not re-checked here)
        assert db.execute(shapes).fetchall() == updated_shapes
    assert (
        db.execute(acls).fetchall() == updated_acls
        and db.execute(grants).fetchall() == updated_grants
        and db.execute(column_acls).fetchall() == updated_column_acls
    )
    if with_snippets:  # what the files loaded into a fresh install store (fresh_load)
        fresh_mirrored, fresh = fresh_load
        assert fresh_mirrored == updated_mirrored
        # 0.8.0's update computes the new feature dimensions in SQL from the stored rotations; a
        # load computes them in the kernel from float8: the same cube, to float4 rounding.
        assert [r[:2] for r in fresh] == [r[:2] for r in updated_features]
        difference = np.abs(
            np.array([r[2] for r in fresh]) - np.array([r[2] for r in updated_features])
        )
        assert difference.shape[1] == 49 and difference.max() < 1e-6, difference.max(axis=0)
