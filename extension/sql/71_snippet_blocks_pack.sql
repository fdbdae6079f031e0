-- Packing the snippet blocks of a pose and rate (src/pack_blocks.c): the loader calls it after a load
-- that left enough of a pose's snippets in blocks of consecutive ones.
CREATE FUNCTION modb.pack_snippet_blocks(min_unpacked_share float8 DEFAULT 0)
RETURNS TABLE (pose_key text, fps float8, snippets bigint, blocks int, seconds float8)
LANGUAGE c VOLATILE STRICT PARALLEL UNSAFE
AS 'MODULE_PATHNAME', 'modb_pack_snippet_blocks';
COMMENT ON FUNCTION modb.pack_snippet_blocks(float8) IS
    'Re-cuts the snippet blocks of each pose and rate whose share of snippets in blocks of consecutive ones (as loaded) is at least min_unpacked_share (0: every pose, again) into blocks of snippets near each other in feature space (a k-d split in units of the default profile''s box), which select_next_snippets'' box search meets less often; one row per pose and rate packed. Waits for, and holds off, other writers of blocks';

REVOKE EXECUTE ON FUNCTION modb.pack_snippet_blocks(float8) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.pack_snippet_blocks(float8) TO modb_loader;
GRANT DELETE ON modb.snippet_blocks TO modb_loader;
