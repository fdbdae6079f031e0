"""select_next_snippets (C, 0.10.0) returns what the reference query (the 0.9.0 SQL function,
select_next_snippets_reference) returns: the same ids, levels, order, proximity and continuity, on
seeded requests reaching every relaxation level, with and without a transition graph, a collection
and an exclude list; and modb.explain_selection reports what the call scanned."""

from __future__ import annotations

import random
import re

import psycopg
import pytest
from support.databases import GRAPH

PROFILES = ("default", "strict", "locomotion")
# Session thresholds as fractions of the default profile's typical ones (None: the profile's own).
# With the previous snippet's own successor excluded, these reach every relaxation level on CMU 131.
TIGHTNESS = (None, 1.0, 0.5, 0.25)
PER_LEVEL = 50
CALL = "SELECT * FROM modb.{}(%s, %s, %s, %s, %s, %s)"
# The snippet that plays on from prev in its own clip (always a level-0 continuation).
SUCCESSOR = """
SELECT n.id FROM modb.snippets s JOIN modb.snippets n
    ON (n.clip_id, n.version, n.mirrored) = (s.clip_id, s.version, s.mirrored)
   AND n.first_frame = s.first_frame + s.n_frames - 1
 WHERE s.id = %s"""


def connect(dsn: str) -> psycopg.Connection:
    """Plain rows (modb's own connection returns arrays as numpy, which compare element-wise)."""
    return psycopg.connect(dsn, autocommit=True)


def _set_tightness(conn, f) -> None:
    """The four thresholds of the session, in one statement (a round trip, not four)."""
    params = []
    for knob, value in (
        ("position_threshold", 0.12),
        ("angle_threshold", 0.3),
        ("velocity_threshold", 0.6),
        ("angular_velocity_threshold", 4.0),
    ):
        params += [f"modb.{knob}", "" if f is None else repr(value * f)]
    conn.execute("SELECT " + ", ".join(["set_config(%s, %s, false)"] * 4), params)


def _both(conn, args):
    fast = conn.execute(CALL.format("select_next_snippets"), args).fetchall()
    reference = conn.execute(CALL.format("select_next_snippets_reference"), args).fetchall()
    return fast, reference


def _answered_by(conn, args) -> str:
    lines = [
        r[0]
        for r in conn.execute("SELECT * FROM modb.explain_selection(%s, %s, %s, %s, %s, %s)", args)
    ]
    return next(line for line in lines if "Answered by" in line)


# A profile of odd user thresholds (0.18.0, every term bounded): only wrists and ankles, the L1
# norm, no velocity terms, on top of the tightness factors.
ODD_KNOBS = {
    "joints": "left_wrist,right_wrist,left_ankle,right_ankle",
    "norm": "l1",
    "velocity_terms": "off",
}


def _set_knobs(conn, knobs: dict) -> None:
    for knob in ODD_KNOBS:
        conn.execute("SELECT set_config(%s, %s, false)", [f"modb.{knob}", knobs.get(knob, "")])


def _every_level(dsn: str, seed: int, knobs: dict, per_level_wanted: int = PER_LEVEL) -> None:
    """Seeded requests until every relaxation level 0-4 answered per_level_wanted of them: the fast
    path's rows (ids, levels, order, proximity, continuity) are the reference's."""
    rng = random.Random(seed)
    per_level = {level: 0 for level in range(5)}
    fast_answers = 0
    with connect(dsn) as conn:
        _set_knobs(conn, knobs)
        ids = [r[0] for r in conn.execute("SELECT id FROM modb.snippets ORDER BY id")]
        collections = [
            r[0] for r in conn.execute("SELECT modb.collection_path(id) FROM modb.collections")
        ]
        for i in range(3000):
            if min(per_level.values()) >= per_level_wanted:
                break
            f = rng.choice(TIGHTNESS)
            _set_tightness(conn, f)
            prev = rng.choice(ids)
            target = [round(rng.uniform(-6, 6), 3) for _ in range(rng.choice((2, 3)))]
            k = rng.choice((1, 1, 3, 8))
            exclude = rng.sample(ids, rng.choice((0, 0, 5, 40)))
            if rng.random() < 0.8:
                exclude += [r[0] for r in conn.execute(SUCCESSOR, [prev])]
            collection = rng.choice(collections) if rng.random() < 0.2 else None
            args = [prev, target, k, rng.choice(PROFILES), collection, exclude or None]
            fast, reference = _both(conn, args)
            assert fast == reference, (args, f, knobs)
            if reference:
                per_level[reference[0][7]] += 1
                if (
                    reference[0][7] < 4
                    and len(reference) == k
                    and reference[-1][7] < 4
                    and i % 7 == 0
                ):
                    assert "the fast path" in _answered_by(conn, args), args
                    fast_answers += 1
        _set_tightness(conn, None)
        _set_knobs(conn, {})
    assert min(per_level.values()) >= per_level_wanted, per_level
    assert fast_answers >= per_level_wanted * 2 // 5  # 20 of the default 50


