-- Selecting by annotation (SET modb.annotations, or "annotations" in a profile): names of a clip
-- version's annotation segments (meta "annotations"), OR-ed; a name starting with ! excludes. A snippet
-- passes when every one of its frames lies in a segment with one of the names (when any is given) and none
-- of its frames lies in a segment with an excluded name. Mirrored snippets have their clip's segments. Read
-- at every call, so an edit of the annotations takes effect on the next one.

CREATE FUNCTION modb.annotation_spec(value text, origin text DEFAULT NULL)
RETURNS text[]
LANGUAGE plpgsql IMMUTABLE PARALLEL SAFE
AS $$
DECLARE
    names text[];
BEGIN
    names := ARRAY(SELECT btrim(n) FROM unnest(string_to_array(value, ',')) AS n WHERE btrim(n) NOT IN ('', '!'));
    IF EXISTS (SELECT FROM unnest(names) n WHERE n ~ '[[:cntrl:]:]' OR n ~ '^!\s*!' OR length(n) > 65) THEN
        RAISE EXCEPTION '% = % is not a list of annotation names', coalesce(origin, 'modb.annotations'), quote_literal(value)
            USING HINT = 'names separated by commas, each at most 64 characters without control characters or '':'', '
                         || 'a ! before one to exclude it: e.g. ''walk, turn'' or ''!run''';
    END IF;
    RETURN CASE WHEN names = '{}' THEN NULL
                ELSE ARRAY(SELECT DISTINCT CASE WHEN n LIKE '!%' THEN '!' || btrim(substr(n, 2)) ELSE n END
                             FROM unnest(names) AS n ORDER BY 1) END;
END
$$;
COMMENT ON FUNCTION modb.annotation_spec(text, text) IS
    'The annotation names a selection keeps to, from ''walk, turn, !run'' (comma-separated, ! excludes): sorted, distinct, NULL for none; an error naming origin (the knob or profile) for a bad list';

CREATE FUNCTION modb.annotated(clip_id bigint, version int, first_frame int, n_frames int, spec text[])
RETURNS boolean
LANGUAGE sql STABLE PARALLEL SAFE
BEGIN ATOMIC
    SELECT (NOT EXISTS (SELECT FROM unnest(spec) AS n WHERE n NOT LIKE '!%')
            OR coalesce((SELECT range_agg(int4range((a->>'start')::int, (a->>'end')::int, '[]'))
                           FROM jsonb_array_elements(v.meta->'annotations') AS a
                          WHERE a->>'name' = ANY (spec))
                        @> int4range(annotated.first_frame, annotated.first_frame + annotated.n_frames - 1, '[]'), false))
       AND NOT coalesce((SELECT range_agg(int4range((a->>'start')::int, (a->>'end')::int, '[]'))
                           FROM jsonb_array_elements(v.meta->'annotations') AS a
                          WHERE '!' || (a->>'name') = ANY (spec))
                        && int4range(annotated.first_frame, annotated.first_frame + annotated.n_frames - 1, '[]'), false)
      FROM modb.clip_versions v
     WHERE v.clip_id = annotated.clip_id AND v.version = annotated.version;
END;
COMMENT ON FUNCTION modb.annotated(bigint, int, int, int, text[]) IS
    'Whether frames first_frame .. first_frame + n_frames - 1 of a clip version pass an annotation spec (modb.annotation_spec): all inside segments with one of its names (when it has any), none inside a segment with a !name';
