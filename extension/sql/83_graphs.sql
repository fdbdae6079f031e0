-- Transition graphs: which snippets a chain can keep moving and steering among (modb_kernel/transitions.py
-- says why).
-- A graph is a modb.graphs row (kind 'transitions': how it was built and what it holds, in jsonb) and
-- its snippets in modb.graph_snippets, which select_next_snippet reads when the `graph` knob names it.

CREATE TABLE modb.graph_snippets (
    graph_id   bigint NOT NULL REFERENCES modb.graphs (id) ON DELETE CASCADE,
    snippet_id bigint NOT NULL REFERENCES modb.snippets (id) ON DELETE CASCADE,
    PRIMARY KEY (graph_id, snippet_id)
);
COMMENT ON TABLE modb.graph_snippets IS
    'The snippets a transition graph keeps (its largest strongly connected component that turns both ways): with SET modb.graph = ''<name>'' (or "graph" in a profile) select_next_snippet chooses among these only';
CREATE INDEX graph_snippets_snippet_idx ON modb.graph_snippets (snippet_id);  -- for ON DELETE CASCADE
SELECT pg_catalog.pg_extension_config_dump('modb.graph_snippets', '');

CREATE OR REPLACE FUNCTION modb.build_transition_graph(name text, profile text DEFAULT 'default',
                                                       collection text DEFAULT NULL, min_turn_degrees float8 DEFAULT 45)
RETURNS bigint
LANGUAGE plpython3u VOLATILE PARALLEL UNSAFE
AS $py$
#@modb_kernel
import json
import numpy as np

T = kernel.transitions
TRANSITION_SLACK = 1e-9
if not name:
    plpy.error("a transition graph needs a name")
if name.strip().lower() in ("none", "profile"):
    plpy.error(f'"{name}" cannot name a graph: SET modb.graph = \'{name.strip().lower()}\' means '
               + ("no graph" if name.strip().lower() == "none" else "the profile's graph"),
               hint="choose another name")
if min_turn_degrees is None or not 0 <= min_turn_degrees <= 180:
    plpy.error(f"min_turn_degrees must be between 0 and 180, got {min_turn_degrees}")
plan = plpy.execute(plpy.prepare(
    """SELECT to_jsonb(p) - 'box_half_width' AS shown, modb.transition_key(p) AS transition_key, p.*
         FROM modb.match_plan($1) p""", ["text"]), [profile])[0]
collections = None
if collection is not None:
    collections = plpy.execute(plpy.prepare("SELECT modb.collection_subtree($1) AS ids", ["text"]), [collection])[0]["ids"]
    if not collections:
        plpy.error(f'no collection "{collection}"', hint="modb.collection_path(id) names the stored ones")
snippets = plpy.execute(plpy.prepare(
    """SELECT s.id, s.begin_terminator, s.end_terminator, s.pose_key || '@' || s.fps AS grp, s.future_heading,
              s.clip_id || '/' || s.version || '/' || s.mirrored AS clip, s.first_frame, s.n_frames,
              s.net_translation[1] AS net_x, s.net_translation[3] AS net_z, s.net_heading, (s.n_frames - 1) / s.fps AS duration
         FROM modb.snippets s WHERE $1::bigint[] IS NULL OR s.collection_id = ANY ($1) ORDER BY s.id""",
    ["bigint[]"]), [collections])
n = len(snippets)
if n == 0:
    plpy.error("no snippets to build a graph from" + (f' in collection "{collection}"' if collection else ""),
               hint="`modb load` builds snippets")
plpy.notice(f"modb: transition graph \"{name}\": reading the terminators of {n} snippets")
column = lambda key: [r[key] for r in snippets]
terminators = plpy.execute(plpy.prepare(  # those of the snippets just read, each once
    """SELECT t.id, t.positions, t.rotations, t.velocities, t.angular_velocities,
              (SELECT array_agg(cube_ll_coord(t.features, i) ORDER BY i) FROM generate_series(1, cube_dim(t.features)) i) AS features
         FROM modb.terminators t WHERE t.id = ANY ($1)""", ["bigint[]"]),
    [sorted(set(column("begin_terminator")) | set(column("end_terminator")))])
row_of = {r["id"]: i for i, r in enumerate(terminators)}
term = T.Terminators(*([r[c] for r in terminators] for c in
                       ("positions", "rotations", "velocities", "angular_velocities", "features")))