def test_fast_path_equals_the_reference_at_every_level(cmu):
    _every_level(cmu, 23, {})


def test_fast_path_equals_the_reference_with_odd_user_thresholds(cmu):
    """Term codes bound every term a profile can name: a profile that names few joints, compares
    positions by the L1 norm and leaves velocities out gets the reference's rows at every level
    (15 requests a level here; `modb bench tail` compares hundreds more)."""
    _every_level(cmu, 29, ODD_KNOBS, 15)


def test_fast_path_equals_the_reference_with_a_transition_graph(locomotion):
    rng = random.Random(5)
    stored = 0
    with connect(locomotion) as conn:
        conn.execute("SELECT set_config('modb.graph', %s, false)", [GRAPH])
        ids = [r[0] for r in conn.execute("SELECT snippet_id FROM modb.graph_snippets ORDER BY 1")]
        for _ in range(150):
            target = [round(rng.uniform(-8, 8), 3) for _ in range(2)]
            args = [rng.choice(ids), target, rng.choice((1, 4)), "default", None, None]
            fast, reference = _both(conn, args)
            assert fast == reference, args
            lines = [
                r[0]
                for r in conn.execute(
                    "SELECT * FROM modb.explain_selection(%s, %s, %s, %s, %s, %s)", args
                )
            ]
            stored += any("stored transitions" in line for line in lines)
    assert stored >= 100  # level 0 read the graph's stored transitions and ranked by its cost-to-go


def test_a_start_and_errors_are_the_references(cmu, locomotion):
    """A start (no previous snippet; 0.29.0's fast path, every pose's blocks least objective first)
    returns the reference's rows: targets near and far, k, profiles, a collection, excluded
    snippets, an annotation spec and a transition graph; the errors are the reference's."""
    rng = random.Random(7)
    for dsn in (cmu, locomotion):
        with connect(dsn) as conn:
            ids = [r[0] for r in conn.execute("SELECT id FROM modb.snippets ORDER BY id")]
            collections = [
                r[0] for r in conn.execute("SELECT modb.collection_path(id) FROM modb.collections")
            ]
            graph = conn.execute(
                "SELECT name FROM modb.graphs WHERE kind = 'transitions' LIMIT 1"
            ).fetchone()
            for i in range(12 if dsn == cmu else 8):  # the reference scans every snippet
                args = [
                    None,
                    [round(rng.uniform(-8, 8), 2) for _ in range(rng.choice((2, 3)))],
                    rng.choice((1, 3, 8)),
                    rng.choice(PROFILES),
                    rng.choice(collections) if i % 4 == 1 else None,
                    rng.sample(ids, 20) if i % 4 == 2 else None,
                ]
                knob = {3: ("modb.annotations", "!fall"), 0: ("modb.graph", graph and graph[0])}
                setting = knob.get(i % 4) if i % 8 < 4 else None
                if setting and setting[1]:
                    conn.execute("SELECT set_config(%s, %s, false)", list(setting))
                fast, reference = _both(conn, args)
                assert fast == reference and fast, (args, setting)
                assert "the fast path" in _answered_by(conn, args), args
                conn.execute("RESET modb.annotations")
                conn.execute("RESET modb.graph")
    with connect(cmu) as conn:
        for bad, message in (
            ([1, [1.0], 1, "default", None, None], "target must be"),
            ([1, [1.0, 2.0], 0, "default", None, None], "k must be at least 1"),
            ([-5, [1.0, 2.0], 1, "default", None, None], "no snippet -5"),
            ([1, [1.0, 2.0], 1, "nonesuch", None, None], 'unknown match profile "nonesuch"'),
            ([1, [1.0, 2.0], 1, "default", "no/such", None], 'no collection "no/such"'),
        ):
            with pytest.raises(Exception, match=message):
                conn.execute(CALL.format("select_next_snippets"), bad)


