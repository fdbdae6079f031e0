"""select_next_snippet as a user meets it: snippet windows, relaxation, exclusion, the plan and the
feature index, the continuity ratio, requests it refuses."""

from __future__ import annotations

import psycopg
import pytest
from support.data import REPO
from support.databases import plan_nodes

from modb.database.connection import connect


def test_snippet_windows_follow_the_frame_rate(cmu):
    with connect(cmu) as conn:
        rows = conn.execute(
            "SELECT DISTINCT window_frames, stride_frames FROM modb.snippet_sources"
        ).fetchall()
        assert rows == [(61, 4)]  # 0.5 s at 120 fps (+1: the seam frame), one start every 1/30 s
        n_frames = dict(conn.execute("SELECT clip_id, n_frames FROM modb.current_clips").fetchall())
        per_clip = conn.execute(
            "SELECT clip_id, count(*), max(first_frame + n_frames) FROM modb.snippets "
            "WHERE NOT mirrored GROUP BY clip_id"
        ).fetchall()
        for clip_id, count, end in per_clip:
            assert (
                count == len(range(0, n_frames[clip_id] - 61 + 1, 4)) and end <= n_frames[clip_id]
            )
        (mirrored,) = conn.execute("SELECT count(*) FROM modb.snippets WHERE mirrored").fetchone()
        assert mirrored == sum(c for _, c, _ in per_clip)  # one call doubles the data


def test_relaxation_levels_and_the_last_resort(cmu):
    with connect(cmu) as conn:
        prev, clip, last = conn.execute(
            "SELECT id, clip_id, first_frame + n_frames - 1 FROM modb.snippets "
            "WHERE NOT mirrored ORDER BY id LIMIT 1 OFFSET 500"
        ).fetchone()
        # Its natural successor starts on its last frame with the very same terminator (ratio 0):
        # leave it out.
        (successor,) = conn.execute(
            "SELECT id FROM modb.snippets WHERE clip_id = %s AND first_frame = %s AND NOT mirrored",
            [clip, last],
        ).fetchone()
        seen = {}
        for threshold in ("10", "0.1", "0.05", "0.02", "0.01", "0.005", "1e-9"):
            conn.execute(f"SET modb.position_threshold = '{threshold}'")
            conn.execute(f"SET modb.angle_threshold = '{float(threshold) * 3}'")
            conn.execute(f"SET modb.velocity_threshold = '{float(threshold) * 5}'")
            conn.execute(f"SET modb.angular_velocity_threshold = '{float(threshold) * 30}'")
            rows = conn.execute(
                "SELECT snippet_id, relax_level, continuity FROM modb.select_next_snippets("
                "%s, '{0,2}', 50, 'default', NULL, %s)",
                [prev, [prev, successor]],
            ).fetchall()
            assert rows, f"nothing returned at threshold {threshold} although candidates exist"
            for _, level, ratio in rows:
                if level < 4:
                    assert (
                        (2.0 ** (level - 1) if level else -1.0) < ratio <= 2.0**level * (1 + 1e-9)
                    )
                else:
                    assert ratio > 8.0
            assert [r[1] for r in rows] == sorted(r[1] for r in rows)  # lower levels first
            seen[threshold] = rows[0][1]
        levels = list(seen.values())  # tighter thresholds, higher levels, down to the last resort
        assert (
            levels == sorted(levels)
            and levels[0] == 0
            and levels[-1] == 4
            and len(set(levels)) >= 4
        ), seen


def test_exclusion_removes_every_overlapping_window_but_not_the_successor(cmu):
    with connect(cmu) as conn:
        clip, first, n = conn.execute(
            "SELECT clip_id, first_frame, n_frames FROM modb.snippets "
            "WHERE NOT mirrored AND first_frame = 200 LIMIT 1"
        ).fetchone()
        ids = dict(
            conn.execute(
                "SELECT first_frame, id FROM modb.snippets WHERE clip_id = %s AND NOT mirrored",
                [clip],
            ).fetchall()
        )
        played = ids[first]
        # everything continues everything: only exclusion filters
        conn.execute("SET modb.position_threshold = '100'")
        conn.execute("SET modb.angle_threshold = '100'")
        conn.execute("SET modb.velocity_terms = off")
        got = conn.execute(
            "SELECT snippet_id FROM modb.select_next_snippets(%s, '{0,0}', 100000, 'default', "
            "NULL, %s)",
            [played, [played]],
        ).fetchall()
        got = {r[0] for r in got}
        for f, sid in ids.items():
            overlaps = f + 1 <= first + n - 1 and first + 1 <= f + n - 1
            assert (sid in got) != overlaps, (f, first)
        # starts on the played snippet's last frame: the seam, not a replay
        successor = ids[first + n - 1]
        assert successor in got and ids[first + 4] not in got and ids[first - 4] not in got


