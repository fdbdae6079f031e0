"""Parallel safety from behaviour (issue 56): every function of schema modb declared PARALLEL SAFE
is called inside a parallel worker, on real data, and must run there as it runs in the leader.

A label is a promise the planner acts on: a PARALLEL SAFE function may be run in a worker, where a
PL/pgSQL EXCEPTION block or a PL/Python plpy.execute (a subtransaction each, in PostgreSQL 15)
fails with "cannot start subtransactions during a parallel operation". So CALLS holds, for each
function pg_proc labels PARALLEL SAFE, a query that calls it with arguments read from columns of
regular tables (modb's own, and `args`, made here): constant arguments would let the planner fold
an immutable call in the leader, a STRICT function given NULL would never run, and a temporary
table would keep the query in the leader (parallel restricted). Each query runs under SET
force_parallel_mode = on: EXPLAIN ANALYZE must show a worker launched, the rows must be those the
leader returns with force_parallel_mode off, and there must be rows.

An immutable function without arguments is folded to a constant wherever its call is planned, so a
call in the query itself would run in the leader: it is called through planned_in_worker, which
runs a query text inside the worker, where that query is planned and the function evaluated.

test_every_parallel_safe_function_is_listed keeps CALLS (with NOT_CALLABLE: functions that take
`internal`, which no query can call) equal to what pg_proc labels PARALLEL SAFE, both ways: a new
function labelled so fails it until it gets a call here.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass

import psycopg
import pytest
from support.commands import run_modb
from support.data import mocap
from support.databases import plan_nodes, scratch_database

from modb.database.connection import connect
from modb.jobs.graph_build import build_here
from modb.models import graphs as model_graphs
from modb.models.pipeline import build_model

COLLECTION = "pw"
GRAPH = "pw_graph"  # the transition graph (over every snippet: one clip has no 45-degree turns)
MODEL_GRAPH = "pw_walk"  # the graph of the two step models

# Every function labelled PARALLEL SAFE, and whether it takes `internal` (no query can call it).
SAFE = """SELECT p.oid::regprocedure::text, 'internal'::regtype = ANY (p.proargtypes::regtype[])
            FROM pg_proc p WHERE p.pronamespace = 'modb'::regnamespace AND p.proparallel = 's'"""


@dataclass(frozen=True)
class Call:
    sql: str  # a query that calls the function (on the row of `args` and modb's tables)
    raises: str | None = None  # the error it must raise instead, in a worker as in the leader
    setting: str | None = None  # a SET for the session before the call


def rows_of(call: str, source: str = "args a") -> str:
    """A query of the rows a set-returning function returns. WITH ORDINALITY: a SQL function is
    called, not inlined into the query (where the planner judges its body, not its label, and a
    body that is safe inside a worker, a CTE say, keeps the whole query in the leader)."""
    return f"SELECT f.* FROM {source}, {call} WITH ORDINALITY f"


def planned_in_worker(expression: str) -> str:
    """A query that evaluates an argument-less expression where the query is planned: inside the
    worker (planned_in_worker is PL/pgSQL, whose queries are planned when they run)."""
    return f"SELECT planned_in_worker($$SELECT ({expression})::text$$) FROM args"


# The one row of table `args` (ARGS) holds the arguments: a snippet of the transition graph and a
# successor of it, the avatar's place and goals, and the other values the calls read. ENDS: the
# terminators where snippet `args.snippet` ends (e) and its successor `args.next` begins (b).
ENDS = (
    "args a JOIN modb.snippets s ON s.id = a.snippet"
    " JOIN modb.terminators e ON e.id = s.end_terminator"
    " JOIN modb.snippets n ON n.id = a.next"
    " JOIN modb.terminators b ON b.id = n.begin_terminator"
)
WORLD = "a.snippet, a.position, a.heading, a.target_world, a.profile, a.collection, a.exclude"

CALLS: dict[str, Call] = {
    "modb._collection_id(text)": Call("SELECT modb._collection_id(a.collection) FROM args a"),
    "modb._knob_boolean(text,text,text)": Call(
        "SELECT modb._knob_boolean(a.knob_boolean, a.on_text, a.origin) FROM args a"
    ),
    "modb._knob_number(text,text,text)": Call(
        "SELECT modb._knob_number(a.knob_number, a.number_text, a.origin) FROM args a"
    ),
    "modb._thresholds(jsonb,text[],text[])": Call(
        "SELECT modb._thresholds(a.threshold_spec, a.joint_names, a.included) FROM args a"
    ),
    "modb.aim_point(double precision[],double precision)": Call(
        "SELECT modb.aim_point(a.target, a.lookahead) FROM args a"
    ),
    "modb.annotated(bigint,integer,integer,integer,text[])": Call(
        "SELECT modb.annotated(a.clip, a.version, a.step_start, a.step_frames, a.spec),"
        " modb.annotated(a.clip, a.version, a.step_start, a.step_frames, a.spec_excluding)"
        " FROM args a"
    ),
    "modb.annotation_spec(text,text)": Call(
        "SELECT modb.annotation_spec(a.spec_text, a.origin) FROM args a"
    ),
    "modb.annotations_ok(jsonb,integer)": Call(
        "SELECT modb.annotations_ok(v.meta, v.n_frames) FROM modb.clip_versions v"
    ),
    "modb.approach_cost(double precision[],double precision[],double precision,double precision[],"
    "double precision)": Call(
        "SELECT modb.approach_cost(s.net_translation, s.future_translation, s.future_heading,"
        " a.target, a.heading_weight) FROM args a JOIN modb.snippets s ON s.id = a.snippet"
    ),
    "modb.can_rest(text)": Call("SELECT modb.can_rest(a.collection) FROM args a"),
    "modb.library_version()": Call("SELECT modb.library_version() FROM args a"),
    "modb.candidates_examined(bigint,integer,text)": Call(
        "SELECT modb.candidates_examined(a.snippet, a.relax_level, a.profile) FROM args a"
    ),
    "modb.check_request(bigint,double precision[],integer,text)": Call(
        "SELECT modb.check_request(a.snippet, a.target, a.k, a.collection) FROM args a"
    ),
    "modb.check_synthesis(double precision[],integer,bigint,double precision[],double precision,"
    "text,double precision,double precision)": Call(
        "SELECT modb.check_synthesis(a.targets, a.k, a.snippet, a.position, a.heading, a.profile,"
        " a.radius, a.exclude_seconds) FROM args a"
    ),
    "modb.check_world_request(double precision[],double precision,double precision[])": Call(
        "SELECT modb.check_world_request(a.position, a.heading, a.target_world) FROM args a"
    ),
    "modb.collection_path(bigint)": Call(
        "SELECT modb.collection_path(c.id) FROM modb.collections c ORDER BY c.id"
    ),
    "modb.collection_subtree(text)": Call(
        "SELECT modb.collection_subtree(a.collection) FROM args a"
    ),
    "modb.continuity_ratio(modb.terminators,modb.terminators,modb.match_plan)": Call(
        f"SELECT modb.continuity_ratio(e, b, modb.match_plan(a.profile)) FROM {ENDS}"
    ),
    "modb.continuity_ratio_native(modb.terminators,modb.terminators,modb.match_plan)": Call(
        f"SELECT modb.continuity_ratio_native(e, b, modb.match_plan(a.profile)) FROM {ENDS}"
    ),
    "modb.cost_to_go(real[],double precision[],jsonb)": Call(
        "SELECT modb.cost_to_go(t.cost_to_go, a.target, g.data->'cost_to_go') FROM args a"
        " JOIN modb.graph_transitions t ON t.from_snippet = a.snippet"
        " JOIN modb.graphs g ON g.id = t.graph_id"
    ),
    "modb.default_graph(text,text)": Call(
        "SELECT modb.default_graph(a.profile, a.collection) FROM args a"
    ),
    "modb.edit_script_problems(jsonb)": Call(
        "SELECT modb.edit_script_problems(a.commands) FROM args a"
    ),
    "modb.end_speed(bigint)": Call("SELECT modb.end_speed(a.snippet) FROM args a"),
    "modb.explain_selection(bigint,double precision[],integer,text,text,bigint[],boolean)": Call(
        # the lines of what it found: not the times, nor whether the session had the plan cached
        "SELECT f.line FROM args a, modb.explain_selection(a.snippet, a.target, a.k, a.profile,"
        " a.collection, a.exclude, a.verbose) WITH ORDINALITY f(line, n)"
        " WHERE f.line ~ '^ *(Answered by|snippets in|[0-9]+ candidates)'"
    ),
    "modb.feature_names()": Call(planned_in_worker("modb.feature_names()")),
    "modb.find_collection(text)": Call("SELECT modb.find_collection(a.collection) FROM args a"),
    "modb.finite_ok(real[])": Call(
        "SELECT modb.finite_ok(v.translations) FROM modb.clip_versions v"
    ),
    "modb.forward_kinematics(jsonb,real[],real[])": Call(
        rows_of(
            "modb.forward_kinematics(k.hierarchy, v.rotations[1:2], v.translations[1:2])",
            "modb.clip_versions v JOIN modb.skeletons k ON k.id = v.skeleton_id",
        )
    ),
    "modb.frame_key(bigint,integer,boolean)": Call(
        "SELECT modb.frame_key(s.clip_id, s.version, s.mirrored) FROM args a"
        " JOIN modb.snippets s ON s.id = a.snippet"
    ),
    "modb.graph_is_current(bigint)": Call(
        "SELECT modb.graph_is_current(g.id) FROM modb.graphs g WHERE g.kind = 'transitions'"
    ),
    "modb.joint_axes_ok(jsonb,jsonb)": Call(
        "SELECT modb.joint_axes_ok(k.hierarchy, k.joint_axes),"
        " modb.joint_axes_ok(k.hierarchy, a.bad_joint_axes) FROM modb.skeletons k, args a"
    ),
    "modb.joint_axes_problem(jsonb,jsonb)": Call(
        "SELECT modb.joint_axes_problem(k.hierarchy, a.bad_joint_axes),"
        " modb.joint_axes_problem(k.hierarchy, k.joint_axes) FROM modb.skeletons k, args a"
    ),
    "modb.joint_map_ok(jsonb,jsonb)": Call(
        "SELECT modb.joint_map_ok(k.hierarchy, k.joint_map) FROM modb.skeletons k"
    ),
    "modb.local_to_world(double precision[],double precision,double precision[])": Call(
        "SELECT modb.local_to_world(a.position, a.heading, a.target) FROM args a"
    ),
    "modb.match_box(cube,modb.match_plan,double precision)": Call(
        "SELECT modb.match_box(s.begin_features, modb.match_plan(a.profile), a.scale)::text"
        " FROM args a JOIN modb.snippets s ON s.id = a.snippet"
    ),
    "modb.match_knobs()": Call(planned_in_worker("modb.match_knobs()")),
    "modb.match_plan(text)": Call("SELECT modb.match_plan(a.profile)::text FROM args a"),
    "modb.max_joint_angle(real[],real[],integer[])": Call(
        f"SELECT modb.max_joint_angle(e.rotations, b.rotations, a.joint_indices) FROM {ENDS}"
    ),
    "modb.mirror_pairs_ok(jsonb,jsonb)": Call(
        "SELECT modb.mirror_pairs_ok(k.hierarchy, k.mirror_pairs) FROM modb.skeletons k"
    ),
    "modb.model_document_problems(jsonb)": Call(
        # a stored model is sound (no problem); with fps 0, one
        "SELECT modb.model_document_problems(m.data),"
        " modb.model_document_problems(jsonb_set(m.data, '{fps}', '0'))"
        " FROM modb.models m WHERE m.kind = 'motion_primitive'"
    ),
    "modb.model_mixture_md5(jsonb)": Call(
        "SELECT modb.model_mixture_md5(m.data) FROM modb.models m WHERE m.kind = 'motion_primitive'"
    ),
    "modb.tree_shape(jsonb)": Call(
        "SELECT modb.tree_shape(m.meta) FROM modb.models m WHERE m.kind = 'motion_primitive'"
    ),
    "modb.model_graph_problem(jsonb,bigint)": Call(
        # the stored graph is sound (NULL); without its transitions, a node no transition reaches
        "SELECT modb.model_graph_problem(g.data, g.skeleton_id) IS NULL,"
        " modb.model_graph_problem(g.data - 'transitions', g.skeleton_id)"
        " FROM modb.graphs g WHERE g.kind = 'models'"
    ),
    "modb.quat_angle(double precision,double precision,double precision,double precision,"
    "double precision,double precision,double precision,double precision)": Call(
        "SELECT modb.quat_angle(a.q1[1], a.q1[2], a.q1[3], a.q1[4], a.q2[1], a.q2[2], a.q2[3],"
        " a.q2[4]) FROM args a"
    ),
    "modb.quat_angle(double precision[],double precision[])": Call(
        "SELECT modb.quat_angle(a.q1, a.q2) FROM args a"
    ),
    "modb.raise_in_words(text,text,text,text)": Call(
        "SELECT modb.raise_in_words(a.message, a.error_state, a.detail, a.hint) FROM args a",
        raises="no snippet 0",
    ),
    "modb.rest_speed()": Call(planned_in_worker("modb.rest_speed()")),
    "modb.select_next_snippet(bigint,double precision[],text,text,bigint[])": Call(
        rows_of("modb.select_next_snippet(a.snippet, a.target, a.profile, a.collection, a.exclude)")
    ),
    "modb.select_next_snippet_world(bigint,double precision[],double precision,"
    "double precision[],text,text,bigint[])": Call(
        rows_of(f"modb.select_next_snippet_world({WORLD})")
    ),
    "modb.select_next_snippets(bigint,double precision[],integer,text,text,bigint[])": Call(
        rows_of(
            "modb.select_next_snippets(a.snippet, a.target, a.k, a.profile,"
            " a.collection, a.exclude)"
        )
    ),
    "modb.select_next_snippets_reference(bigint,double precision[],integer,text,text,"
    "bigint[])": Call(
        rows_of(
            "modb.select_next_snippets_reference(a.snippet, a.target, a.k,"
            " a.profile, a.collection, a.exclude)"
        )
    ),
    "modb.select_snippet_ending(bigint,double precision[],double precision,double precision[],"
    "text,text,bigint[],boolean)": Call(
        rows_of(f"modb.select_snippet_ending({WORLD}, a.standing)")
    ),
    "modb.select_snippet_ending_reference(bigint,double precision[],double precision,"
    "double precision[],text,text,bigint[],boolean)": Call(
        rows_of(f"modb.select_snippet_ending_reference({WORLD}, a.standing)")
    ),
    "modb.select_synthesis_step(bigint,double precision[],double precision,double precision[],"
    "text,text,bigint[],boolean)": Call(rows_of(f"modb.select_synthesis_step({WORLD}, a.resting)")),
    "modb.session_settings()": Call(
        "SELECT modb.session_settings() FROM args a", setting="SET modb.heading_weight = '0.5'"
    ),
    "modb.skeleton_identity(jsonb)": Call(
        "SELECT modb.skeleton_identity(k.hierarchy) FROM modb.skeletons k"
    ),
    "modb.skeleton_joint_names(jsonb)": Call(
        "SELECT modb.skeleton_joint_names(k.hierarchy) FROM modb.skeletons k"
    ),
    "modb.skeleton_pose_key(jsonb)": Call(
        "SELECT modb.skeleton_pose_key(k.hierarchy) FROM modb.skeletons k"
    ),
    "modb.snippet_pools()": Call(rows_of("modb.snippet_pools()")),
    "modb.snippets_ending_within(bigint,double precision[],double precision,double precision[],"
    "text,text,bigint[],boolean,double precision)": Call(
        rows_of(f"modb.snippets_ending_within({WORLD}, a.standing, a.scale)")
    ),
    "modb.standard_joints()": Call(planned_in_worker("modb.standard_joints()")),
    "modb.synthesis_chain(double precision[],integer,bigint,double precision[],double precision,"
    "text,text,double precision,double precision,boolean)": Call(
        rows_of(
            "modb.synthesis_chain(a.targets, a.k, a.snippet, a.position,"
            " a.heading, a.profile, a.collection, a.radius, a.exclude_seconds, a.resting)"
        )
    ),
    "modb.synthesis_goal(double precision[],integer)": Call(
        "SELECT modb.synthesis_goal(a.targets, a.k - 1) FROM args a"
    ),
    "modb.synthesis_step_end(double precision[],double precision,double precision[],"
    "double precision,double precision[],double precision)": Call(
        rows_of(
            "modb.synthesis_step_end(a.position, a.heading, s.net_translation, s.net_heading,"
            " a.target_world, a.radius)",
            "args a JOIN modb.snippets s ON s.id = a.snippet",
        )
    ),
    "modb.target_cost(double precision[],double precision,double precision[],"
    "double precision)": Call(
        "SELECT modb.target_cost(s.net_translation, s.net_heading, a.target, a.heading_weight)"
        " FROM args a JOIN modb.snippets s ON s.id = a.snippet"
    ),
    "modb.token_grant(bytea)": Call(rows_of("modb.token_grant(a.token_sha256)")),
    "modb.transition_graph_inputs(text,text,double precision)": Call(
        rows_of("modb.transition_graph_inputs(a.new_graph, a.collection, a.min_turn)")
    ),
    "modb.transition_graph_terminators(bigint[])": Call(
        rows_of("modb.transition_graph_terminators(a.terminators)")
    ),
    "modb.transition_key(modb.match_plan)": Call(
        "SELECT modb.transition_key(modb.match_plan(a.profile)) FROM args a"
    ),
    "modb.unit_quaternions_ok(real[],double precision)": Call(
        "SELECT modb.unit_quaternions_ok(v.rotations, a.tolerance)"
        " FROM modb.clip_versions v, args a"
    ),
    "modb.walk_speed()": Call(planned_in_worker("modb.walk_speed()")),
    "modb.weighted_joint_angle(real[],real[],integer[],double precision[])": Call(
        f"SELECT modb.weighted_joint_angle(e.rotations, b.rotations, a.joint_indices, a.weights)"
        f" FROM {ENDS}"
    ),
    "modb.world_positions(bigint,integer)": Call(
        rows_of("modb.world_positions(a.clip, a.version)")
    ),
    "modb.world_to_local(double precision[],double precision,double precision[])": Call(
        "SELECT modb.world_to_local(a.position, a.heading, a.target_world) FROM args a"
    ),
}

# Functions no query can call: GiST support functions take and return `internal` (the index code
# calls them, in the process that writes the index; PostgreSQL 15 builds GiST indexes serially).
NOT_CALLABLE: dict[str, str] = {
    "modb.feature_cube_penalty(internal,internal,internal)": "GiST support: takes internal",
    "modb.feature_cube_picksplit(internal,internal)": "GiST support: takes internal",
}

ARGS = f"""
CREATE TABLE args AS
SELECT t.from_snippet AS snippet, t.next,
       v.clip_id AS clip, v.version, (step->>'start')::int AS step_start,
       (step->>'end')::int - (step->>'start')::int + 1 AS step_frames,
       ARRAY[step->>'name'] AS spec, ARRAY['!' || (step->>'name')] AS spec_excluding,
       ARRAY(SELECT begin_terminator FROM modb.snippets ORDER BY id LIMIT 3) AS terminators,
       '{COLLECTION}'::text AS collection, 'default'::text AS profile,
       'pw_again'::text AS new_graph,
       '{{0.5, 3}}'::float8[] AS target, '{{0.1, 0, -0.2}}'::float8[] AS position,
       0.3::float8 AS heading, '{{1, 4}}'::float8[] AS target_world,
       '{{{{0, 4}}, {{2, 8}}}}'::float8[] AS targets, 3 AS k, '{{}}'::bigint[] AS exclude,
       false AS verbose, false AS standing, false AS resting, 4 AS relax_level,
       0.5::float8 AS radius, 1.0::float8 AS exclude_seconds, 1.5::float8 AS lookahead,
       0.5::float8 AS heading_weight, 2.0::float8 AS scale, 0.0::float8 AS min_turn,
       1e-5::float8 AS tolerance, '{{0, 1, 2}}'::int[] AS joint_indices,
       '{{1, 0.5, 0.25}}'::float8[] AS weights,
       '{{0.9238795, 0.3826834, 0, 0}}'::float8[] AS q1, '{{1, 0, 0, 0}}'::float8[] AS q2,
       'velocity_terms'::text AS knob_boolean, 'on'::text AS on_text,
       'heading_weight'::text AS knob_number, '0.25'::text AS number_text,
       'profile "x"'::text AS origin, 'run, walk, !bow'::text AS spec_text,
       '{{"default": 0.1, "head": 0.2}}'::jsonb AS threshold_spec,
       ARRAY['pelvis', 'head', 'left_wrist'] AS joint_names, ARRAY['pelvis', 'head'] AS included,
       '[{{"op": "trim", "start": 0, "end": 10}}, {{"op": "twirl"}}]'::jsonb AS commands,
       '{{"joints": 1}}'::jsonb AS bad_joint_axes, sha256('a parallel token') AS token_sha256,
       'no snippet 0'::text AS message, '22023'::text AS error_state,
       'a detail'::text AS detail, 'a hint'::text AS hint
  FROM (SELECT t.from_snippet, min(n.id) AS next  -- a successor that does not start where it ends
          FROM modb.graph_transitions t
          JOIN modb.snippets p ON p.id = t.from_snippet
          JOIN modb.snippets n ON n.id = ANY (t.to_snippets)
         WHERE t.cost_to_go IS NOT NULL AND p.future_translation IS NOT NULL
           AND n.begin_terminator <> p.end_terminator
         GROUP BY t.from_snippet ORDER BY t.from_snippet LIMIT 1) t
  JOIN modb.snippets s ON s.id = t.from_snippet
  JOIN modb.clip_versions v ON (v.clip_id, v.version) = (s.clip_id, s.version)
  CROSS JOIN LATERAL (SELECT x FROM jsonb_array_elements(v.meta->'annotations') x
                       ORDER BY (x->>'start')::int LIMIT 1) a(step);