def _outside(lines: list[str]) -> int:
    """The candidates explain_selection says were passed over as outside the graph or collection."""
    found = [re.search(r"outside the graph or collection: (\d+)", line) for line in lines]
    return sum(int(m.group(1)) for m in found if m)


def test_a_graph_or_small_collection_is_known_before_rows_are_read(locomotion):
    """0.29.0: a call naming a transition graph, or a collection of at most a quarter of the
    snippets, passes over the candidates outside it when their block is read (their ids read once
    a session after 64 rows refused, src/candidate_sets.c), not when their rows are: the rows stay
    the reference's for starts, plain calls, coming to rest and setting off in collection
    demo/cmu/131 of the demo's data, and starts in the demo's graph; and explain_selection counts
    those passed over."""
    rng = random.Random(61)
    small = "demo/cmu/131"
    ending = "SELECT * FROM modb.{}(%s, %s, %s, %s, %s, %s, %s, %s)"
    with connect(locomotion) as conn:
        ids = [
            r[0]
            for r in conn.execute(
                "SELECT id FROM modb.snippets"
                " WHERE collection_id = ANY (modb.collection_subtree(%s)) ORDER BY id",
                [small],
            )
        ]
        (everything,) = conn.execute("SELECT count(*) FROM modb.snippets").fetchone()
        assert len(ids) <= everything / 4, (len(ids), everything)  # small enough to be kept
        outside = {"collection": 0, "graph": 0}
        for i in range(14):
            target = [round(rng.uniform(-6, 6), 2), round(rng.uniform(-6, 6), 2)]
            prev = None if i % 7 == 0 else rng.choice(ids)
            args = [prev, target, rng.choice((1, 3)), rng.choice(PROFILES), small, None]
            fast, reference = _both(conn, args)
            assert fast == reference and fast, args
            outside["collection"] += _outside(_explain(conn, args))
            if prev is not None:
                asked = [prev, [0.0, 0.0, 0.0], 0.0, target, "default", small, None, i % 2 == 0]
                fast = conn.execute(ending.format("select_snippet_ending"), asked).fetchall()
                reference = conn.execute(
                    ending.format("select_snippet_ending_reference"), asked
                ).fetchall()
                assert fast == reference, asked
        conn.execute("SELECT set_config('modb.graph', %s, false)", [GRAPH])
        for _ in range(2):  # starts in the graph (the reference scans every snippet)
            args = [None, [round(rng.uniform(-6, 6), 2), 8.0], 1, "default", None, None]
            fast, reference = _both(conn, args)
            assert fast == reference and fast, args
            outside["graph"] += _outside(_explain(conn, args))
        conn.execute("RESET modb.graph")
    assert all(n > 0 for n in outside.values()), outside


def _explain(conn, args, verbose=False) -> list[str]:
    return [
        r[0]
        for r in conn.execute(
            "SELECT * FROM modb.explain_selection(%s, %s, %s, %s, %s, %s, %s)", [*args, verbose]
        )
    ]


def _level(lines: list[str], level: int) -> list[str]:
    """The lines of one level's report (its first line and the indented ones after it)."""
    first = next(i for i, line in enumerate(lines) if line.startswith(f"  Level {level}"))
    rest = [line for line in lines[first + 1 :]]
    end = next((i for i, line in enumerate(rest) if not line.startswith("    ")), len(rest))
    return lines[first : first + 1 + end]


