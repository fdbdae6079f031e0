-- The GiST index of the feature cube: contrib/cube's support functions with modb's penalty and split
-- (src/cube_gist.c: cube's volume-based ones degenerate in 49 dimensions and the selection's box overlapped
-- most of the index's pages). Every operator of cube's own class, so any cube query can use the index.

CREATE FUNCTION modb.feature_cube_penalty(internal, internal, internal)
RETURNS internal
LANGUAGE c IMMUTABLE STRICT PARALLEL SAFE
AS 'MODULE_PATHNAME', 'modb_cube_penalty';
COMMENT ON FUNCTION modb.feature_cube_penalty(internal, internal, internal) IS
    'GiST support (modb.cube_feature_ops): the growth of a page''s sum of extents, not of its volume, to take in an entry';

CREATE FUNCTION modb.feature_cube_picksplit(internal, internal)
RETURNS internal
LANGUAGE c IMMUTABLE STRICT PARALLEL SAFE
AS 'MODULE_PATHNAME', 'modb_cube_picksplit';
COMMENT ON FUNCTION modb.feature_cube_picksplit(internal, internal) IS
    'GiST support (modb.cube_feature_ops): the R*-tree''s split, with sums of extents in place of volumes';

CREATE OPERATOR CLASS modb.cube_feature_ops FOR TYPE cube USING gist AS
    OPERATOR 3 &&,
    OPERATOR 6 =,
    OPERATOR 7 @>,
    OPERATOR 8 <@,
    OPERATOR 15 ~> (cube, int) FOR ORDER BY float_ops,
    OPERATOR 16 <#> (cube, cube) FOR ORDER BY float_ops,
    OPERATOR 17 <-> (cube, cube) FOR ORDER BY float_ops,
    OPERATOR 18 <=> (cube, cube) FOR ORDER BY float_ops,
    FUNCTION 1 g_cube_consistent (internal, cube, smallint, oid, internal),
    FUNCTION 2 g_cube_union (internal, internal),
    FUNCTION 5 modb.feature_cube_penalty (internal, internal, internal),
    FUNCTION 6 modb.feature_cube_picksplit (internal, internal),
    FUNCTION 7 g_cube_same (cube, cube, internal),
    FUNCTION 8 g_cube_distance (internal, cube, smallint, oid, internal);
COMMENT ON OPERATOR CLASS modb.cube_feature_ops USING gist IS
    'GiST for snippet feature cubes: cube''s operators and search, a penalty and split that stay selective in 49 dimensions';

CREATE INDEX snippets_begin_features_idx ON modb.snippets USING gist (begin_features modb.cube_feature_ops);
