-- Snippet blocks: the begin features of up to 32 snippets of one pose and rate as 8-bit codes within the
-- block's bounds (src/snippet_blocks.c). select_next_snippets finds a box's candidates by testing each
-- block's bounds (kept per session in memory: src/block_directory.c) and then the codes of the blocks that
-- meet the box, where the GiST index visits a few percent of its pages whatever the box (BENCHMARKS.md
-- "Selection at scale"). A load adds blocks of consecutive snippets of a clip source;
-- modb.pack_snippet_blocks (below) re-cuts a pose's blocks into ones of snippets near
-- each other in feature space, which are tighter. A block is a superset: every candidate is checked on its
-- exact features again.
-- Derived from modb.snippets by triggers in the same transaction, so a block is visible exactly when its
-- snippets are (any snapshot, a standby, the loader's own uncommitted rows); not dumped: a restore's
-- COPY into modb.snippets builds them again.

CREATE TABLE modb.snippet_blocks (
    clip_id       bigint,
    version       int,
    mirrored      boolean,
    pose_key      text NOT NULL,
    fps           float8 NOT NULL,
    collection_id bigint,
    snippets      bigint[] NOT NULL CHECK (array_length(snippets, 1) BETWEEN 1 AND 32),
    low           real[] NOT NULL,
    high          real[] NOT NULL,
    codes         bytea NOT NULL,
    FOREIGN KEY (clip_id, version, mirrored) REFERENCES modb.snippet_sources ON DELETE CASCADE,
    pack_order    int,
    objective_inputs real[],
    term_bounds   bytea,
    term_codes    bytea,
    input_bounds  real[],
    end_speeds    real[],
    end_bounds    real[],
    CONSTRAINT snippet_blocks_source_check CHECK (pack_order IS NOT NULL OR (clip_id IS NOT NULL
        AND version IS NOT NULL AND mirrored IS NOT NULL AND collection_id IS NOT NULL))
) WITH (toast_tuple_target = 8160);  -- a block (about 7.9 kB, one a page) stays uncompressed
COMMENT ON TABLE modb.snippet_blocks IS
    'Up to 32 snippets of one pose and rate: consecutive ones of a clip source (as loaded) or packed ones near each other (pack_order set); the bounds of their begin features and each one''s 8-bit code within them, and of every term of the continuity ratio (term_bounds, term_codes); select_next_snippets'' box search (kept by triggers on modb.snippets)';
COMMENT ON COLUMN modb.snippet_blocks.objective_inputs IS
    'Per snippet, what its objective is computed from, as float4: net_translation (3), future_translation (3), future_heading; NaN for NULL. A call reads candidates in the order of the least objective these allow and stops when none left can make the answer';
COMMENT ON COLUMN modb.snippet_blocks.pack_order IS
    'The block''s place in its pose''s packing (modb.pack_snippet_blocks), NULL for a block of consecutive snippets of the clip source named by clip_id, version, mirrored and collection_id (NULL in a packed block)';
COMMENT ON COLUMN modb.snippet_blocks.term_bounds IS
    'Every term of the continuity ratio bounded (0.18.0, src/term_codes.c): per joint and kind (position, rotation as the x, y, z of the quaternion with w >= 0, velocity, angular velocity) and axis, the bounds of the block''s begin terminators as 16-bit codes on a fixed scale per kind (0: unbounded below, 65535: above), all low codes then all high ones; NULL in a block written before 0.18.0';
COMMENT ON COLUMN modb.snippet_blocks.term_codes IS
    'Per snippet, each term component''s 4-bit code within term_bounds (two a byte): select_next_snippets rejects a block or a candidate whose continuity ratio cannot be within the level from these, without reading its rows';
COMMENT ON COLUMN modb.snippet_blocks.codes IS
    'snippets x features bytes: floor((feature - low) / ((high - low) / 255)), clamped to 0..255';
COMMENT ON COLUMN modb.snippet_blocks.input_bounds IS
    'The least of each objective input over the block''s snippets (as in objective_inputs), then the greatest of each; NULL where one is not known: the block directory ranks blocks by the least objective they allow (0.18.0)';
COMMENT ON COLUMN modb.snippet_blocks.end_speeds IS
    'Per snippet, its pelvis'' ground speed at its end (float4, as coming to rest computes it): coming to rest and setting off (modb.select_snippet_ending) pass over the snippets that cannot end as wanted without reading them (0.18.0)';
COMMENT ON COLUMN modb.snippet_blocks.end_bounds IS
    'The {x, z} bounds of the net translations of the block''s snippets that end standing (end speed below modb.rest_speed(); x low, z low, x high, z high; NaN: none), then of those that end walking (at least modb.walk_speed()): coming to rest and setting off pass over a block without such snippets unread and rank the others by them (0.29.0; NULL in a block written before)';
CREATE INDEX snippet_blocks_source_idx ON modb.snippet_blocks (clip_id, version, mirrored);  -- ON DELETE CASCADE
-- What a session's block directory holds (src/block_directory.c), read by an index-only scan of narrow
-- tuples instead of a sequential scan of the blocks (about 8 kB each).
CREATE INDEX snippet_blocks_directory_idx ON modb.snippet_blocks (pose_key, fps, pack_order)
    INCLUDE (low, high, input_bounds, end_bounds);

-- BEFORE (0.17.0): a writer takes the generation row before it locks any block, the order
-- modb.pack_snippet_blocks takes them in, so a packing and a write (a delete of a clip's old blocks by
-- cascade) cannot each hold what the other waits for. The new number is seen with the rows, at commit.
CREATE TRIGGER snippet_blocks_generation BEFORE INSERT OR UPDATE OR DELETE OR TRUNCATE ON modb.snippet_blocks
    FOR EACH STATEMENT EXECUTE FUNCTION modb.next_generation('snippet_blocks');

CREATE FUNCTION modb.add_snippet_blocks(snippet_ids bigint[])
RETURNS int
LANGUAGE c VOLATILE STRICT PARALLEL UNSAFE
AS 'MODULE_PATHNAME', 'modb_add_snippet_blocks';
COMMENT ON FUNCTION modb.add_snippet_blocks(bigint[]) IS
    'Adds the blocks of these snippets (in clip order, up to 32 consecutive ones of a source each); returns how many. The triggers on modb.snippets call it';

CREATE FUNCTION modb.snippets_inserted()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
BEGIN
    PERFORM modb.add_snippet_blocks(ARRAY(SELECT id FROM inserted));
    RETURN NULL;
END
$$;
COMMENT ON FUNCTION modb.snippets_inserted() IS 'Trigger: blocks for the snippets an INSERT added';
CREATE TRIGGER snippets_blocks_insert AFTER INSERT ON modb.snippets REFERENCING NEW TABLE AS inserted
    FOR EACH STATEMENT EXECUTE FUNCTION modb.snippets_inserted();

-- The trigger function behind snippets_blocks_update: an update of what a block holds adds a block for the new values; the old block keeps naming the snippet, whose exact values are
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
         WHERE (n.begin_features, n.begin_terminator, n.pose_key, n.fps, n.collection_id, n.clip_id, n.version, n.mirrored)
               IS DISTINCT FROM (o.begin_features, o.begin_terminator, o.pose_key, o.fps, o.collection_id, o.clip_id, o.version, o.mirrored)
            OR (o.future_heading IS NOT NULL
                AND (n.net_translation, n.future_translation, n.future_heading)
                    IS DISTINCT FROM (o.net_translation, o.future_translation, o.future_heading))));
    RETURN NULL;