def test_explain_selection_counts_what_the_rule_finds_and_fits_a_screen(cmu):
    """The rows explain_selection says level 0 found within the ratio are the reference's level-0
    rows (asked for more rows than there are, it returns every one); asked for one in a wide box, it
    reads fewer rows than it has candidates (least key first). Its report fits a screen (at most 40
    lines of at most 120 characters) at every level; verbose adds the profile and each level's box,
    the box a sequential scan agrees with."""
    rng = random.Random(8)
    with connect(cmu) as conn:
        ids = [r[0] for r in conn.execute("SELECT id FROM modb.snippets ORDER BY id")]
        fewer = levels_seen = 0
        for i in range(10):
            prev = rng.choice(ids)
            _set_tightness(conn, 2.0)  # a wider box: more candidates than one batch
            one = _level(_explain(conn, [prev, [0.5, 3.0], 1, "default", None, None]), 0)
            _set_tightness(conn, None)
            args = [prev, [0.5, 3.0], len(ids) + 1, "default", None, None]
            lines = _explain(conn, args, verbose=True)
            level0 = " ".join(_level(lines, 0))
            within = int(re.search(r"(\d+) within ratio 1,", level0).group(1))
            reference = conn.execute(CALL.format("select_next_snippets_reference"), args).fetchall()
            assert within == sum(1 for row in reference if row[7] == 0), (args, level0)
            assert '"position_threshold"' in lines[1], lines[1]
            box = next(line for line in lines if line.startswith("    Box:")).split("'")[1]
            in_box = int(re.search(r"rows read: (\d+) in the box", level0).group(1))
            conn.execute("SET enable_indexscan = off")
            conn.execute("SET enable_bitmapscan = off")
            (brute,) = conn.execute(
                "SELECT count(*) FROM modb.snippets WHERE begin_features <@ %s::cube", [box]
            ).fetchone()
            conn.execute("RESET enable_indexscan")
            conn.execute("RESET enable_bitmapscan")
            assert in_box <= brute, (args, level0)  # the term codes left out some of the box
            m = re.search(r"(\d+) candidates, (\d+) rows read", " ".join(one))
            candidates, read = int(m.group(1)), int(m.group(2))
            assert read <= candidates
            fewer += read < candidates
            # a screen, whatever the level reached (tight thresholds reach levels 1-3)
            _set_tightness(conn, (1.0, 0.25, 0.1)[i % 3])
            successor = [r[0] for r in conn.execute(SUCCESSOR, [prev])] or None
            short = _explain(conn, [prev, [4.0, -2.0], 1, "default", None, successor])
            _set_tightness(conn, None)
            assert len(short) <= 40 and max(map(len, short)) <= 120, short
            levels_seen = max(
                levels_seen, sum("not run" not in line for line in short if "  Level" in line)
            )
        assert fewer >= 3
        assert levels_seen >= 2


def _requests(conn, rng, n, but_clip=None):
    ids = [
        r[0]
        for r in conn.execute(
            "SELECT id FROM modb.snippets WHERE clip_id IS DISTINCT FROM %s ORDER BY id", [but_clip]
        )
    ]
    out = []
    for _ in range(n):
        prev = rng.choice(ids)
        exclude = [r[0] for r in conn.execute(SUCCESSOR, [prev])] or None
        out.append([prev, [round(rng.uniform(-4, 4), 3), 2.0], 3, "default", None, exclude])
    return out


def test_own_uncommitted_snippets_are_selected_and_rolled_back_ones_are_not(cmu):
    """A transaction that rebuilds a clip's snippets (new ids, new blocks) selects among them before
    it commits, as the reference does under the same snapshot; after its rollback neither sees
    them."""
    rng = random.Random(11)
    with connect(cmu) as conn:
        (clip,) = conn.execute(
            "SELECT min(clip_id) FROM modb.snippets WHERE NOT mirrored"
        ).fetchone()
        before = conn.execute("SELECT max(id) FROM modb.snippets").fetchone()[0]
        with conn.transaction(force_rollback=True):
            conn.execute(
                "DELETE FROM modb.snippet_sources WHERE clip_id = %s AND NOT mirrored", [clip]
            )
            assert conn.execute("SELECT modb.build_snippets(clip => %s)", [clip]).fetchone()[0] > 0
            new = [
                r[0] for r in conn.execute("SELECT id FROM modb.snippets WHERE id > %s", [before])
            ]
            chosen_new = 0
            for args in _requests(conn, rng, 40) + [
                [p, [0.0, 2.0], 3, "default", None, None] for p in rng.sample(new, 20)
            ]:
                fast, reference = _both(conn, args)
                assert fast == reference, args
                chosen_new += any(row[0] > before for row in fast)
            assert chosen_new >= 10  # the uncommitted snippets were candidates
        for args in _requests(conn, rng, 20):
            fast, reference = _both(conn, args)
            assert fast == reference and all(row[0] <= before for row in fast), args


def test_a_repeatable_read_snapshot_keeps_its_snippets_while_another_session_changes_them(cmu):
    rng = random.Random(12)
    with connect(cmu) as reader, connect(cmu) as writer:
        (clip,) = writer.execute("SELECT max(clip_id) FROM modb.snippets WHERE mirrored").fetchone()
        requests = _requests(reader, rng, 30, but_clip=clip)  # prevs that outlive the writer
        reader.autocommit = False
        reader.isolation_level = psycopg.IsolationLevel.REPEATABLE_READ
        first = [_both(reader, args) for args in requests]
        assert all(fast == reference for fast, reference in first)
        # Committed while the reader's snapshot lasts: new blocks and ids (the clip with the highest
        # ids, so the shared database keeps its order).
        with writer.transaction():
            writer.execute(
                "DELETE FROM modb.snippet_sources WHERE clip_id = %s AND mirrored", [clip]
            )
            writer.execute("SELECT modb.build_snippets(clip => %s, mirrored => true)", [clip])
        again = [_both(reader, args) for args in requests]
        assert again == first  # the reader's snapshot: the old snippets, its directory read again
        reader.rollback()
        reader.autocommit = True
        for args in requests:
            fast, reference = _both(reader, args)
            assert fast == reference, args


