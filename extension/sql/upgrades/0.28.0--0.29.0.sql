-- 0.29.0: no stall on the synthesis path (issue 61).
-- modb.library_version() says which modb.so a session runs: where the server preloads it
-- (shared_preload_libraries, which shares the block directory and the resolved match plans between
-- sessions), the one loaded when the server started. This update needs 0.29.0's: with an older one it
-- stops here, changing nothing, and says to restart the server.
--@include 01_library.sql

-- Coming to rest and setting off: each snippet block gains end_bounds (the net translations' {x, z}
-- bounds of its snippets that end standing, and of those that end walking), which the block directory
-- holds, so that modb.select_snippet_ending passes over the blocks with no snippet ending as asked without
-- reading them. The update adds the column and the directory index's copy of it in seconds; the blocks it
-- finds have none (NULL) and are all read until modb.pack_snippet_blocks derives them again, which
-- `modb db start` does for the embedded database and a load does for the poses it packs.
ALTER TABLE modb.snippet_blocks ADD COLUMN end_bounds real[];
COMMENT ON COLUMN modb.snippet_blocks.end_bounds IS
    'The {x, z} bounds of the net translations of the block''s snippets that end standing (end speed below modb.rest_speed(); x low, z low, x high, z high; NaN: none), then of those that end walking (at least modb.walk_speed()): coming to rest and setting off pass over a block without such snippets unread and rank the others by them (0.29.0; NULL in a block written before)';
DROP INDEX modb.snippet_blocks_directory_idx;
CREATE INDEX snippet_blocks_directory_idx ON modb.snippet_blocks (pose_key, fps, pack_order)
    INCLUDE (low, high, input_bounds, end_bounds);

-- A selection that names a collection (or a graph) passes over the candidates outside it when their block
-- is read, from the collection's snippet ids read once per session and generation by this index.
CREATE INDEX snippets_collection_idx ON modb.snippets (collection_id, id);

-- The rule of coming to rest and setting off (modb.snippets_ending_within) puts a candidate at the least
-- level L whose scale 2^L its ratio is within, compared as float8 as the scale is.
--@include 89_synthesis.sql

-- Motion models prepared once per server process (issue 62): what a session's backend holds.
--@include 96a_prepared_models.sql

-- Actions in graphs of models (issue 63): a node may be of type action, and synthesis takes actions (the
-- old signature of modb.synthesize_from_models dropped: the new one's last argument has a default).
--@include 94_model_graph_problem.sql
DROP FUNCTION modb.synthesize_from_models(text, float8[], float8, int, float8);
DROP FUNCTION modb._synthesize_from_models(text, float8[], float8, int, float8);
--@include 96b_synthesis_from_models.sql

-- What to run next, where it is seen (an extension script shows WARNINGs, not NOTICEs).
DO $$
BEGIN
    IF EXISTS (SELECT FROM modb.snippet_blocks) THEN
        RAISE WARNING 'modb 0.29.0: the snippet blocks have no end bounds yet; coming to rest and setting off read more blocks until they are derived again'
            USING HINT = 'Run SELECT * FROM modb.pack_snippet_blocks(0); once (it runs beside live selections: about 30 s a million snippets). modb db start does it by itself.';
    END IF;
END
$$;

-- Action primitives found automatically (issue 63): modb.annotate_action.
--@include 88a_action_annotations.sql
