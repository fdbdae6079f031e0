"""What select_next_snippet(s), select_next_snippet_world and synthesize do with input they cannot
honour: errors naming the argument or knob, its value and what is allowed, never a silent row or no
row; and an exclude list that costs time linear in its length. Through the public SQL functions only
(the plan-shape check reads EXPLAIN generically), on real capture: four Bandai walks."""

from __future__ import annotations

import os
import random

import psycopg
import pytest
from support.commands import run_modb
from support.data import mocap
from support.databases import scratch_database

from modb.database.connection import connect

BAD_PARAMETER = psycopg.errors.InvalidParameterValue
TARGET = "{0.3, 2}"


@pytest.fixture(scope="module")
def walks(cluster):
    files = [
        mocap("bandai-1", "data", f"dataset-1_walk_{style}_001.bvh")
        for style in ("active", "angry", "normal", "happy")
    ]
    with scratch_database(cluster, f"selection_input_{os.getpid()}") as dsn:
        r = run_modb(dsn, "load", *files, "--collection", "bandai-1", "-q")
        assert r.returncode == 0, r.stderr
        yield dsn


@pytest.fixture
def conn(walks):
    with connect(walks) as c:
        yield c


def middle_snippet(conn) -> int:
    """A snippet from the middle of the first clip: it has neighbours on both sides."""
    return conn.execute(
        "SELECT id FROM modb.snippets WHERE NOT mirrored "
        "AND clip_id = (SELECT min(clip_id) FROM modb.snippets) "
        "ORDER BY first_frame LIMIT 1 OFFSET 60"
    ).fetchone()[0]


def refused(conn, sql, params=(), error=psycopg.Error) -> psycopg.Error:
    with pytest.raises(error) as caught:
        conn.execute(sql, params).fetchall()
    return caught.value


# --- 1. knobs: finite and in their documented ranges, checked at SET ------------------------------

OUT_OF_RANGE_KNOBS = [
    ("position_threshold", "Infinity"),  # was accepted: a row at level 0, whatever the seam
    ("position_threshold", "NaN"),
    ("position_threshold", "1e999"),  # what the avatar panel can send; was a bare float8 error
    ("position_threshold", "-Infinity"),
    ("position_threshold", "0"),
    ("position_threshold", "-1"),
    ("angle_threshold", "inf"),
    ("velocity_threshold", "NaN"),
    ("angular_velocity_threshold", "1e999"),
    ("heading_weight", "Infinity"),
    ("heading_weight", "-1"),
    ("heading_weight", "NaN"),
    ("continuity_weight", "Infinity"),
    ("lookahead_distance", "NaN"),
    ("lookahead_distance", "0"),
    ("position_threshold", "abc"),
    ("velocity_terms", "maybe"),
]


@pytest.mark.parametrize("knob,value", OUT_OF_RANGE_KNOBS)
def test_a_knob_out_of_its_range_is_refused_at_set_naming_it_its_value_and_the_range(
    conn, knob, value
):
    # Since 0.10.0 the knobs are real settings (the test cluster preloads modb, as the embedded one
    # does): the SET itself fails, and the session keeps the profile's value.
    e = refused(conn, "SELECT set_config(%s, %s, false)", [f"modb.{knob}", value])
    message, detail = e.diag.message_primary or "", e.diag.message_detail or ""
    assert f"modb.{knob}" in message and value in message, message
    assert "allowed" in detail or "on or off" in detail, detail
    assert f"modb.{knob}" in (e.diag.message_hint or ""), e.diag.message_hint  # what to do
    assert conn.execute(f"SHOW modb.{knob}").fetchone()[0] == ""


@pytest.mark.parametrize(
    "call",
    [
        "SELECT * FROM modb.select_next_snippet(NULL, '{0, 2}')",
        "SELECT * FROM modb.select_next_snippets(%(prev)s, '{0, 2}', 3)",
        "SELECT * FROM modb.select_next_snippet_world(%(prev)s, '{0, 0, 0}', 0, '{0, 2}')",
        "SELECT * FROM modb.synthesize('{{0, 4}}', 3)",
        "SELECT modb.candidates_examined(%(prev)s, 0)",
    ],
)
def test_every_entry_point_refuses_an_infinite_threshold(conn, call):
    refused(conn, "SET modb.position_threshold = 'Infinity'")
    prev = middle_snippet(conn)
    # A profile's own values are checked where the plan is resolved, on every path.
    with pytest.raises(psycopg.Error) as caught, conn.transaction():
        conn.execute(
            "UPDATE modb.match_profiles SET settings = settings || "
            "'{\"position_threshold\": \"Infinity\"}' WHERE name = 'default'"
        )
        conn.execute(call, {"prev": prev} if "%(" in call else ()).fetchall()
    message = caught.value.diag.message_primary
    assert 'profile "default"' in message and "position_threshold" in message, message


