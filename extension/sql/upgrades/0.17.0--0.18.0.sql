-- 0.18.0: every term of the continuity ratio bounded where select_next_snippets' box search reads
-- (src/term_codes.c): snippet blocks carry term bounds and per-snippet term codes, and every existing
-- block is derived again here (modb.pack_snippet_blocks(0), a NOTICE per pose and rate). The update
-- holds modb.snippet_blocks (ALTER TABLE) until it commits: selections wait for it (BENCHMARKS.md says how
-- long at a million snippets).

-- A standby's replication slot keeps the WAL the re-derivation writes (about twice the blocks' size):
-- warned about before the work starts, where a slot's limit could be passed.
DO $$
DECLARE
    expected bigint := 2.5 * pg_total_relation_size('modb.snippet_blocks') + 64 * 1024 * 1024;
    keep text := current_setting('max_slot_wal_keep_size');
    slot record;
BEGIN
    FOR slot IN SELECT slot_name, safe_wal_size FROM pg_replication_slots
                 WHERE safe_wal_size IS NOT NULL AND safe_wal_size < expected LOOP
        RAISE WARNING 'modb: this update writes about % of WAL; replication slot "%" can keep only % more before max_slot_wal_keep_size (%) invalidates it',
            pg_size_pretty(expected), slot.slot_name, pg_size_pretty(slot.safe_wal_size), keep
            USING HINT = 'Let the standby catch up first, or raise max_slot_wal_keep_size for the update (ALTER SYSTEM, then SELECT pg_reload_conf()), or cancel and run the update when the standby is connected';
    END LOOP;
END
$$;

ALTER TABLE modb.snippet_blocks ADD COLUMN term_bounds bytea, ADD COLUMN term_codes bytea,
    ADD COLUMN input_bounds real[], ADD COLUMN end_speeds real[];
COMMENT ON TABLE modb.snippet_blocks IS
    'Up to 32 snippets of one pose and rate: consecutive ones of a clip source (as loaded) or packed ones near each other (pack_order set); the bounds of their begin features and each one''s 8-bit code within them, and of every term of the continuity ratio (term_bounds, term_codes); select_next_snippets'' box search (kept by triggers on modb.snippets)';
COMMENT ON COLUMN modb.snippet_blocks.term_bounds IS
    'Every term of the continuity ratio bounded (0.18.0, src/term_codes.c): per joint and kind (position, rotation as the x, y, z of the quaternion with w >= 0, velocity, angular velocity) and axis, the bounds of the block''s begin terminators as 16-bit codes on a fixed scale per kind (0: unbounded below, 65535: above), all low codes then all high ones; NULL in a block written before 0.18.0';
COMMENT ON COLUMN modb.snippet_blocks.input_bounds IS
    'The least of each objective input over the block''s snippets (as in objective_inputs), then the greatest of each; NULL where one is not known: the block directory ranks blocks by the least objective they allow (0.18.0)';
COMMENT ON COLUMN modb.snippet_blocks.end_speeds IS
    'Per snippet, its pelvis'' ground speed at its end (float4, as coming to rest computes it): coming to rest and setting off (modb.select_snippet_ending) pass over the snippets that cannot end as wanted without reading them (0.18.0)';
COMMENT ON COLUMN modb.snippet_blocks.term_codes IS
    'Per snippet, each term component''s 4-bit code within term_bounds (two a byte): select_next_snippets rejects a block or a candidate whose continuity ratio cannot be within the level from these, without reading its rows';

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

-- explain_selection: a screen by default (0.18.0), the profile and the boxes when verbose.
DROP FUNCTION modb.explain_selection(bigint, float8[], int, text, text, bigint[]);
--@include 86_selection.sql

-- Coming to rest and setting off by the box search (select_snippet_ending in C; the SQL kept as
-- select_snippet_ending_reference).
--@include 89_synthesis.sql

--@functions
-- Every block derived again, with its term codes (the loader packs every pose after a load the same way).
SELECT count(*) AS pose_groups FROM modb.pack_snippet_blocks(0);
CREATE INDEX snippet_blocks_directory_idx ON modb.snippet_blocks (pose_key, fps, pack_order)
    INCLUDE (low, high, input_bounds);
