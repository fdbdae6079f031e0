"""select_next_snippet as a user meets it: relaxation, exclusion, the plan, privileges, upgrades, mirroring."""
from __future__ import annotations

import os

import numpy as np
import psycopg
import pytest

from conftest import REPO, mocap, plan_nodes, run_modb, scratch_database
from modb.database.connection import connect
from modb.synthesis.graphs import list_graphs


@pytest.fixture(scope="module")
def cmu(cluster):
    """CMU 131 (14 ASF/AMC trials, 120 fps) with snippets and their mirror images."""
    with scratch_database(cluster, f"behaviour_{os.getpid()}") as dsn:
        r = run_modb(dsn, "load", *sorted(mocap("cmu", "131").glob("*.amc")), "--collection", "cmu/131", "--mirror")
        assert r.returncode == 0, r.stderr
        yield dsn


def test_snippet_windows_follow_the_frame_rate(cmu):
    with connect(cmu) as conn:
        rows = conn.execute("SELECT DISTINCT window_frames, stride_frames FROM modb.snippet_sources").fetchall()
        assert rows == [(61, 4)]  # 0.5 s at 120 fps (+1: the seam frame), one start every 1/30 s
        n_frames = dict(conn.execute("SELECT clip_id, n_frames FROM modb.current_clips").fetchall())
        per_clip = conn.execute("SELECT clip_id, count(*), max(first_frame + n_frames) FROM modb.snippets "
                                "WHERE NOT mirrored GROUP BY clip_id").fetchall()
        for clip_id, count, end in per_clip:
            assert count == len(range(0, n_frames[clip_id] - 61 + 1, 4)) and end <= n_frames[clip_id]
        (mirrored,) = conn.execute("SELECT count(*) FROM modb.snippets WHERE mirrored").fetchone()
        assert mirrored == sum(c for _, c, _ in per_clip)  # one call doubles the data


def test_mirror_images_turn_the_other_way(cmu):
    with connect(cmu) as conn:
        rows = conn.execute(
            "SELECT a.net_translation, b.net_translation, a.net_heading, b.net_heading FROM modb.snippets a "
            "JOIN modb.snippets b USING (clip_id, version, first_frame) WHERE NOT a.mirrored AND b.mirrored").fetchall()
    a = np.array([r[0] for r in rows]); b = np.array([r[1] for r in rows])
    # CMU 131's captured skeleton is not exactly symmetric (arms differ by up to ~1.5 cm): mm-level agreement.
    assert np.abs(b - a * [-1, 1, 1]).max() < 0.01
    turn_error = np.abs(np.array([r[3] for r in rows]) + np.array([r[2] for r in rows]))
    assert np.median(turn_error) < 0.002 and turn_error.max() < 0.1  # the hip axis feels the asymmetry most


def test_relaxation_levels_and_the_last_resort(cmu):
    with connect(cmu) as conn:
        prev, clip, last = conn.execute("SELECT id, clip_id, first_frame + n_frames - 1 FROM modb.snippets "
                                        "WHERE NOT mirrored ORDER BY id LIMIT 1 OFFSET 500").fetchone()
        # Its natural successor starts on its last frame with the very same terminator (ratio 0): leave it out.
        (successor,) = conn.execute("SELECT id FROM modb.snippets WHERE clip_id = %s AND first_frame = %s "
                                    "AND NOT mirrored", [clip, last]).fetchone()
        seen = {}
        for threshold in ("10", "0.1", "0.05", "0.02", "0.01", "0.005", "1e-9"):
            conn.execute(f"SET modb.position_threshold = '{threshold}'")
            conn.execute(f"SET modb.angle_threshold = '{float(threshold) * 3}'")
            conn.execute(f"SET modb.velocity_threshold = '{float(threshold) * 5}'")
            conn.execute(f"SET modb.angular_velocity_threshold = '{float(threshold) * 30}'")
            rows = conn.execute("SELECT snippet_id, relax_level, continuity FROM modb.select_next_snippets("
                                "%s, '{0,2}', 50, 'default', NULL, %s)", [prev, [prev, successor]]).fetchall()
            assert rows, f"nothing returned at threshold {threshold} although candidates exist"
            for _, level, ratio in rows:
                if level < 4:
                    assert (2.0 ** (level - 1) if level else -1.0) < ratio <= 2.0 ** level * (1 + 1e-9)
                else:
                    assert ratio > 8.0
            assert [r[1] for r in rows] == sorted(r[1] for r in rows)  # lower levels first
            seen[threshold] = rows[0][1]
        levels = list(seen.values())  # tighter thresholds, higher levels, down to the last resort
        assert levels == sorted(levels) and levels[0] == 0 and levels[-1] == 4 and len(set(levels)) >= 4, seen