END
$$;
COMMENT ON FUNCTION modb.snippets_updated() IS
    'Trigger: blocks for snippets whose features, begin terminator, pose, rate, collection or source an UPDATE changed, or their objective''s inputs once filled';
CREATE TRIGGER snippets_blocks_update AFTER UPDATE ON modb.snippets
    REFERENCING OLD TABLE AS old_rows NEW TABLE AS new_rows
    FOR EACH STATEMENT EXECUTE FUNCTION modb.snippets_updated();

-- A block's term codes are its snippets' begin terminators: an UPDATE of a terminator's terms (which no
-- writer of the project makes; a hand edit might) adds blocks for the snippets that begin there.
CREATE FUNCTION modb.terminators_updated()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
BEGIN
    PERFORM modb.add_snippet_blocks(ARRAY(
        SELECT s.id FROM new_rows n JOIN old_rows o ON o.id = n.id JOIN modb.snippets s ON s.begin_terminator = n.id
         WHERE (n.positions, n.rotations, n.velocities, n.angular_velocities)
               IS DISTINCT FROM (o.positions, o.rotations, o.velocities, o.angular_velocities)));
    RETURN NULL;
END
$$;
COMMENT ON FUNCTION modb.terminators_updated() IS
    'Trigger: blocks for the snippets beginning at terminators whose terms an UPDATE changed (their term codes)';
CREATE TRIGGER terminators_blocks_update AFTER UPDATE ON modb.terminators
    REFERENCING OLD TABLE AS old_rows NEW TABLE AS new_rows
    FOR EACH STATEMENT EXECUTE FUNCTION modb.terminators_updated();

GRANT SELECT ON modb.snippet_blocks TO modb_reader;
-- The loader's snippets bring their blocks (the triggers run as the inserting role).
GRANT INSERT ON modb.snippet_blocks TO modb_loader;
REVOKE EXECUTE ON FUNCTION modb.add_snippet_blocks(bigint[]) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.add_snippet_blocks(bigint[]) TO modb_loader;

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
