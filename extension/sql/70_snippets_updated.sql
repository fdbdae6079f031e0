-- The trigger function behind snippets_blocks_update (71_snippet_blocks.sql): an update of what a block
-- holds adds a block for the new values; the old block keeps naming the snippet, whose exact values are
-- read again at every selection. A snippet in two blocks has no trusted objective inputs (src/
-- block_directory.c), so an edit of them after its futures were filled adds a block too; filling them
-- (modb.fill_futures, from NULL) does not: the block's NaN says they were not known.
CREATE OR REPLACE FUNCTION modb.snippets_updated()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
BEGIN
    PERFORM modb.add_snippet_blocks(ARRAY(
        SELECT n.id FROM new_rows n JOIN old_rows o ON o.id = n.id
         WHERE (n.begin_features, n.pose_key, n.fps, n.collection_id, n.clip_id, n.version, n.mirrored)
               IS DISTINCT FROM (o.begin_features, o.pose_key, o.fps, o.collection_id, o.clip_id, o.version, o.mirrored)
            OR (o.future_heading IS NOT NULL
                AND (n.net_translation, n.future_translation, n.future_heading)
                    IS DISTINCT FROM (o.net_translation, o.future_translation, o.future_heading))));
    RETURN NULL;
END
$$;
COMMENT ON FUNCTION modb.snippets_updated() IS
    'Trigger: blocks for snippets whose features, pose, rate, collection or source an UPDATE changed, or their objective''s inputs once filled';
