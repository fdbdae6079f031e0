-- 0.3.0: synthesis in the database (modb.synthesize and its helpers); the objective measures where a
-- snippet leads (snippets.future_translation / future_heading) plus a continuity weight; the default
-- and strict profiles retuned for seams that look like natural steps.

-- Indexes for the snippets -> terminators foreign keys: without them, replacing or deleting snippets of
-- many clips scanned every snippet once per terminator (minutes for 115k snippets; 1.5 s with them).
CREATE INDEX snippets_begin_terminator_idx ON modb.snippets (begin_terminator);
CREATE INDEX snippets_end_terminator_idx ON modb.snippets (end_terminator);

ALTER TABLE modb.snippets
    ADD COLUMN future_translation float8[] CHECK (array_length(future_translation, 1) = 3),
    ADD COLUMN future_heading float8;
COMMENT ON COLUMN modb.snippets.future_translation IS
    'Where playing on leads: pelvis travel over this snippet and up to two play-on snippets of its clip (1.5 s for 0.5 s windows), in the heading frame of its first frame; the objective of select_next_snippet';
COMMENT ON COLUMN modb.snippets.future_heading IS 'The heading change over the same frames as future_translation (radians)';
--@include 71_futures.sql
SELECT modb.fill_futures();

ALTER TYPE modb.match_plan ADD ATTRIBUTE continuity_weight float8, ADD ATTRIBUTE lookahead_distance float8;
COMMENT ON TYPE modb.match_plan IS
    'A profile resolved for one query: included joints (0-based standard indices), thresholds per standard joint (Infinity when not included), the half-widths of the search box per feature, and the objective''s weights';
--@include 72_plan.sql
--@include 73_profiles.sql
--@include 76_select.sql
--@include 78_synthesize.sql
--@functions
-- 0.2.0 built mirror images whose rotations were expressed in other joint frames than the captured ones
-- (positions were right), so mirrored snippets never followed captured ones. Rebuild them with this
-- version's kernel and the windows they had; their snippet ids change.
DO $$
DECLARE
    source record;
BEGIN
    FOR source IN SELECT ss.clip_id, ss.window_frames, ss.stride_frames, v.fps
                    FROM modb.snippet_sources ss JOIN modb.clip_versions v USING (clip_id, version)
                   WHERE ss.mirrored ORDER BY ss.clip_id
    LOOP
        DELETE FROM modb.snippet_sources WHERE clip_id = source.clip_id AND mirrored;
        PERFORM modb.build_snippets(clip => source.clip_id, window_seconds => (source.window_frames - 1) / source.fps,
                                    stride_seconds => source.stride_frames / source.fps, mirrored => true);
    END LOOP;
END
$$;
