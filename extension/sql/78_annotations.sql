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

-- Clips cut from another clip's annotated segments (0.14.0): the motion primitives that models are built
-- from. Such a clip refers to its source version's frames and has no version, so no snippets, of its own:
-- the source's snippets already cover those frames.
CREATE TABLE modb.clip_segments (
    clip_id        bigint PRIMARY KEY REFERENCES modb.clips (id) ON DELETE CASCADE,
    source_clip    bigint NOT NULL,
    source_version int NOT NULL,
    first_frame    int NOT NULL CHECK (first_frame >= 0),
    last_frame     int NOT NULL CHECK (last_frame >= first_frame),
    annotation     text NOT NULL,
    FOREIGN KEY (source_clip, source_version) REFERENCES modb.clip_versions (clip_id, version) ON DELETE CASCADE
);
COMMENT ON TABLE modb.clip_segments IS
    'A clip that is frames first_frame..last_frame (0-based, inclusive) of another clip''s version, cut at the segment annotation (modb.split_by_annotation); it has no versions or snippets of its own';
CREATE INDEX clip_segments_source_idx ON modb.clip_segments (source_clip, source_version);  -- ON DELETE CASCADE
SELECT pg_catalog.pg_extension_config_dump('modb.clip_segments', '');
GRANT SELECT ON modb.clip_segments TO modb_reader;
GRANT INSERT ON modb.clip_segments TO modb_loader;

CREATE FUNCTION modb.clip_segments_after_delete()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
BEGIN
    -- The source version went (its deletion cascades here, run as the owner): the cut clip goes with it.
    DELETE FROM modb.clips c WHERE c.id = OLD.clip_id;
    RETURN NULL;
END
$$;
COMMENT ON FUNCTION modb.clip_segments_after_delete() IS 'Trigger: a clip cut from a version goes when that version does';
CREATE TRIGGER clip_segments_after_delete AFTER DELETE ON modb.clip_segments
    FOR EACH ROW EXECUTE FUNCTION modb.clip_segments_after_delete();

CREATE FUNCTION modb.clip_versions_not_segment()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
BEGIN
    IF EXISTS (SELECT FROM modb.clip_segments s WHERE s.clip_id = NEW.clip_id) THEN
        RAISE EXCEPTION 'clip % is cut from clip % (frames %-%): it has no versions of its own', NEW.clip_id,
            (SELECT source_clip FROM modb.clip_segments WHERE clip_id = NEW.clip_id),
            (SELECT first_frame FROM modb.clip_segments WHERE clip_id = NEW.clip_id),
            (SELECT last_frame FROM modb.clip_segments WHERE clip_id = NEW.clip_id)
            USING ERRCODE = 'check_violation', HINT = 'load the file under another name or into another collection';
    END IF;
    RETURN NEW;
END
$$;
COMMENT ON FUNCTION modb.clip_versions_not_segment() IS 'Trigger: a clip cut from another (modb.clip_segments) never gets a version';
CREATE TRIGGER clip_versions_not_segment BEFORE INSERT ON modb.clip_versions
    FOR EACH ROW EXECUTE FUNCTION modb.clip_versions_not_segment();

CREATE FUNCTION modb.split_by_annotation(clip bigint, annotation text DEFAULT NULL, collection text DEFAULT NULL)
RETURNS TABLE (clip_id bigint, name text, segment text, first_frame int, last_frame int, created boolean)
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
DECLARE
    src record;
    seg record;
    target_collection bigint;
    clip_name text;
    existing record;
BEGIN
    SELECT c.name, c.collection_id, v.version, v.meta INTO src
      FROM modb.clips c JOIN modb.clip_versions v ON v.clip_id = c.id
     WHERE c.id = split_by_annotation.clip
     ORDER BY v.version DESC LIMIT 1;
    IF NOT FOUND THEN
        RAISE EXCEPTION 'no clip % with a version', split_by_annotation.clip
            USING ERRCODE = 'no_data_found', HINT = '`modb list` shows the stored clips';
    END IF;
    target_collection := CASE WHEN split_by_annotation.collection IS NULL THEN src.collection_id
                              ELSE modb.ensure_collection(split_by_annotation.collection) END;
    FOR seg IN
        SELECT a->>'name' AS name, (a->>'start')::int AS start, (a->>'end')::int AS stop
          FROM jsonb_array_elements(coalesce(src.meta->'annotations', '[]')) a
         WHERE split_by_annotation.annotation IS NULL OR a->>'name' = split_by_annotation.annotation
         ORDER BY 2, 3, 1
    LOOP
        clip_name := format('%s_%s_%s-%s', src.name, seg.name, seg.start, seg.stop);
        SELECT c.id, s.source_clip, s.source_version, s.first_frame, s.last_frame INTO existing
          FROM modb.clips c LEFT JOIN modb.clip_segments s ON s.clip_id = c.id
         WHERE c.collection_id = target_collection AND c.name = clip_name;
        IF FOUND THEN  -- split again: the same cut is kept, anything else by that name is an error
            IF (existing.source_clip, existing.source_version, existing.first_frame, existing.last_frame)
               IS DISTINCT FROM (split_by_annotation.clip, src.version, seg.start, seg.stop) THEN
                RAISE EXCEPTION 'collection "%" already has a clip "%" that is not this cut',
                    modb.collection_path(target_collection), clip_name
                    USING ERRCODE = 'unique_violation', HINT = 'split into another collection';
            END IF;
            RETURN QUERY SELECT existing.id, clip_name, seg.name, seg.start, seg.stop, false;
            CONTINUE;
        END IF;
        INSERT INTO modb.clips (collection_id, name, meta)
        VALUES (target_collection, clip_name,
                jsonb_build_object('cut_from', jsonb_build_object('clip_id', split_by_annotation.clip,
                                                                   'version', src.version)))
        RETURNING id INTO existing;
        INSERT INTO modb.clip_segments (clip_id, source_clip, source_version, first_frame, last_frame, annotation)
        VALUES (existing.id, split_by_annotation.clip, src.version, seg.start, seg.stop, seg.name);
        RETURN QUERY SELECT existing.id, clip_name, seg.name, seg.start, seg.stop, true;
    END LOOP;
END
$$;
COMMENT ON FUNCTION modb.split_by_annotation(bigint, text, text) IS
    'Cuts the clip''s current version at its annotated segments (only those named annotation, when given): a clip per segment, named SOURCE_NAME_START-END, in collection (default: the source''s), referring to the source''s frames (modb.clip_segments); splitting again keeps the cuts made';
REVOKE EXECUTE ON FUNCTION modb.split_by_annotation(bigint, text, text) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.split_by_annotation(bigint, text, text) TO modb_loader;