keys = lambda values: np.unique(values, return_inverse=True)[1]
begin = np.array([row_of[t] for t in column("begin_terminator")])
end = np.array([row_of[t] for t in column("end_terminator")])
group, clip = keys(column("grp")), keys(column("clip"))
first_frame, n_frames = np.array(column("first_frame")), np.array(column("n_frames"))
# A hair looser than level 0, so the stored transitions hold every pair the SQL test passes (numpy and
# SQL round differently); selection applies the exact test again.
thresholds = {k: np.array(plan[k], dtype=np.float64) * (1 + TRANSITION_SLACK) for k in
              ("position_threshold", "angle_threshold", "velocity_threshold", "angular_velocity_threshold")}
spec = dict(thresholds, joints=list(plan["joints"]), norm=plan["norm"], velocity_terms=plan["velocity_terms"],
            box_half_width=plan["box_half_width"])
src, dst, ratio = T.edges(term, begin, end, group, clip, first_frame, n_frames, spec,
                   progress=lambda done: plpy.notice(f"modb: transition graph \"{name}\": {done}/{n} snippets"))
turn = np.array([np.nan if t is None else t for t in column("future_heading")], dtype=np.float64)
keep = T.steerable(n, src, dst, group, np.nan_to_num(turn), np.radians(min_turn_degrees))
ids = np.array(column("id"), dtype=np.int64)
out_degree = np.bincount(src, minlength=n)
inside = keep[src] & keep[dst]
# The cost-to-go among the kept snippets (modb_kernel/cost_to_go.py), priced beyond its grid at their median speed.
C = kernel.cost_to_go
kept = np.flatnonzero(keep)
if not len(kept):
    plpy.error(f'transition graph "{name}": no set of these {n} snippets can keep walking and turn '
               f'{min_turn_degrees:g} degrees each way',
               hint="load more varied motion (turns, both ways), or pass a smaller min_turn_degrees")
position = np.full(n, -1)
position[kept] = np.arange(len(kept))
net_x, net_z, heading, duration = (np.array(column(c), dtype=np.float64)[kept] for c in ("net_x", "net_z", "net_heading", "duration"))
grid = C.Grid(speed=max(float(np.median(np.hypot(net_x, net_z) / duration)), C.MIN_SPEED))
plpy.notice(f"modb: transition graph \"{name}\": cost-to-go of {len(kept)} snippets on {grid.angles} x {grid.rings} goal positions")
seconds_per_ratio = (plan["continuity_weight"] or 0) / grid.speed  # the selection's price of a rough seam
seam = ratio[inside] * seconds_per_ratio
costs, iterations, change = C.cost_to_go(
    grid, net_x, net_z, heading, duration, position[src[inside]], position[dst[inside]], seam,
    progress=lambda i, c: i % 10 or plpy.notice(f"modb: transition graph \"{name}\": cost-to-go iteration {i}, largest change {c:.3f} s"))
data = {"profile": profile, "collection": collection, "min_turn_degrees": min_turn_degrees,
        "plan": json.loads(plan["shown"]),
        "snippets": n, "edges": int(len(src)), "kept": int(keep.sum()),
        "dead_ends": int((out_degree == 0).sum()),
        "edges_within_kept": int(inside.sum()), "transition_key": json.loads(plan["transition_key"]),
        "cost_to_go": dict(grid.as_json(), seconds_per_ratio=seconds_per_ratio, iterations=iterations,
                           last_change=change)}
# The old graph goes with its name (92_graph_names.sql), its rows with it.
plpy.execute(plpy.prepare("DELETE FROM modb.graph_names WHERE name = $1 AND kind = 'transitions'", ["text"]), [name])
plpy.execute(plpy.prepare("INSERT INTO modb.graph_names (name, kind) VALUES ($1, 'transitions')", ["text"]), [name])
graph_id = plpy.execute(plpy.prepare(
    "INSERT INTO modb.graphs (name, kind, data) VALUES ($1, 'transitions', $2::jsonb) RETURNING id",
    ["text", "text"]), [name, json.dumps(data)])[0]["id"]
plpy.execute(plpy.prepare(
    "INSERT INTO modb.graph_snippets (graph_id, snippet_id) SELECT $1, unnest($2::bigint[])", ["bigint", "bigint[]"]),
    [graph_id, ids[keep].tolist()])
