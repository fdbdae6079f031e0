CREATE FUNCTION modb.collection_path(collection bigint)
RETURNS text
LANGUAGE sql STABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    WITH RECURSIVE up(id, parent_id, name, depth) AS (
        SELECT id, parent_id, name, 0 FROM modb.collections WHERE id = collection
        UNION ALL
        SELECT c.id, c.parent_id, c.name, up.depth + 1 FROM modb.collections c JOIN up ON c.id = up.parent_id
         WHERE up.depth < 1000  -- a parent_id cycle, which only the owner can create, must not recurse forever
    )
    SELECT string_agg(name, '/' ORDER BY depth DESC) FROM up;
END;
COMMENT ON FUNCTION modb.collection_path(bigint) IS 'The path "a/b/c" of a collection, NULL for an unknown id';

CREATE FUNCTION modb.find_collection(path text)
RETURNS bigint
LANGUAGE plpgsql STABLE STRICT PARALLEL SAFE
AS $$
DECLARE
    part text;
    current bigint := NULL;
BEGIN
    FOREACH part IN ARRAY string_to_array(trim(BOTH '/' FROM path), '/') LOOP
        SELECT id INTO current FROM modb.collections
         WHERE parent_id IS NOT DISTINCT FROM current AND name = part;
        IF NOT FOUND THEN
            RETURN NULL;
        END IF;
    END LOOP;
    RETURN current;
END
$$;
COMMENT ON FUNCTION modb.find_collection(text) IS 'The id of the collection at path "a/b/c", NULL when absent';

CREATE FUNCTION modb.collection_subtree(path text)
RETURNS bigint[]
LANGUAGE sql STABLE STRICT PARALLEL SAFE
BEGIN ATOMIC
    WITH RECURSIVE down(id, depth) AS (
        SELECT id, 0 FROM modb.collections WHERE id = modb.find_collection(path)
        UNION ALL
        SELECT c.id, down.depth + 1 FROM modb.collections c JOIN down ON c.parent_id = down.id WHERE down.depth < 1000
    )
    SELECT coalesce(array_agg(id), '{}') FROM down;
END;
COMMENT ON FUNCTION modb.collection_subtree(text) IS 'Ids of the collection at path "a/b" and of every collection below it';

CREATE FUNCTION modb.ensure_collection(path text)
RETURNS bigint
LANGUAGE plpgsql VOLATILE STRICT PARALLEL UNSAFE
AS $$
DECLARE
    part text;
    current bigint := NULL;
    found_id bigint;
BEGIN
    IF trim(BOTH '/' FROM path) = '' THEN
        RAISE EXCEPTION 'collection path is empty' USING HINT = 'give a path like "bandai/walks"';
    END IF;
    FOREACH part IN ARRAY string_to_array(trim(BOTH '/' FROM path), '/') LOOP
        IF part = '' THEN
            RAISE EXCEPTION 'collection path "%" has an empty part', path USING HINT = 'remove the doubled "/"';
        END IF;
        INSERT INTO modb.collections (parent_id, name) VALUES (current, part)
            ON CONFLICT (parent_id, name) DO NOTHING
            RETURNING id INTO found_id;
        IF found_id IS NULL THEN
            SELECT id INTO found_id FROM modb.collections WHERE parent_id IS NOT DISTINCT FROM current AND name = part;
        END IF;
        current := found_id;
        found_id := NULL;
    END LOOP;
    RETURN current;
END
$$;
COMMENT ON FUNCTION modb.ensure_collection(text) IS 'The id of the collection at path "a/b/c", creating missing levels';

CREATE VIEW modb.current_clips AS
SELECT c.id AS clip_id,
       c.name,
       modb.collection_path(c.collection_id) AS collection,
       v.version,
       v.skeleton_id,
       v.fps,
       v.n_frames,
       v.n_frames / v.fps AS seconds,
       v.source_file,
       v.source_sha256,
       v.meta,
       v.created_at
  FROM modb.clips c
  JOIN LATERAL (SELECT * FROM modb.clip_versions cv WHERE cv.clip_id = c.id ORDER BY cv.version DESC LIMIT 1) v ON true;
COMMENT ON VIEW modb.current_clips IS 'Every clip with its newest version ("the clip" unless a version is named)';