def test_explain_of_the_reference_shows_the_inlined_function_and_the_gist_box(cmu):
    # select_next_snippets_reference, the rule as one SQL query, is what EXPLAIN can show whole
    # (select_next_snippets, C, has modb.explain_selection: tests/test_select_fast.py).
    with connect(cmu) as conn:
        prev = conn.execute(
            "SELECT id FROM modb.snippets ORDER BY id LIMIT 1 OFFSET 100"
        ).fetchone()[0]
        reference = "SELECT * FROM modb.select_next_snippets_reference(%s, '{1,2}', 1)"
        nodes = plan_nodes(conn, reference, [prev])
        assert not any(
            n.get("Function Name", "").startswith("select_next_snippet") for n in nodes
        ), "select_next_snippets_reference was not inlined"
        box_scans = [
            n
            for n in nodes
            if n.get("Index Name") == "snippets_begin_features_idx"
            and "begin_features <@" in n.get("Index Cond", "")
        ]
        assert box_scans and box_scans[0].get("Actual Loops", 0) >= 1, [
            n["Node Type"] for n in nodes
        ]
        text = "\n".join(r[0] for r in conn.execute("EXPLAIN " + reference, [prev]).fetchall())
        assert "Index Cond: (begin_features <@" in text


def test_the_feature_index_finds_what_a_sequential_scan_finds(cmu):
    # modb.cube_feature_ops keeps cube's search and changes how pages are filled: any mistake there
    # loses or invents rows. Boxes of every relaxation scale and profile, and the nearest-first
    # order of level 4.
    with connect(cmu) as conn:
        ends = [r[0] for r in conn.execute("SELECT end_terminator FROM modb.snippets ORDER BY id")]
        compared = 0
        for profile in ("default", "strict", "locomotion"):
            for end in ends[3 :: len(ends) // 12]:
                for scale in (1.0, 2.0, 8.0):
                    box = conn.execute(
                        "SELECT modb.match_box(features, modb.match_plan(%s), %s) FROM "
                        "modb.terminators "
                        "WHERE id = %s",
                        [profile, scale, end],
                    ).fetchone()[0]
                    query = (
                        "SELECT array_agg(id ORDER BY id) FROM modb.snippets "
                        "WHERE begin_features <@ %s::cube"
                    )
                    found = {}
                    for scan, off in (
                        ("index", "enable_seqscan"),
                        ("sequential", "enable_indexscan"),
                    ):
                        conn.execute("RESET ALL")
                        conn.execute(f"SET {off} = off")
                        conn.execute(
                            "SET enable_bitmapscan = %s" % ("off" if scan == "sequential" else "on")
                        )
                        used = [n.get("Index Name") for n in plan_nodes(conn, query, [box])]
                        assert ("snippets_begin_features_idx" in used) == (scan == "index"), (
                            scan,
                            used,
                        )
                        found[scan] = conn.execute(query, [box]).fetchone()[0]
                    assert found["index"] == found["sequential"], (profile, end, scale)
                    compared += len(found["index"] or [])
            nearest = (
                "SELECT array_agg(id) FROM (SELECT id FROM modb.snippets ORDER BY begin_features "
                "<-> "
                "(SELECT features FROM modb.terminators WHERE id = %s), id LIMIT 20) n"
            )
            conn.execute("RESET ALL")
            conn.execute("SET enable_seqscan = off")
            by_index = conn.execute(nearest, [ends[5]]).fetchone()[0]
            conn.execute("RESET ALL")
            conn.execute("SET enable_indexscan = off")
            assert by_index == conn.execute(nearest, [ends[5]]).fetchone()[0]
        conn.execute("RESET ALL")
        assert compared >= 1000, compared


def test_candidates_examined_is_what_the_box_scans_of_the_selection_returned(cmu):
    # modb.candidates_examined recounts; EXPLAIN ANALYZE of the selection itself says what its box
    # scans handed on (rows after the pose and rate filter), at each relaxation level it ran.
    with connect(cmu) as conn:
        ids = [r[0] for r in conn.execute("SELECT id FROM modb.snippets ORDER BY id")]
        checked, counts = 0, set()
        for knobs in ({}, {"position_threshold": "0.05"}, {"velocity_terms": "off", "norm": "l1"}):
            conn.execute("SET jit = off")
            for knob, value in knobs.items():
                conn.execute("SELECT set_config(%s, %s, false)", [f"modb.{knob}", value])
            for prev in ids[7 :: len(ids) // 8]:
                level = conn.execute(
                    "SELECT relax_level FROM modb.select_next_snippet(%s, '{1,2}')", [prev]
                ).fetchone()[0]
                if level == 4:  # the nearest start configuration: an ordered scan, not a box
                    continue
                nodes = plan_nodes(
                    conn,
                    "SELECT * FROM modb.select_next_snippets_reference(%s, '{1,2}', 1)",
                    [prev],
                )
                scanned = sum(
                    n["Actual Rows"] * n["Actual Loops"]
                    for n in nodes
                    if n["Node Type"] in ("Bitmap Heap Scan", "Index Scan")
                    and "begin_features <@" in n.get("Recheck Cond", "") + n.get("Index Cond", "")
                )
                examined = conn.execute(
                    "SELECT modb.candidates_examined(%s, %s)", [prev, level]
                ).fetchone()[0]
                assert scanned == examined, (knobs, prev, level)
                checked += 1
                counts.add(examined)
            conn.execute("RESET ALL")
        assert checked >= 16 and len(counts) >= 8, (checked, counts)


# 0.6.0's continuity_ratio, as the upgrade to 0.2.0 created it: no later script changed it before
# 0.7.0 (extension/compare_chain.py shows the chain installs each release's catalogue).
FROZEN_0_6_0 = REPO / "extension" / "sql" / "released" / "modb--0.1.0--0.2.0.sql"


def test_the_c_continuity_ratio_equals_the_sql_expression_it_replaced_to_the_last_bit(cmu):
    # 0.7.0 computes the ratio in C. The 0.6.0 expression (from the released scripts, as a
    # temporary function) is the reference: same float4 differences, pow(x, 2), atan2, so the same
    # value, bit for bit.
    text = FROZEN_0_6_0.read_text()
    start = text.index("CREATE FUNCTION modb.continuity_ratio(a modb.terminators")
    old = text[start : text.index("COMMENT ON FUNCTION modb.continuity_ratio(", start)].replace(
        "CREATE FUNCTION modb.continuity_ratio(", "CREATE FUNCTION pg_temp.continuity_ratio_sql(", 1
    )
    with connect(cmu) as conn:
        conn.execute(old)
        ends = [r[0] for r in conn.execute("SELECT end_terminator FROM modb.snippets ORDER BY id")]
        compared = 0
        for knobs in (
            {},
            {"norm": "l1", "velocity_terms": "off", "joints": "pelvis,left_hip,head"},
            {"position_threshold": "0.05", "angle_threshold": "0.2"},
        ):
            conn.execute("RESET ALL")
            for knob, value in knobs.items():
                conn.execute("SELECT set_config(%s, %s, false)", [f"modb.{knob}", value])
            for prev in ends[5 :: len(ends) // 3][:3]:
                n, differ = conn.execute(
                    "WITH p AS MATERIALIZED (SELECT modb.match_plan('default') AS plan), "
                    "     q AS MATERIALIZED (SELECT t FROM modb.terminators t WHERE id = %s) "
                    "SELECT count(*), count(*) FILTER (WHERE modb.continuity_ratio(q.t, b, p.plan) "
                    "                                  IS DISTINCT FROM "
                    "pg_temp.continuity_ratio_sql(q.t, b, p.plan)) "
                    "  FROM p, q, (SELECT * FROM modb.terminators ORDER BY id LIMIT 2500) b",
                    [prev],
                ).fetchone()
                assert differ == 0, (knobs, prev, differ)
                compared += n
        assert compared >= 20_000


BAD_PARAMETER, RAISED = psycopg.errors.InvalidParameterValue, psycopg.errors.RaiseException


@pytest.mark.parametrize(
    "setting,call,error,message",
    [
        (
            None,
            "SELECT * FROM modb.select_next_snippet(NULL, '{1}')",
            BAD_PARAMETER,
            "target must be {x, z} or {x, y, z}",
        ),
        (
            None,
            "SELECT * FROM modb.select_next_snippet(NULL, '{1,2,3,4}')",
            BAD_PARAMETER,
            "target must be",
        ),
        (
            None,
            "SELECT * FROM modb.select_next_snippet(NULL, '{NaN,1}')",
            BAD_PARAMETER,
            "target must be",
        ),
        (
            None,
            "SELECT * FROM modb.select_next_snippet(NULL, NULL)",
            BAD_PARAMETER,
            "target must be",
        ),
        (
            None,
            "SELECT * FROM modb.select_next_snippet(999999999, '{0,1}')",
            BAD_PARAMETER,
            "no snippet 999999999",
        ),
        (
            None,
            "SELECT * FROM modb.select_next_snippet(999999999, '{0,1}', 'nope')",
            RAISED,
            'unknown match profile "nope"',
        ),
        (
            None,
            "SELECT * FROM modb.select_next_snippet(NULL, '{0,1}', 'default', 'no/such')",
            BAD_PARAMETER,
            'no collection "no/such"',
        ),
        (
            None,
            "SELECT * FROM modb.select_next_snippets(NULL, '{0,1}', NULL)",
            BAD_PARAMETER,
            "k must be at least 1",
        ),
        (
            "SET modb.position_threshold = '-1'",
            "SELECT * FROM modb.select_next_snippet(NULL, '{0,1}')",
            RAISED,
            "thresholds must be positive",
        ),
        (
            "SET modb.heading_weight = '-5'",
            "SELECT * FROM modb.select_next_snippet(NULL, '{0,1}')",
            RAISED,
            "heading_weight must not be negative",
        ),
        (
            "SET modb.continuity_weight = '-1'",
            "SELECT * FROM modb.select_next_snippet(NULL, '{0,1}')",
            RAISED,
            "continuity_weight must not be negative",
        ),
        (
            "SET modb.lookahead_distance = '0'",
            "SELECT * FROM modb.select_next_snippet(NULL, '{0,1}')",
            RAISED,
            "lookahead_distance must be positive",
        ),
    ],
)
def test_requests_that_cannot_be_answered_are_errors(cmu, setting, call, error, message):
    with connect(cmu) as conn:
        if setting:
            # Since 0.10.0 a knob out of range is refused at SET (the library is preloaded), and the
            # call, with the profile's value, is answered.
            with pytest.raises(psycopg.errors.InvalidParameterValue) as refused:
                conn.execute(setting)
            assert message.lower() in refused.value.diag.message_detail.lower()
            assert conn.execute(call).fetchall()
            return
        with pytest.raises(error, match=message):
            conn.execute(call).fetchall()


def test_the_previous_snippet_is_never_replayed(cmu):
    with connect(cmu) as conn:
        prev, clip, first, n = conn.execute(
            "SELECT id, clip_id, first_frame, n_frames FROM modb.snippets "
            "WHERE NOT mirrored ORDER BY id LIMIT 1 OFFSET 300"
        ).fetchone()
        rows = conn.execute(
            "SELECT s.clip_id, s.first_frame FROM modb.select_next_snippets(%s, '{0,0}', 500) x "
            "JOIN modb.snippets s ON s.id = x.snippet_id WHERE NOT s.mirrored",
            [prev],
        ).fetchall()
        assert rows
        for c, f in rows:
            assert c != clip or not (f + 1 <= first + n - 1 and first + 1 <= f + n - 1), (f, first)