def test_knobs_in_range_still_select(conn):
    prev = middle_snippet(conn)
    for knob, value in [
        ("position_threshold", "0.001"),  # tight: answered at a relaxation level, still answered
        ("position_threshold", " 0.2 "),
        ("angle_threshold", "3.5"),  # beyond pi: no limit, but a number
        ("heading_weight", "0"),
        ("continuity_weight", "0"),
        ("lookahead_distance", "1e3"),
        ("velocity_terms", "off"),
    ]:
        conn.execute("SELECT set_config(%s, %s, false)", [f"modb.{knob}", value])
        rows = conn.execute(
            "SELECT snippet_id FROM modb.select_next_snippet(%s, %s)", [prev, TARGET]
        ).fetchall()
        assert len(rows) == 1, (knob, value)
        conn.execute(f"RESET modb.{knob}")


@pytest.mark.parametrize(
    "name,threshold", [("infinite", '"Infinity"'), ("huge", "1e999"), ("negative", "-0.1")]
)
def test_a_profile_threshold_out_of_range_is_an_error_naming_the_profile_and_joint(
    conn, name, threshold
):
    conn.execute(
        "INSERT INTO modb.match_profiles (name, settings) SELECT %s, settings "
        "|| jsonb_build_object('position_threshold', %s::jsonb) "
        "FROM modb.match_profiles WHERE name = 'default'",
        [f"input_{name}", f'{{"default": 0.1, "left_ankle": {threshold}}}'],
    )
    try:
        e = refused(
            conn,
            "SELECT * FROM modb.select_next_snippet(%s, %s, %s)",
            [middle_snippet(conn), TARGET, f"input_{name}"],
        )
        message = e.diag.message_primary
        assert f'profile "input_{name}"' in message and "left_ankle" in message, message
        assert "position_threshold" in message and "allowed" in message, message
    finally:
        conn.execute("DELETE FROM modb.match_profiles WHERE name = %s", [f"input_{name}"])


# --- 2. targets, k, prev, the world arguments, synthesize's goals and lengths -------------------


@pytest.mark.parametrize(
    "target",
    [
        "{}",  # was answered with a row
        "[0:1]={1,2}",  # was answered, reading a NULL z
        "{1e308, 1}",  # was a bare overflow error
        "{NaN, 1}",
        "{Infinity, 0}",
        "{0, -Infinity, 1}",
        "{1, NULL}",
        "{{1, 2}}",
        "{1}",
        "{1, 2, 3, 4}",
    ],
)
def test_a_target_that_is_not_x_z_or_x_y_z_of_finite_metres_is_an_error(conn, target):
    prev = middle_snippet(conn)
    for call in (
        "SELECT * FROM modb.select_next_snippet(%s, %s)",
        "SELECT * FROM modb.select_next_snippets(%s, %s, 3)",
    ):
        e = refused(conn, call, [prev, target], BAD_PARAMETER)
        assert "target must be {x, z} or {x, y, z}" in e.diag.message_primary


@pytest.mark.parametrize("prev_is_null", [False, True])
@pytest.mark.parametrize(
    "k", [0, -3, None]
)  # 0: returned nothing; -3: "LIMIT must not be negative"
def test_k_below_one_is_the_documented_error(conn, k, prev_is_null):
    prev = None if prev_is_null else middle_snippet(conn)
    e = refused(
        conn,
        "SELECT * FROM modb.select_next_snippets(%s, %s, %s)",
        [prev, TARGET, k],
        BAD_PARAMETER,
    )
    assert f"k must be at least 1, got {'NULL' if k is None else k}" in e.diag.message_primary