def _covered_once(conn) -> tuple[int, int]:
    """Snippets in no block, and snippets in more than one."""
    return conn.execute(
        "SELECT (SELECT count(*) FROM modb.snippets s WHERE NOT EXISTS "
        "        (SELECT FROM modb.snippet_blocks b WHERE s.id = ANY (b.snippets))),"
        "       (SELECT count(*) FROM (SELECT unnest(snippets) FROM modb.snippet_blocks "
        "        GROUP BY 1 HAVING count(*) > 1) twice)"
    ).fetchone()


def test_packed_blocks_cover_every_snippet_once_and_answer_as_the_reference(cmu):
    """modb.pack_snippet_blocks (0.11.0) re-cuts every pose's blocks into k-d leaves: each snippet
    in exactly one block, the packing's order 0..n-1, and the fast path still answers as the
    reference, at every level, before and after a clip's snippets are rebuilt beside the packed
    blocks (deleted ids left in packed blocks, new ones in blocks of consecutive snippets)."""
    rng = random.Random(31)
    with connect(cmu) as conn, conn.transaction(force_rollback=True):
        packed = conn.execute("SELECT * FROM modb.pack_snippet_blocks(0)").fetchall()
        (n_snippets,) = conn.execute("SELECT count(*) FROM modb.snippets").fetchone()
        assert sum(row[2] for row in packed) == n_snippets
        assert _covered_once(conn) == (0, 0)
        assert conn.execute(
            "SELECT bool_and(n = orders AND lowest = 0 AND highest = n - 1) FROM (SELECT"
            " count(*) n, count(DISTINCT pack_order) orders, min(pack_order) lowest,"
            " max(pack_order) highest"
            " FROM modb.snippet_blocks GROUP BY pose_key, fps) g"
        ).fetchone() == (True,)
        ids = [r[0] for r in conn.execute("SELECT id FROM modb.snippets ORDER BY id")]
        (clip,) = conn.execute(
            "SELECT min(clip_id) FROM modb.snippets WHERE NOT mirrored"
        ).fetchone()
        levels = set()
        for step in ("packed", "a clip rebuilt beside them"):
            if step != "packed":
                conn.execute(
                    "DELETE FROM modb.snippet_sources WHERE clip_id = %s AND NOT mirrored", [clip]
                )
                conn.execute("SELECT modb.build_snippets(clip => %s)", [clip])
                assert _covered_once(conn) == (0, 0)
                ids = [r[0] for r in conn.execute("SELECT id FROM modb.snippets ORDER BY id")]
            for _ in range(120):
                f = rng.choice(TIGHTNESS)
                _set_tightness(conn, f)
                prev = rng.choice(ids)
                exclude = [r[0] for r in conn.execute(SUCCESSOR, [prev])] or None
                target = [round(rng.uniform(-6, 6), 3) for _ in range(2)]
                args = [prev, target, rng.choice((1, 3)), rng.choice(PROFILES), None, exclude]
                fast, reference = _both(conn, args)
                assert fast == reference, (step, args, f)
                levels.update(row[7] for row in reference)
        _set_tightness(conn, None)
        assert levels >= {0, 1, 2, 3}, levels


def test_a_packing_waits_for_a_load_in_flight_and_keeps_its_blocks(cmu):
    """A load that has added snippets (and blocks) but not committed holds the blocks' generation
    row: the packing waits for it, then packs what was committed, the loaded snippets with the
    rest."""
    with connect(cmu) as loader, connect(cmu) as packer:
        (clip,) = loader.execute(
            "SELECT max(clip_id) FROM modb.snippets WHERE NOT mirrored"
        ).fetchone()
        loader.autocommit = False
        loader.execute(
            "DELETE FROM modb.snippet_sources WHERE clip_id = %s AND NOT mirrored", [clip]
        )
        loader.execute("SELECT modb.build_snippets(clip => %s)", [clip])
        packer.execute("SET lock_timeout = '300ms'")
        with pytest.raises(psycopg.errors.LockNotAvailable):
            packer.execute("SELECT * FROM modb.pack_snippet_blocks(0)")
        loader.commit()
        packed = packer.execute("SELECT * FROM modb.pack_snippet_blocks(0)").fetchall()
        (n_snippets,) = packer.execute("SELECT count(*) FROM modb.snippets").fetchone()
        assert sum(row[2] for row in packed) == n_snippets
        assert _covered_once(packer) == (0, 0)