def test_exclusion_removes_every_overlapping_window_but_not_the_successor(cmu):
    with connect(cmu) as conn:
        clip, first, n = conn.execute("SELECT clip_id, first_frame, n_frames FROM modb.snippets "
                                      "WHERE NOT mirrored AND first_frame = 200 LIMIT 1").fetchone()
        ids = dict(conn.execute("SELECT first_frame, id FROM modb.snippets WHERE clip_id = %s AND NOT mirrored",
                                [clip]).fetchall())
        played = ids[first]
        conn.execute("SET modb.position_threshold = '100'")  # everything continues everything: only exclusion filters
        conn.execute("SET modb.angle_threshold = '100'")
        conn.execute("SET modb.velocity_terms = off")
        got = conn.execute("SELECT snippet_id FROM modb.select_next_snippets(%s, '{0,0}', 100000, 'default', NULL, %s)",
                           [played, [played]]).fetchall()
        got = {r[0] for r in got}
        for f, sid in ids.items():
            overlaps = f + 1 <= first + n - 1 and first + 1 <= f + n - 1
            assert (sid in got) != overlaps, (f, first)
        successor = ids[first + n - 1]  # starts on the played snippet's last frame: the seam, not a replay
        assert successor in got and ids[first + 4] not in got and ids[first - 4] not in got


def test_explain_shows_the_inlined_function_and_the_gist_box(cmu):
    with connect(cmu) as conn:
        prev = conn.execute("SELECT id FROM modb.snippets ORDER BY id LIMIT 1 OFFSET 100").fetchone()[0]
        nodes = plan_nodes(conn, "SELECT * FROM modb.select_next_snippet(%s, '{1,2}')", [prev])
        assert not any(n.get("Function Name", "").startswith("select_next_snippet") for n in nodes), \
            "select_next_snippet was not inlined"
        box_scans = [n for n in nodes if n.get("Index Name") == "snippets_begin_features_idx"
                     and "begin_features <@" in n.get("Index Cond", "")]
        assert box_scans and box_scans[0].get("Actual Loops", 0) >= 1, [n["Node Type"] for n in nodes]
        text = "\n".join(r[0] for r in conn.execute(
            "EXPLAIN SELECT * FROM modb.select_next_snippet(%s, '{1,2}')", [prev]).fetchall())
        assert "Index Cond: (begin_features <@" in text


