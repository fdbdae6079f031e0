-- 0.8.0: the indexed feature cube gains the first two columns of the neck's, head's and wrists' rotation
-- matrices (25 -> 49 dimensions), so select_next_snippet's box bounds their angles as well: the continuity
-- check gets about 30x fewer candidates on real data (BENCHMARKS "Selection at scale").
CREATE OR REPLACE FUNCTION modb.feature_names()
RETURNS text[]
LANGUAGE sql IMMUTABLE PARALLEL SAFE
RETURN {{FEATURES}};
COMMENT ON FUNCTION modb.feature_names() IS
    'The 49 dimensions of the indexed feature cube, in order (metres, m/s, and rotation-matrix entries)';
--@include 72_plan.sql
-- The profile resolved once per selection (it was once per use of the plan in the inlined query).
--@include 76_select.sql

-- The index is built again below, with modb's operator class; dropped first, so that the rewrite does not
-- update it row by row.
DROP INDEX modb.snippets_begin_features_idx;

-- Every stored terminator's new dimensions, from its stored rotations (the kernel computes the same columns
-- from float8 at load; the difference, about 1e-7, is far inside the box's 1e-4 margin). R e_x, then R e_y.
ALTER TABLE modb.terminators DROP CONSTRAINT terminators_features_check;
UPDATE modb.terminators t
   SET features = cube(ARRAY(SELECT cube_ll_coord(t.features, i) FROM generate_series(1, 25) AS i)
                       || ARRAY(SELECT c.v
                                  FROM unnest(ARRAY['neck', 'head', 'left_wrist', 'right_wrist']) WITH ORDINALITY AS j(name, n)
                                 CROSS JOIN LATERAL (SELECT 4 * (array_position(modb.standard_joints(), j.name) - 1) AS o) k
                                 CROSS JOIN LATERAL (SELECT t.rotations[k.o + 1]::float8 AS w, t.rotations[k.o + 2]::float8 AS x,
                                                            t.rotations[k.o + 3]::float8 AS y, t.rotations[k.o + 4]::float8 AS z) q
                                 CROSS JOIN LATERAL unnest(ARRAY[1 - 2 * (q.y * q.y + q.z * q.z), 2 * (q.x * q.y + q.w * q.z),
                                                                 2 * (q.x * q.z - q.w * q.y), 2 * (q.x * q.y - q.w * q.z),
                                                                 1 - 2 * (q.x * q.x + q.z * q.z), 2 * (q.y * q.z + q.w * q.x)])
                                       WITH ORDINALITY AS c(v, m)
                                 ORDER BY j.n, c.m));
ALTER TABLE modb.terminators ADD CONSTRAINT terminators_features_check CHECK (cube_dim(features) = 49);
COMMENT ON COLUMN modb.terminators.features IS
    'The indexed feature vector, physical units: modb.feature_names() lists its 49 dimensions';
UPDATE modb.snippets s SET begin_features = t.features FROM modb.terminators t WHERE t.id = s.begin_terminator;
--@include 70_snippets_index.sql
-- The new index holds the old 25-dimension entries of the rows just rewritten as well (dead, but they
-- widen its pages' bounds until rebuilt), and an extension script cannot VACUUM: the DBA finishes the job (a WARNING:
-- extension scripts run with client_min_messages at WARNING).
DO $$ BEGIN
    RAISE WARNING 'modb 0.8.0: the feature cube has 49 dimensions now; for selection at full speed run '
                 '"VACUUM ANALYZE modb.snippets, modb.terminators" and then '
                 '"REINDEX INDEX CONCURRENTLY modb.snippets_begin_features_idx" (results are right meanwhile)';
END $$;