def test_a_null_prev_starts_anywhere(conn):
    # README: prev_snippet NULL means "start": the snippets that best serve the target, any pose.
    rows = conn.execute(
        "SELECT snippet_id, relax_level, continuity, proximity "
        "FROM modb.select_next_snippets(NULL, %s, 5)",
        [TARGET],
    ).fetchall()
    assert len(rows) == 5 and all(r[1] == 0 and r[2] is None for r in rows)
    assert [r[3] for r in rows] == sorted(r[3] for r in rows)
    (best,) = conn.execute(
        "SELECT snippet_id FROM modb.select_next_snippet(NULL, %s)", [TARGET]
    ).fetchone()
    assert best == rows[0][0]
    first = conn.execute(
        "SELECT snippet_id FROM modb.select_next_snippet(NULL, %s, exclude => %s)",
        [TARGET, [best]],
    ).fetchone()[0]
    assert first != best


@pytest.mark.parametrize(
    "position,heading,target_world,argument",
    [
        ("{0, 0}", "0", "{1, 2}", "position must be {x, y, z}"),  # was blamed on the target
        (None, "0", "{1, 2}", "position must be {x, y, z}"),
        ("{0, NaN, 0}", "0", "{1, 2}", "position must be {x, y, z}"),
        ("{0, 0, 0}", "NaN", "{1, 2}", "heading must be a finite angle"),
        ("{0, 0, 0}", "Infinity", "{1, 2}", "heading must be a finite angle"),
        ("{0, 0, 0}", None, "{1, 2}", "heading must be a finite angle"),
        ("{0, 0, 0}", "0", "{}", "target_world must be {x, z} or {x, y, z}"),
        ("{0, 0, 0}", "0", "{Infinity, 1}", "target_world must be {x, z} or {x, y, z}"),
        ("{0, 0, 0}", "0", "[0:1]={1,2}", "target_world must be {x, z} or {x, y, z}"),
    ],
)
def test_select_next_snippet_world_names_the_bad_argument(
    conn, position, heading, target_world, argument
):
    e = refused(
        conn,
        "SELECT * FROM modb.select_next_snippet_world(%s, %s, %s, %s)",
        [middle_snippet(conn), position, heading, target_world],
        BAD_PARAMETER,
    )
    assert argument in e.diag.message_primary


def test_select_next_snippet_world_still_answers_as_the_local_call(conn):
    prev = middle_snippet(conn)
    world = conn.execute(
        "SELECT snippet_id FROM modb.select_next_snippet_world(%s, '{3, 0, 1}', pi() / 2, "
        "'{5, 0.7}')",
        [prev],
    ).fetchone()
    # facing +X from (3, 1), left is -Z: the goal (5, 0.7) is 2 m ahead and 0.3 m to the left
    local = conn.execute(
        "SELECT snippet_id FROM modb.select_next_snippet(%s, '{0.3, 2}')", [prev]
    ).fetchone()
    assert world == local


@pytest.mark.parametrize(
    "arguments,message",
    [
        ("'{{0, 4}}', 5, arrival_radius => 'NaN'", "arrival_radius must be a positive"),  # ran
        ("'{{0, 4}}', 5, arrival_radius => 'Infinity'", "arrival_radius must be a positive"),
        ("'{{0, 4}}', 5, exclude_seconds => 'NaN'", "exclude_seconds must be zero or more"),  # ran
        ("'[0:0][1:2]={{1, 2}}', 5", "targets must be a list of world goals"),  # blamed a target
        ("'{{1e308, 0}}', 5", "targets must be a list of world goals"),  # bare overflow error
        ("'{{Infinity, 0}}', 5", "targets must be a list of world goals"),
        ("'{}', 5", "targets must be a list of world goals"),
        ("'{{0, 4}}', 0", "max_snippets must be at least 1"),
        ("'{{0, 4}}', -1", "max_snippets must be at least 1"),
        ("'{{0, 4}}', NULL", "max_snippets must be at least 1"),
        ("'{{0, 4}}', 5, start_position => '{0, 0}'", "start_position must be {x, y, z}"),
        ("'{{0, 4}}', 5, start_position => '{0, NaN, 0}'", "start_position must be {x, y, z}"),
        ("'{{0, 4}}', 5, start_position => '[0:2]={0,0,0}'", "start_position must be {x, y, z}"),
        ("'{{0, 4}}', 5, start_heading => 'NaN'", "start_heading must be a finite angle"),
    ],
)
def test_synthesize_refuses_goals_and_lengths_it_cannot_honour(conn, arguments, message):
    e = refused(conn, f"SELECT * FROM modb.synthesize({arguments})", error=BAD_PARAMETER)
    assert message in e.diag.message_primary


