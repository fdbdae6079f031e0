-- 0.21.0: motion primitives. Steps found from foot contacts (modb.annotate_steps) are annotation
-- segments with keyframes and an automatic mark, which the annotations' check now knows; a primitive's
-- examples aligned in time into modb.processed_data (modb.align_primitive).
CREATE OR REPLACE FUNCTION modb.annotations_ok(meta jsonb, n_frames int)
RETURNS boolean
LANGUAGE sql IMMUTABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    SELECT jsonb_typeof(meta) = 'object'
       AND (NOT meta ? 'annotations' OR (
            jsonb_typeof(meta->'annotations') = 'array'
        AND NOT EXISTS (
            SELECT FROM jsonb_array_elements(meta->'annotations') AS a(seg)
            WHERE jsonb_typeof(a.seg) <> 'object'
               OR jsonb_typeof(a.seg->'name') IS DISTINCT FROM 'string'
               OR jsonb_typeof(a.seg->'start') IS DISTINCT FROM 'number'
               OR jsonb_typeof(a.seg->'end') IS DISTINCT FROM 'number'
               OR NOT ((a.seg->>'start')::numeric BETWEEN 0 AND (a.seg->>'end')::numeric)
               OR (a.seg->>'end')::numeric >= n_frames
               OR (a.seg ? 'auto' AND jsonb_typeof(a.seg->'auto') <> 'boolean')
               OR (a.seg ? 'keyframes' AND (jsonb_typeof(a.seg->'keyframes') <> 'array' OR EXISTS (
                   SELECT FROM jsonb_array_elements(a.seg->'keyframes') AS k(frame)
                    WHERE jsonb_typeof(k.frame) <> 'number'
                       OR NOT (k.frame::text::numeric BETWEEN (a.seg->>'start')::numeric
                                                          AND (a.seg->>'end')::numeric)))))));
END;
COMMENT ON FUNCTION modb.annotations_ok(jsonb, int) IS
    'True when meta is an object whose optional "annotations" list holds {name, start, end} segments with 0 <= start <= end < n_frames (frames, 0-based), each with optional "keyframes" (frames within it) and "auto" (true: found by modb.annotate_steps)';
--@include 88_motion_primitives.sql