def test_a_terminator_edited_by_hand_brings_its_snippets_new_term_codes(cmu):
    """A block's term codes are its snippets' begin terminators: an UPDATE of a terminator (which no
    writer of the project makes) adds a block for each snippet that begins there, and a selection
    that the edit changes still answers as the reference (rolled back: the database is shared)."""
    rng = random.Random(31)
    with connect(cmu) as conn, conn.transaction(force_rollback=True):
        ids = [r[0] for r in conn.execute("SELECT id FROM modb.snippets ORDER BY id")]
        edited = rng.sample(ids, 20)
        before = conn.execute(
            "SELECT count(*) FROM modb.snippet_blocks b WHERE b.snippets && %s::bigint[]", [edited]
        ).fetchone()[0]
        # both wrists' rotations made a quarter turn about x: their candidates' ratios change
        conn.execute(
            "UPDATE modb.terminators t SET rotations = (SELECT array_agg(CASE"
            " WHEN (i - 1) / 4 IN (11, 18)"
            " THEN (ARRAY[0.70710677, 0, 0, 0.70710677])[(i - 1) %% 4 + 1]"
            " ELSE t.rotations[i] END ORDER BY i) FROM generate_subscripts(t.rotations, 1) i)"
            " WHERE t.id IN (SELECT begin_terminator FROM modb.snippets WHERE id = ANY (%s))",
            [edited],
        )
        after = conn.execute(
            "SELECT count(*) FROM modb.snippet_blocks b WHERE b.snippets && %s::bigint[]", [edited]
        ).fetchone()[0]
        assert after > before
        for prev in rng.sample(ids, 30):
            args = [prev, [1.0, 2.0], 5, "default", None, None]
            fast, reference = _both(conn, args)
            assert fast == reference, args


REFERENCE_CALLS = """
SELECT coalesce(sum(calls), 0) FROM pg_stat_xact_user_functions
 WHERE schemaname = 'modb' AND funcname = 'select_snippet_ending_reference'"""


def test_coming_to_rest_and_setting_off_answer_as_their_reference(cmu):
    """select_snippet_ending (C, 0.18.0) returns what select_snippet_ending_reference (the SQL
    rule of coming to rest and setting off) returns: the same snippet, level, proximity and ratio,
    or none; at every level, each one the least L with ratio <= 2^L; and it answers by itself
    (0.28.0 and before sent every call to the reference: the function statistics count its
    calls)."""
    rng = random.Random(41)
    call = "SELECT * FROM modb.{}(%s, %s, %s, %s, %s, NULL, %s, %s)"
    levels = {}
    with connect(cmu) as conn:
        conn.execute("SET track_functions = 'all'")
        ids = [r[0] for r in conn.execute("SELECT id FROM modb.snippets ORDER BY id")]
        for i in range(60):
            args = [
                rng.choice(ids),
                [round(rng.uniform(-3, 3), 2), 0.0, round(rng.uniform(-3, 3), 2)],
                round(rng.uniform(-3, 3), 2),
                [round(rng.uniform(-6, 6), 2), round(rng.uniform(-6, 6), 2)],
                rng.choice(PROFILES),
                rng.sample(ids, rng.choice((0, 3))) or None,
                rng.random() < 0.6,
            ]
            _set_tightness(conn, (None, 0.5, 0.25)[i % 3])
            with conn.transaction():  # pending counts: of earlier transactions too until flushed
                before = conn.execute(REFERENCE_CALLS).fetchone()[0]
                fast = conn.execute(call.format("select_snippet_ending"), args).fetchall()
                assert conn.execute(REFERENCE_CALLS).fetchone()[0] == before, args
            reference = conn.execute(
                call.format("select_snippet_ending_reference"), args
            ).fetchall()
            assert fast == reference, args
            for row in reference:
                level, ratio = row[7], row[8]
                assert level == next(k for k in range(4) if ratio <= 2.0**k), row
                levels[level] = levels.get(level, 0) + 1
        _set_tightness(conn, None)
    assert sorted(levels) == [0, 1, 2, 3], levels