# --- 3. exclude: linear in its length ----------------------------------------------------------

MARKER = 987_654_321  # an id no snippet has, to find the exclude list in a plan


def long_exclude(conn, prev) -> tuple[list[int], list[int]]:
    """A 10,000-element exclude list (the best continuation of prev, every snippet of another
    clip, each three times, shuffled among ids no snippet has) and the smaller list it is equivalent
    to."""
    (best,) = conn.execute(
        "SELECT snippet_id FROM modb.select_next_snippet(%s, %s)", [prev, TARGET]
    ).fetchone()
    other = [
        r[0]
        for r in conn.execute(
            "SELECT id FROM modb.snippets WHERE clip_id = (SELECT max(clip_id) FROM modb.snippets)"
        ).fetchall()
    ]
    real = [best, *other]
    (top,) = conn.execute("SELECT max(id) FROM modb.snippets").fetchone()
    ids = real * 3 + [MARKER]
    ids += range(top + 1, top + 1 + 10_000 - len(ids))
    random.Random(7).shuffle(ids)
    assert len(ids) == 10_000
    return ids, sorted(set(real))


def test_a_long_exclude_is_read_once_not_once_per_candidate(conn):
    prev = middle_snippet(conn)
    ids, _ = long_exclude(conn, prev)
    (explained,) = conn.execute(
        "EXPLAIN (ANALYZE, VERBOSE, FORMAT JSON) "
        "SELECT * FROM modb.select_next_snippet(%s, %s, exclude => %s)",
        [prev, TARGET, ids],
    ).fetchone()
    nodes, todo = [], [explained[0]["Plan"]]
    while todo:
        nodes.append(todo.pop())
        todo.extend(nodes[-1].get("Plans", []))
    marker = str(MARKER)
    readers = []
    for node in nodes:
        for key, value in node.items():
            if key in ("Plans", "Output") or marker not in str(value):
                continue
            # The list may be an argument of a function the plan runs (unnest, or the selection
            # itself when it is not inlined), never a condition tested per row (= ANY / <> ALL).
            assert key == "Function Call", (node["Node Type"], key, str(value)[:200])
            readers.append(node)
    assert readers and all(n.get("Actual Loops", 0) <= 1 for n in readers), [
        (n["Node Type"], n.get("Actual Loops")) for n in readers
    ]


def test_a_long_exclude_selects_what_its_short_equivalent_and_a_brute_force_select(conn):
    prev = middle_snippet(conn)
    ids, short = long_exclude(conn, prev)
    snippets = {
        r[0]: r[1:]
        for r in conn.execute(
            "SELECT id, clip_id, version, mirrored, first_frame, n_frames, pose_key, fps "
            "FROM modb.snippets"
        ).fetchall()
    }

    def played(s):  # the frames a snippet plays after its first (the seam)
        clip, version, mirrored, first, n = snippets[s][:5]
        return (clip, version, mirrored), first + 1, first + n - 1

    blocked = set()
    for x in [*short, prev]:
        source, lo, hi = played(x)
        for s in snippets:
            src, a, b = played(s)
            if src == source and a <= hi and lo <= b:
                blocked.add(s)
    same_kind = {s for s, v in snippets.items() if v[5:] == snippets[prev][5:]}
    assert set(short) <= blocked and len(blocked) < len(same_kind) - 10

    def select(k, exclude):
        return conn.execute(
            "SELECT snippet_id, relax_level, proximity, continuity "
            "FROM modb.select_next_snippets(%s, %s, %s, exclude => %s)",
            [prev, TARGET, k, exclude],
        ).fetchall()

    # With k above the number of snippets every level returns all it holds: the candidates are
    # exactly the snippets of prev's pose and rate that replay nothing prev or exclude played.
    everything = select(100_000, ids)
    assert {r[0] for r in everything} == same_kind - blocked
    assert everything == select(100_000, short)
    assert select(1, ids) == select(1, short) == everything[:1]
    assert (
        conn.execute(
            "SELECT snippet_id FROM modb.select_next_snippet(%s, %s, exclude => %s)",
            [prev, TARGET, ids],
        ).fetchone()[0]
        == everything[0][0]
    )