plpy.execute(plpy.prepare(  # one row per kept snippet: its successors, and row k of the costs for the k-th
    """INSERT INTO modb.graph_transitions (graph_id, from_snippet, to_snippets, cost_to_go)
       SELECT $1, e.f, e.t, $5[(k.i - 1) * $6 + 1 : k.i * $6]
         FROM (SELECT f, array_agg(t ORDER BY t) AS t FROM unnest($2::bigint[], $3::bigint[]) AS e(f, t) GROUP BY f) e
         JOIN unnest($4::bigint[]) WITH ORDINALITY AS k(id, i) ON k.id = e.f""",
    ["bigint", "bigint[]", "bigint[]", "bigint[]", "real[]", "int"]),
    [graph_id, ids[src[inside]].tolist(), ids[dst[inside]].tolist(), ids[kept].tolist(), costs.ravel().tolist(),
     grid.angles * grid.rings])
plpy.notice(f"modb: transition graph \"{name}\": kept {data['kept']} of {n} snippets "
            f"({data['edges']} transitions, {data['dead_ends']} snippets with none); "
            f"cost-to-go after {iterations} iterations (last change {change:.3f} s)")
return graph_id
$py$;
COMMENT ON FUNCTION modb.build_transition_graph(text, text, text, float8) IS
    'Builds (or rebuilds) the transition graph "name" over the snippets (of the collection): edges are relaxation level 0 of the profile; a snippet is kept when it lies in the largest strongly connected component (per skeleton and rate) among those holding turns of at least min_turn_degrees each way (where snippets lead: future_heading), so a chain restricted to it (SET modb.graph) never runs into a dead end and can face any goal; stores each kept snippet''s level-0 successors and its cost-to-go (seconds to goals around its end through the graph); returns the modb.graphs id. Rebuild after loading';

-- A transition graph's level-0 transitions, stored. From a kept snippet, select_next_snippet reads its
-- successors here (one index lookup, then the exact check of a few dozen rows) instead of searching the
-- feature box (which admits hundreds to thousands of candidates in dense data, each checked exactly).
-- Valid only for the continuity settings the graph was built with: modb.transition_key says which.

CREATE TABLE modb.graph_transitions (
    graph_id     bigint NOT NULL,
    from_snippet bigint NOT NULL,
    to_snippets  bigint[] NOT NULL,
    cost_to_go   real[],
    PRIMARY KEY (graph_id, from_snippet),
    FOREIGN KEY (graph_id, from_snippet) REFERENCES modb.graph_snippets ON DELETE CASCADE
);
COMMENT ON TABLE modb.graph_transitions IS
    'For each snippet a transition graph keeps: the kept snippets that may follow it at relaxation level 0 (a superset by a hair: the exact test runs again at selection). One row per snippet, not per transition: a tenth of the size';
SELECT pg_catalog.pg_extension_config_dump('modb.graph_transitions', '');

CREATE OR REPLACE FUNCTION modb.transition_key(plan modb.match_plan)
RETURNS jsonb
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
-- The settings that decide which transitions pass level 0; the objective's weights do not.
RETURN jsonb_build_object('joints', (plan).joints, 'norm', (plan).norm, 'velocity_terms', (plan).velocity_terms,
                          'position_threshold', (plan).position_threshold, 'angle_threshold', (plan).angle_threshold,
                          'velocity_threshold', (plan).velocity_threshold,
                          'angular_velocity_threshold', (plan).angular_velocity_threshold);
COMMENT ON FUNCTION modb.transition_key(modb.match_plan) IS
    'What a plan''s level-0 test depends on (joints, norm, velocity terms, thresholds): a graph''s stored transitions serve the plans with its key';

-- Graph names, in a table no selection reads: a graph is deleted by deleting its name here, and its
-- modb.graphs row, stored snippets and transitions go with it (ON DELETE CASCADE, run as the owner). So the
-- loader needs no DELETE on modb.graphs, which every selection reads (a DELETE grant would also let it LOCK
-- that table against every reader).
CREATE TABLE modb.graph_names (
    name text NOT NULL,
    kind text NOT NULL,
    PRIMARY KEY (name, kind)
);
COMMENT ON TABLE modb.graph_names IS
    'The name and kind of every graph in modb.graphs: deleting a row here deletes that graph with its rows';
INSERT INTO modb.graph_names (name, kind) SELECT name, kind FROM modb.graphs;  -- on update: the graphs so far
ALTER TABLE modb.graphs ADD FOREIGN KEY (name, kind) REFERENCES modb.graph_names ON DELETE CASCADE;
SELECT pg_catalog.pg_extension_config_dump('modb.graph_names', '');

GRANT SELECT ON modb.graph_names TO modb_reader;
GRANT INSERT, DELETE ON modb.graph_names TO modb_loader;
GRANT INSERT (name, kind, skeleton_id, data, meta) ON modb.graphs TO modb_loader;
GRANT UPDATE (skeleton_id, data, meta) ON modb.graphs TO modb_loader;