def test_the_feature_index_finds_what_a_sequential_scan_finds(cmu):
    # modb.cube_feature_ops keeps cube's search and changes how pages are filled: any mistake there loses or
    # invents rows. Boxes of every relaxation scale and profile, and the nearest-first order of level 4.
    with connect(cmu) as conn:
        ends = [r[0] for r in conn.execute("SELECT end_terminator FROM modb.snippets ORDER BY id")]
        compared = 0
        for profile in ("default", "strict", "locomotion"):
            for end in ends[3::len(ends) // 12]:
                for scale in (1.0, 2.0, 8.0):
                    box = conn.execute("SELECT modb.match_box(features, modb.match_plan(%s), %s) FROM modb.terminators "
                                       "WHERE id = %s", [profile, scale, end]).fetchone()[0]
                    query = "SELECT array_agg(id ORDER BY id) FROM modb.snippets WHERE begin_features <@ %s::cube"
                    found = {}
                    for scan, off in (("index", "enable_seqscan"), ("sequential", "enable_indexscan")):
                        conn.execute("RESET ALL")
                        conn.execute(f"SET {off} = off")
                        conn.execute("SET enable_bitmapscan = %s" % ("off" if scan == "sequential" else "on"))
                        used = [n.get("Index Name") for n in plan_nodes(conn, query, [box])]
                        assert ("snippets_begin_features_idx" in used) == (scan == "index"), (scan, used)
                        found[scan] = conn.execute(query, [box]).fetchone()[0]
                    assert found["index"] == found["sequential"], (profile, end, scale)
                    compared += len(found["index"] or [])
            nearest = "SELECT array_agg(id) FROM (SELECT id FROM modb.snippets ORDER BY begin_features <-> " \
                      "(SELECT features FROM modb.terminators WHERE id = %s), id LIMIT 20) n"
            conn.execute("RESET ALL")
            conn.execute("SET enable_seqscan = off")
            by_index = conn.execute(nearest, [ends[5]]).fetchone()[0]
            conn.execute("RESET ALL")
            conn.execute("SET enable_indexscan = off")
            assert by_index == conn.execute(nearest, [ends[5]]).fetchone()[0]
        conn.execute("RESET ALL")
        assert compared >= 1000, compared


def test_candidates_examined_is_what_the_box_scans_of_the_selection_returned(cmu):
    # modb.candidates_examined recounts; EXPLAIN ANALYZE of the selection itself says what its box scans
    # handed on (rows after the pose and rate filter), at each relaxation level it ran.
    with connect(cmu) as conn:
        ids = [r[0] for r in conn.execute("SELECT id FROM modb.snippets ORDER BY id")]
        checked, counts = 0, set()
        for knobs in ({}, {"position_threshold": "0.05"}, {"velocity_terms": "off", "norm": "l1"}):
            conn.execute("SET jit = off")
            for knob, value in knobs.items():
                conn.execute("SELECT set_config(%s, %s, false)", [f"modb.{knob}", value])
            for prev in ids[7::len(ids) // 8]:
                level = conn.execute("SELECT relax_level FROM modb.select_next_snippet(%s, '{1,2}')", [prev]).fetchone()[0]
                if level == 4:  # the nearest start configuration: an ordered scan, not a box
                    continue
                nodes = plan_nodes(conn, "SELECT * FROM modb.select_next_snippet(%s, '{1,2}')", [prev])
                scanned = sum(n["Actual Rows"] * n["Actual Loops"] for n in nodes
                              if n["Node Type"] in ("Bitmap Heap Scan", "Index Scan")
                              and "begin_features <@" in n.get("Recheck Cond", "") + n.get("Index Cond", ""))
                examined = conn.execute("SELECT modb.candidates_examined(%s, %s)", [prev, level]).fetchone()[0]
                assert scanned == examined, (knobs, prev, level)
                checked += 1
                counts.add(examined)
            conn.execute("RESET ALL")
        assert checked >= 16 and len(counts) >= 8, (checked, counts)


FROZEN_0_6_0 = REPO / "extension" / "sql" / "released" / "modb--0.6.0.sql"


def test_the_c_continuity_ratio_equals_the_sql_expression_it_replaced_to_the_last_bit(cmu):
    # 0.7.0 computes the ratio in C. The 0.6.0 expression (from its frozen install script, as a temporary
    # function) is the reference: same float4 differences, pow(x, 2), atan2, so the same value, bit for bit.
    text = FROZEN_0_6_0.read_text()
    start = text.index("CREATE FUNCTION modb.continuity_ratio(a modb.terminators")
    old = text[start:text.index("COMMENT ON FUNCTION modb.continuity_ratio(", start)].replace(
        "CREATE FUNCTION modb.continuity_ratio(", "CREATE FUNCTION pg_temp.continuity_ratio_sql(", 1)
    with connect(cmu) as conn:
        conn.execute(old)
        ends = [r[0] for r in conn.execute("SELECT end_terminator FROM modb.snippets ORDER BY id")]
        compared = 0
        for knobs in ({}, {"norm": "l1", "velocity_terms": "off", "joints": "pelvis,left_hip,head"},
                      {"position_threshold": "0.05", "angle_threshold": "0.2"}):
            conn.execute("RESET ALL")
            for knob, value in knobs.items():
                conn.execute("SELECT set_config(%s, %s, false)", [f"modb.{knob}", value])
            for prev in ends[5::len(ends) // 3][:3]:
                n, differ = conn.execute(
                    "WITH p AS MATERIALIZED (SELECT modb.match_plan('default') AS plan), "
                    "     q AS MATERIALIZED (SELECT t FROM modb.terminators t WHERE id = %s) "
                    "SELECT count(*), count(*) FILTER (WHERE modb.continuity_ratio(q.t, b, p.plan) "
                    "                                  IS DISTINCT FROM pg_temp.continuity_ratio_sql(q.t, b, p.plan)) "
                    "  FROM p, q, (SELECT * FROM modb.terminators ORDER BY id LIMIT 2500) b", [prev]).fetchone()
                assert differ == 0, (knobs, prev, differ)
                compared += n
        assert compared >= 20_000


def test_reader_selects_loader_builds(cmu):
    with connect(cmu) as conn:
        conn.execute("DROP ROLE IF EXISTS t_reader")
        conn.execute("CREATE ROLE t_reader LOGIN IN ROLE modb_reader")
    try:
        with psycopg.connect(psycopg.conninfo.make_conninfo(cmu, user="t_reader")) as conn:
            assert conn.execute("SELECT count(*) FROM modb.select_next_snippet(NULL, '{0,1}')").fetchone()[0] == 1
            with pytest.raises(psycopg.errors.InsufficientPrivilege):
                conn.execute("SELECT modb.build_snippets()")
    finally:
        with connect(cmu) as conn:
            conn.execute("DROP ROLE t_reader")


SNIPPET_ROWS = "SELECT id, clip_id, first_frame, begin_terminator, net_heading FROM modb.snippets " \
               "WHERE NOT mirrored ORDER BY id"
FEATURES = "SELECT c.name, t.mirrored || '/' || t.frame, " \
           "       (SELECT array_agg(cube_ll_coord(t.features, i) ORDER BY i) FROM generate_series(1, cube_dim(t.features)) i) " \
           "FROM modb.terminators t JOIN modb.clips c ON c.id = t.clip_id ORDER BY 1, 2"
MIRRORED_TERMINATORS = "SELECT c.name, t.frame, md5(t.rotations::text), md5(t.positions::text) FROM modb.terminators t " \
                       "JOIN modb.clips c ON c.id = t.clip_id WHERE t.mirrored ORDER BY 1, 2"


@pytest.mark.parametrize("old", ["0.1.0", "0.2.0", "0.3.0", "0.4.0", "0.5.0", "0.6.0", "0.7.0"])
def test_update_keeps_the_data(cluster, fresh_db, db, old):
    current = db.execute("SELECT default_version FROM pg_available_extensions WHERE name = 'modb'").fetchone()[0]
    db.execute("DROP EXTENSION modb")
    db.execute(f"CREATE EXTENSION modb VERSION '{old}'")
    with_snippets = old != "0.1.0"  # snippets (and mirror images) came with 0.2.0
    files = [mocap("cmu", "131", "131_01.amc"), mocap("cmu", "131", "131_02.amc")]
    r = run_modb(fresh_db, "load", *files, *(["--mirror"] if with_snippets else ["--no-snippets"]))
    assert r.returncode == 0, r.stderr
    db.execute("UPDATE modb.clip_versions SET meta = '{\"tags\": [\"kept\"]}'")
    before = db.execute("SELECT clip_id, version, n_frames, meta, md5(rotations::text) FROM modb.clip_versions "
                        "ORDER BY 1").fetchall()
    positions = db.execute("SELECT sum(x + 2 * y + 3 * z) FROM modb.world_positions(1)").fetchone()[0]
    snippets = db.execute(SNIPPET_ROWS).fetchall() if with_snippets else []
    old_mirrored = db.execute(MIRRORED_TERMINATORS).fetchall() if with_snippets else []
    if with_snippets:
        db.execute("INSERT INTO modb.match_profiles (name, settings) "
                   "SELECT 'mine', settings FROM modb.match_profiles WHERE name = 'default'")
        mine = db.execute("SELECT settings FROM modb.match_profiles WHERE name = 'mine'").fetchone()[0]
    # A graph built before 0.5.0 stored no transitions: it keeps working through the box. One built by 0.5.0
    # has no cost-to-go: it keeps ranking by where the candidates lead. One built by 0.6.0 or later keeps its
    # costs (0.8.0's wider feature cube changes no transition).
    if old in ("0.4.0", "0.5.0", "0.6.0", "0.7.0"):
        db.execute("SELECT modb.build_transition_graph('old', 'locomotion', NULL, 0)")
    db.execute("ALTER EXTENSION modb UPDATE")
    if old in ("0.4.0", "0.5.0", "0.6.0", "0.7.0"):
        stored, costs = db.execute("SELECT count(*), count(cost_to_go) FROM modb.graph_transitions").fetchone()
        assert (stored > 0) == (old != "0.4.0") and costs == (stored if old >= "0.6.0" else 0), (stored, costs)
        db.execute("SET modb.graph = 'old'")
        chosen, in_graph = db.execute("SELECT count(*), count(g.snippet_id) FROM modb.synthesize('{{0,3}}', 4) s "
                                      "LEFT JOIN modb.graph_snippets g USING (snippet_id)").fetchone()
        assert chosen == 4 and in_graph == chosen
        db.execute("RESET modb.graph")
        assert next(g for g in list_graphs(db) if g.name == "old").current == (old >= "0.6.0")  # else rebuild it
    assert db.execute("SELECT extversion FROM pg_extension WHERE extname = 'modb'").fetchone()[0] == current
    assert db.execute("SELECT clip_id, version, n_frames, meta, md5(rotations::text) FROM modb.clip_versions "
                      "ORDER BY 1").fetchall() == before
    assert db.execute("SELECT sum(x + 2 * y + 3 * z) FROM modb.world_positions(1)").fetchone()[0] == positions
    if with_snippets:
        assert db.execute(SNIPPET_ROWS).fetchall() == snippets
        # 0.2.0's mirror images had rotations in other joint frames: the update rebuilt them, as a fresh
        # install's load would (compared after the reinstall below).
        updated_mirrored = db.execute(MIRRORED_TERMINATORS).fetchall()
        updated_features = db.execute(FEATURES).fetchall()
        assert len(updated_mirrored) == len(old_mirrored)
        assert (updated_mirrored != old_mirrored) == (old == "0.2.0")
        assert db.execute("SELECT count(*) FROM modb.snippets WHERE mirrored").fetchone()[0] > 0
        assert db.execute("SELECT count(*) FROM modb.snippets WHERE future_translation IS NULL").fetchone()[0] == 0
        assert db.execute("SELECT settings FROM modb.match_profiles WHERE name = 'mine'").fetchone()[0] == mine
        if old == "0.2.0":  # 0.3.0 retuned the shipped default; the copy the user made keeps 0.2.0's
            assert mine != db.execute("SELECT settings FROM modb.match_profiles WHERE name = 'default'").fetchone()[0]
    else:
        (added,) = db.execute("SELECT modb.build_snippets()").fetchone()
        assert added > 0
    assert db.execute("SELECT count(*) FROM modb.select_next_snippet(NULL, '{0,2}')").fetchone()[0] == 1
    assert db.execute("SELECT count(*) FROM modb.synthesize('{{0,3}}', 4)").fetchone()[0] == 4
    # Lower body, no turn asked for: under the default profile (tuned at 30 fps) these two 120 fps clips
    # have no component that turns 45 degrees each way.
    db.execute("SELECT modb.build_transition_graph('g', 'locomotion', NULL, 0)")
    stored, costs = db.execute("SELECT count(*), count(e.cost_to_go) FROM modb.graph_transitions e "
                               "JOIN modb.graphs g ON g.id = e.graph_id WHERE g.name = 'g'").fetchone()
    assert stored > 0 and costs == stored
    assert next(g for g in list_graphs(db) if g.name == "g").current
    db.execute("SET modb.graph = 'g'")
    chosen, in_graph = db.execute("SELECT count(*), count(g.snippet_id) FROM modb.synthesize('{{0,3}}', 4) s "
                                  "LEFT JOIN modb.graph_snippets g USING (snippet_id)").fetchone()
    assert chosen > 0 and in_graph == chosen
    db.execute("RESET modb.graph")
    # What a fresh install of the current version has, the updated one has: same objects, same definitions.
    objects = "SELECT pg_describe_object(classid, objid, 0) FROM pg_depend WHERE refobjid = " \
              "(SELECT oid FROM pg_extension WHERE extname = 'modb') AND deptype = 'e' ORDER BY 1"
    updated = [r[0] for r in db.execute(objects).fetchall()]
    functions = "SELECT p.oid::regprocedure::text, md5(pg_get_functiondef(p.oid)), obj_description(p.oid, 'pg_proc') FROM pg_proc p " \
                "WHERE pronamespace = 'modb'::regnamespace AND prokind = 'f' ORDER BY 1"
    updated_functions = db.execute(functions).fetchall()
    acls = "SELECT c.relname, c.relacl::text FROM pg_class c WHERE relnamespace = 'modb'::regnamespace ORDER BY 1"
    grants = "SELECT p.oid::regprocedure::text, p.proacl::text FROM pg_proc p " \
             "WHERE pronamespace = 'modb'::regnamespace ORDER BY 1"
    updated_acls, updated_grants = db.execute(acls).fetchall(), db.execute(grants).fetchall()
    db.execute("DROP ROLE IF EXISTS t_updated_reader")
    db.execute("CREATE ROLE t_updated_reader LOGIN IN ROLE modb_reader")
    try:
        with psycopg.connect(psycopg.conninfo.make_conninfo(fresh_db, user="t_updated_reader")) as reader:
            assert reader.execute("SELECT count(*) FROM modb.select_next_snippet(NULL, '{0,2}')").fetchone()[0] == 1
    finally:
        db.execute("DROP ROLE t_updated_reader")
    db.execute("DROP EXTENSION modb CASCADE")
    db.execute("CREATE EXTENSION modb")
    assert [r[0] for r in db.execute(objects).fetchall()] == updated
    assert db.execute(functions).fetchall() == updated_functions
    assert db.execute(acls).fetchall() == updated_acls and db.execute(grants).fetchall() == updated_grants
    if with_snippets:
        assert run_modb(fresh_db, "load", *files, "--mirror").returncode == 0
        assert db.execute(MIRRORED_TERMINATORS).fetchall() == updated_mirrored
        # 0.8.0's update computes the new feature dimensions in SQL from the stored rotations; a load computes
        # them in the kernel from float8: the same cube, to float4 rounding.
        fresh = db.execute(FEATURES).fetchall()
        assert [r[:2] for r in fresh] == [r[:2] for r in updated_features]
        difference = np.abs(np.array([r[2] for r in fresh]) - np.array([r[2] for r in updated_features]))
        assert difference.shape[1] == 49 and difference.max() < 1e-6, difference.max(axis=0)


def test_new_versions_replace_their_snippets_and_other_ids_stay(fresh_db, db, tmp_path):
    walk = mocap("bandai-1", "data", "dataset-1_walk_active_001.bvh")
    run = mocap("bandai-1", "data", "dataset-1_run_active_001.bvh")
    assert run_modb(fresh_db, "load", walk, run, "--collection", "c").returncode == 0
    snippets = "SELECT c.name, s.version, array_agg(s.id ORDER BY s.id) FROM modb.snippets s " \
               "JOIN modb.clips c ON c.id = s.clip_id GROUP BY 1, 2 ORDER BY 1, 2"
    before = {(n, v): ids for n, v, ids in db.execute(snippets).fetchall()}
    assert run_modb(fresh_db, "load", walk, run, "--collection", "c").returncode == 0  # nothing new
    assert db.execute("SELECT modb.build_snippets()").fetchone()[0] == 0
    assert {(n, v): ids for n, v, ids in db.execute(snippets).fetchall()} == before
    changed = tmp_path / walk.name
    lines = walk.read_text().splitlines()
    lines[lines.index("MOTION") + 3] = " ".join("0" for _ in lines[lines.index("MOTION") + 3].split())
    changed.write_text("\n".join(lines) + "\n")
    r = run_modb(fresh_db, "load", changed, "--collection", "c")
    assert r.returncode == 0 and "1 clip versions loaded" in r.stdout
    after = {(n, v): ids for n, v, ids in db.execute(snippets).fetchall()}
    run_key = ("dataset-1_run_active_001", 1)
    assert after[run_key] == before[run_key]  # other clips keep their snippet ids
    assert ("dataset-1_walk_active_001", 1) not in after and ("dataset-1_walk_active_001", 2) in after
    assert len(after[("dataset-1_walk_active_001", 2)]) == len(before[("dataset-1_walk_active_001", 1)])


BAD_PARAMETER, RAISED = psycopg.errors.InvalidParameterValue, psycopg.errors.RaiseException


@pytest.mark.parametrize("setting,call,error,message", [
    (None, "SELECT * FROM modb.select_next_snippet(NULL, '{1}')", BAD_PARAMETER, "target must be {x, z} or {x, y, z}"),
    (None, "SELECT * FROM modb.select_next_snippet(NULL, '{1,2,3,4}')", BAD_PARAMETER, "target must be"),
    (None, "SELECT * FROM modb.select_next_snippet(NULL, '{NaN,1}')", BAD_PARAMETER, "target must be"),
    (None, "SELECT * FROM modb.select_next_snippet(NULL, NULL)", BAD_PARAMETER, "target must be"),
    (None, "SELECT * FROM modb.select_next_snippet(999999999, '{0,1}')", BAD_PARAMETER, "no snippet 999999999"),
    (None, "SELECT * FROM modb.select_next_snippet(999999999, '{0,1}', 'nope')", RAISED, 'unknown match profile "nope"'),
    (None, "SELECT * FROM modb.select_next_snippet(NULL, '{0,1}', 'default', 'no/such')", BAD_PARAMETER,
     'no collection "no/such"'),
    (None, "SELECT * FROM modb.select_next_snippets(NULL, '{0,1}', NULL)", BAD_PARAMETER, "k must be at least 1"),
    ("SET modb.position_threshold = '-1'", "SELECT * FROM modb.select_next_snippet(NULL, '{0,1}')", RAISED,
     "thresholds must be positive"),
    ("SET modb.heading_weight = '-5'", "SELECT * FROM modb.select_next_snippet(NULL, '{0,1}')", RAISED,
     "heading_weight must not be negative"),
    ("SET modb.continuity_weight = '-1'", "SELECT * FROM modb.select_next_snippet(NULL, '{0,1}')", RAISED,
     "continuity_weight must not be negative"),
    ("SET modb.lookahead_distance = '0'", "SELECT * FROM modb.select_next_snippet(NULL, '{0,1}')", RAISED,
     "lookahead_distance must be positive"),
])
def test_requests_that_cannot_be_answered_are_errors(cmu, setting, call, error, message):
    with connect(cmu) as conn:
        if setting:
            conn.execute(setting)
        with pytest.raises(error, match=message):
            conn.execute(call).fetchall()


def test_the_previous_snippet_is_never_replayed(cmu):
    with connect(cmu) as conn:
        prev, clip, first, n = conn.execute("SELECT id, clip_id, first_frame, n_frames FROM modb.snippets "
                                            "WHERE NOT mirrored ORDER BY id LIMIT 1 OFFSET 300").fetchone()
        rows = conn.execute("SELECT s.clip_id, s.first_frame FROM modb.select_next_snippets(%s, '{0,0}', 500) x "
                            "JOIN modb.snippets s ON s.id = x.snippet_id WHERE NOT s.mirrored", [prev]).fetchall()
        assert rows
        for c, f in rows:
            assert c != clip or not (f + 1 <= first + n - 1 and first + 1 <= f + n - 1), (f, first)


def test_a_new_version_keeps_its_mirror_images(fresh_db, db):
    amc = mocap("cmu", "131", "131_01.amc")
    assert run_modb(fresh_db, "load", amc, "--mirror").returncode == 0
    assert run_modb(fresh_db, "load", amc, "--fps", "60").returncode == 0  # a new version, no --mirror
    rows = db.execute("SELECT version, mirrored, count(*) FROM modb.snippets GROUP BY 1, 2 ORDER BY 1, 2").fetchall()
    assert [(v, m) for v, m, _ in rows] == [(2, False), (2, True)] and rows[0][2] == rows[1][2]


def test_mirrored_snippets_are_placed_where_the_database_says(cmu):
    """The client mirrors a clip's frames itself (source_frames.py); the database measured the mirrored
    snippets' travel and turn when it built them. A strip that starts on a mirrored snippet (CMU 131, 120 fps)
    must end each snippet where the chain's arithmetic on those stored figures puts it."""
    from modb.synthesis.avatar import Settings
    from modb.synthesis.synth import synthesize

    with connect(cmu) as conn:
        start = conn.execute("SELECT min(id) FROM modb.snippets WHERE mirrored AND first_frame = 120").fetchone()[0]
        result = synthesize(conn, [(0.0, 4.0), (3.0, 0.0)], 4.0, Settings(), start_snippet=start)
    assert result.chain[0].mirrored and sum(c.mirrored for c in result.chain) >= 2
    sk = result.strip.skeleton
    pelvis = result.strip.world_positions()[:, sk.index(sk.joint_map["pelvis"])]
    for c in result.chain:
        assert abs(pelvis[c.end_frame, 0] - c.end.position[0]) < 1e-3
        assert abs(pelvis[c.end_frame, 2] - c.end.position[2]) < 1e-3


def test_mirrored_terminators_are_poses_the_captured_walk_takes(fresh_db, db):
    """A mirrored walk is still a walk: every mirrored terminator must be close, joint by joint, to some
    captured terminator of the same clip (half a cycle away), so that mirrored and captured snippets can
    follow each other. Bandai's Maya-style rig needs per-joint frame reflections (the right limbs' axes are
    the left ones' negated, the spine's frames twist); a wrong one leaves positions exact but turns a joint's
    rotation up to 180 degrees away from any captured one, which this catches. Checked without the mirroring
    code: positions by reflecting the captured ones, rotations by a brute-force nearest search."""
    from modb_kernel.joints import STANDARD_JOINTS

    walk = mocap("bandai-1", "data", "dataset-1_walk_active_001.bvh")
    assert run_modb(fresh_db, "load", walk, "--mirror").returncode == 0
    terms = {m: [np.array(column) for column in zip(*db.execute(
        "SELECT positions, rotations FROM modb.terminators WHERE mirrored = %s ORDER BY frame", [m]).fetchall())]
        for m in (False, True)}
    (captured_p, captured_r), (mirrored_p, mirrored_r) = terms[False], terms[True]
    partner = [STANDARD_JOINTS.index(n.replace("left", "~").replace("right", "left").replace("~", "right"))
               for n in STANDARD_JOINTS]
    captured_p = captured_p.reshape(len(captured_p), 19, 3)
    assert np.abs(captured_p[:, partner] * [-1, 1, 1] - mirrored_p.reshape(captured_p.shape)).max() < 1e-4
    a, b = captured_r.reshape(-1, 19, 4), mirrored_r.reshape(-1, 19, 4)
    cos = np.abs(np.einsum("fjk,gjk->fgj", b, a))  # every mirrored frame against every captured one
    nearest = np.degrees(2 * np.arccos(np.clip(cos.max(axis=1), 0, 1)))  # (mirrored frames, joints)
    assert np.median(nearest, axis=0).max() < 10, dict(zip(STANDARD_JOINTS, np.median(nearest, axis=0).round(1)))


def test_mirrored_snippets_can_follow_captured_ones(fresh_db, db):
    """With two walks and their mirror images, a captured snippet's nearest mirrored continuation (the
    default profile's continuity ratio) is typically no farther than its nearest one from the other
    captured walk: the mirror images add choice instead of forming a pool of their own."""
    walks = [mocap("bandai-1", "data", f"dataset-1_walk_{style}_001.bvh") for style in ("active", "normal")]
    assert run_modb(fresh_db, "load", *walks, "--mirror").returncode == 0
    rows = db.execute(
        "WITH prev AS (SELECT s.id, s.clip_id, t FROM modb.snippets s JOIN modb.terminators t ON t.id = s.end_terminator "
        "               WHERE NOT s.mirrored AND s.id % 25 = 0), "
        "nearest AS (SELECT p.id, c.mirrored, c.clip_id = p.clip_id AS same_clip, "
        "                   min(modb.continuity_ratio(p.t, b, modb.match_plan('default'))) AS ratio "
        "              FROM prev p, modb.snippets c JOIN modb.terminators b ON b.id = c.begin_terminator "
        "             GROUP BY 1, 2, 3) "
        "SELECT mirrored, same_clip, percentile_cont(0.5) WITHIN GROUP (ORDER BY ratio) FROM nearest "
        "GROUP BY 1, 2").fetchall()
    median = {(m, same): r for m, same, r in rows}
    assert median[(True, True)] <= median[(False, False)] and median[(True, False)] <= 1.5 * median[(False, False)], median
