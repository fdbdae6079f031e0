-- 0.11.0: packed snippet blocks. A block may hold snippets of several clip sources of one pose and rate
-- (no clip source then, and its place in the packing), modb.pack_snippet_blocks makes them, blocks hold
-- their snippets' objective inputs, and the block directory keeps 16-bit bounds (src/block_directory.c:
-- nothing to create in SQL). The blocks 0.10.0 made hold no objective inputs: pack them
-- (modb.pack_snippet_blocks(), which `modb db start` and the next load run).
ALTER TABLE modb.snippet_blocks
    ALTER COLUMN clip_id DROP NOT NULL,
    ALTER COLUMN version DROP NOT NULL,
    ALTER COLUMN mirrored DROP NOT NULL,
    ALTER COLUMN collection_id DROP NOT NULL,
    ADD COLUMN pack_order int,
    ADD COLUMN objective_inputs real[],
    ADD CONSTRAINT snippet_blocks_source_check CHECK (pack_order IS NOT NULL OR (clip_id IS NOT NULL
        AND version IS NOT NULL AND mirrored IS NOT NULL AND collection_id IS NOT NULL));
COMMENT ON TABLE modb.snippet_blocks IS
    'Up to 32 snippets of one pose and rate: consecutive ones of a clip source (as loaded) or packed ones near each other (pack_order set); the bounds of their begin features and each one''s 8-bit code within them; select_next_snippets'' box search (kept by triggers on modb.snippets)';
COMMENT ON COLUMN modb.snippet_blocks.objective_inputs IS
    'Per snippet, what its objective is computed from, as float4: net_translation (3), future_translation (3), future_heading; NaN for NULL. A call reads candidates in the order of the least objective these allow and stops when none left can make the answer';
COMMENT ON COLUMN modb.snippet_blocks.pack_order IS
    'The block''s place in its pose''s packing (modb.pack_snippet_blocks), NULL for a block of consecutive snippets of the clip source named by clip_id, version, mirrored and collection_id (NULL in a packed block)';
--@include 70_snippets_updated.sql
--@include 71_snippet_blocks_pack.sql