-- runs a query text where it is called: in a worker, a query planned there
CREATE FUNCTION planned_in_worker(query text) RETURNS SETOF text
LANGUAGE plpgsql STABLE PARALLEL SAFE AS $$ BEGIN RETURN QUERY EXECUTE query; END $$;

INSERT INTO modb.access_tokens (name, role, token_sha256)
VALUES ('parallel', 'reader', sha256('a parallel token'));
"""


@pytest.fixture(scope="module")
def dsn(cluster):
    """One Bandai walk with its steps annotated, its snippets, a transition graph over them, a
    model of each step and a graph of the two models; and the arguments in table `args`."""
    walk = mocap("bandai-2-dev", "data", "dataset-2_walk_active_001.bvh")
    with scratch_database(cluster, f"parallel_safety_{os.getpid()}") as dsn:
        for step in (("load", walk, "--collection", COLLECTION, "-q"),
                     ("annotate", "--steps", COLLECTION)):  # fmt: skip
            r = run_modb(dsn, *step)
            assert r.returncode == 0, f"modb {' '.join(map(str, step))}: {r.stderr}"
        # what `modb graph build` and `modb model build|graph` run, here (not as jobs, which poll)
        with connect(dsn) as conn:
            build_here(conn, GRAPH, min_turn_degrees=0.0)
            for side in ("left", "right"):
                build_model(conn, f"pw_{side}_step", COLLECTION, f"{side}_step")
            model_graphs.build(conn, MODEL_GRAPH, COLLECTION, None)
            conn.execute(ARGS)
            assert conn.execute("SELECT count(*) FROM args").fetchone()[0] == 1
        yield dsn


@pytest.fixture(scope="module")
def conn(dsn):
    with psycopg.connect(dsn, autocommit=True) as conn:
        yield conn


def test_every_parallel_safe_function_is_listed(db):
    """CALLS and NOT_CALLABLE name exactly the functions pg_proc labels PARALLEL SAFE, and what
    NOT_CALLABLE names takes `internal`."""
    takes_internal = dict(db.execute(SAFE).fetchall())
    declared, listed = set(takes_internal), set(CALLS) | set(NOT_CALLABLE)
    both = set(CALLS) & set(NOT_CALLABLE)
    problems = (
        [f"declared PARALLEL SAFE, not run in a worker here (add it to CALLS): {sig}"
         for sig in sorted(declared - listed)]
        + [f"listed here, not declared PARALLEL SAFE: {sig}" for sig in sorted(listed - declared)]
        + [f"in both CALLS and NOT_CALLABLE: {sig}" for sig in sorted(both)]
        + [f"in NOT_CALLABLE ({NOT_CALLABLE[sig]}), yet SQL can call it (takes no internal): {sig}"
           for sig in sorted(set(NOT_CALLABLE) & declared) if not takes_internal[sig]]
    )  # fmt: skip
    assert not problems, "\n".join(problems)


GATHER = ("Gather", "Gather Merge")
TRIES = 20  # the cluster's workers (max_parallel_workers) may be busy with other modules' queries


def _in_a_worker(conn, sig: str, sql: str, n_rows: int) -> None:
    """EXPLAIN ANALYZE runs the query until a worker is launched for it; its rows go through the
    Gather on top."""
    for _ in range(TRIES):
        nodes = plan_nodes(conn, sql)
        gathers = [n for n in nodes if n["Node Type"] in GATHER]
        assert gathers, f"{sig}: the planner keeps {sql!r} out of parallel workers (no Gather)"
        if sum(n["Workers Launched"] for n in gathers) >= 1:
            if nodes[0] is gathers[0]:  # force_parallel_mode's Gather on top of the whole query
                assert nodes[0]["Actual Rows"] == n_rows, f"{sig}: other rows in a worker"
            return
        time.sleep(0.25)
    pytest.fail(f"{sig}: no parallel worker was launched for {sql!r} in {TRIES} tries")


def _raised_in_a_worker(conn, sig: str, sql: str) -> psycopg.Error:
    """The error the query raises in a parallel worker (tried until a worker is launched)."""
    for _ in range(TRIES):
        with pytest.raises(psycopg.Error) as raised:
            conn.execute(sql)
        if "parallel worker" in (raised.value.diag.context or ""):
            return raised.value
        time.sleep(0.25)
    pytest.fail(f"{sig}: the error of {sql!r} was not raised in a parallel worker in {TRIES} tries")


@pytest.mark.parametrize("sig", sorted(CALLS), ids=str)
def test_runs_in_a_parallel_worker(conn, sig):
    """The call runs in a parallel worker without error, and answers as in the leader."""
    call = CALLS[sig]
    conn.execute("RESET ALL")
    if call.setting:
        conn.execute(call.setting)
    if call.raises:
        with pytest.raises(psycopg.Error) as in_leader:
            conn.execute(call.sql)
        assert in_leader.value.diag.message_primary == call.raises
        conn.execute("SET force_parallel_mode = on")
        in_worker = _raised_in_a_worker(conn, sig, call.sql)
        assert (in_worker.diag.message_primary, in_worker.sqlstate) == (
            call.raises,
            in_leader.value.sqlstate,
        ), f"{sig} fails otherwise in a worker: {in_worker}"
        return
    leader = conn.execute(call.sql).fetchall()
    assert leader and any(v is not None for v in leader[0]), f"{sig}: nothing to compare"
    conn.execute("SET force_parallel_mode = on")
    try:
        _in_a_worker(conn, sig, call.sql, len(leader))
        worker = conn.execute(call.sql).fetchall()
    except psycopg.Error as e:
        pytest.fail(f"{sig} fails in a parallel worker: {e.diag.message_primary}"
                    f" (context: {e.diag.context})")  # fmt: skip
    assert worker == leader, f"{sig} answers otherwise in a parallel worker"
