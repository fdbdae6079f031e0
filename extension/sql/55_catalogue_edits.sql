-- Editing the catalogue (0.14.0): rename, move and delete collections, delete a clip or one version, make
-- an older version current again. The REST interface and `modb` call these; so can a loader in SQL.
--
-- Deletes are real: the rows go, their snippets with them (ON DELETE CASCADE), and with the snippets their
-- rows in every transition graph, so a graph over them is stale (modb.graph_is_current) but never names a
-- snippet that is gone. The loader gets no table-level DELETE on what the selection reads (it would also
-- let it LOCK those tables against every reader): the deleting functions are PL/pgSQL SECURITY
-- DEFINER with a fixed search_path, executable by modb_loader only, and each deletes exactly what it names.
--
-- Edits that run at the same time cannot undo each other's checks (0.15.0): moves of collections queue
-- on one advisory lock (moves are rare), so two moves ("a into b", "b into a") cannot store a loop; the
-- deletes of a clip's versions queue on its row, so two of them cannot leave it none.

CREATE FUNCTION modb.collections_before_update()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
BEGIN
    IF NEW.parent_id IS DISTINCT FROM OLD.parent_id THEN
        -- wait for other moves to end, then check the tree as they left it (a new snapshot per query)
        PERFORM pg_catalog.pg_advisory_xact_lock(pg_catalog.hashtext('modb.collections: a move'));
    END IF;
    IF NEW.parent_id IS NOT NULL AND NEW.parent_id = ANY (modb.collection_subtree(modb.collection_path(OLD.id))) THEN
        RAISE EXCEPTION 'collection "%" cannot move into "%", which lies inside it',
            modb.collection_path(OLD.id), modb.collection_path(NEW.parent_id)
            USING ERRCODE = 'check_violation', HINT = 'move it beside or above itself';
    END IF;
    RETURN NEW;
END
$$;
COMMENT ON FUNCTION modb.collections_before_update() IS 'Trigger: a collection never moves into itself or below itself';
CREATE TRIGGER collections_before_update BEFORE UPDATE OF parent_id ON modb.collections
    FOR EACH ROW EXECUTE FUNCTION modb.collections_before_update();
GRANT UPDATE (name, parent_id) ON modb.collections TO modb_loader;

CREATE FUNCTION modb._collection_id(path text)
RETURNS bigint
LANGUAGE plpgsql STABLE STRICT PARALLEL SAFE
AS $$
DECLARE
    found_id bigint := modb.find_collection(path);
BEGIN
    IF found_id IS NULL THEN
        RAISE EXCEPTION 'no collection "%"', path
            USING ERRCODE = 'no_data_found', HINT = 'SELECT modb.collection_path(id) FROM modb.collections lists them';
    END IF;
    RETURN found_id;
END
$$;
COMMENT ON FUNCTION modb._collection_id(text) IS 'The id of the collection at path "a/b", an error naming the path when absent';

CREATE FUNCTION modb.rename_collection(path text, new_name text)
RETURNS text
LANGUAGE plpgsql VOLATILE STRICT PARALLEL UNSAFE
AS $$
DECLARE
    target bigint := modb._collection_id(path);
BEGIN
    UPDATE modb.collections SET name = new_name WHERE id = target;
    RETURN modb.collection_path(target);
EXCEPTION WHEN unique_violation THEN
    RAISE EXCEPTION 'collection "%" already holds "%"', coalesce(modb.collection_path(
        (SELECT parent_id FROM modb.collections WHERE id = target)), '(top)'), new_name
        USING ERRCODE = 'unique_violation', HINT = 'choose another name';
END
$$;
COMMENT ON FUNCTION modb.rename_collection(text, text) IS
    'Renames the collection at path (its last part becomes new_name, no "/"); returns its new path. Graphs over the old path become stale';

CREATE FUNCTION modb.move_collection(path text, new_parent text)
RETURNS text
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
DECLARE
    target bigint := modb._collection_id(coalesce(path, ''));
BEGIN
    UPDATE modb.collections
       SET parent_id = CASE WHEN trim(BOTH '/' FROM coalesce(new_parent, '')) = '' THEN NULL
                            ELSE modb._collection_id(new_parent) END
     WHERE id = target;
    RETURN modb.collection_path(target);
EXCEPTION WHEN unique_violation THEN
    RAISE EXCEPTION 'collection "%" already holds one named "%"', coalesce(nullif(new_parent, ''), '(top)'),
        (SELECT name FROM modb.collections WHERE id = target)
        USING ERRCODE = 'unique_violation', HINT = 'rename one of them first';
END
$$;
COMMENT ON FUNCTION modb.move_collection(text, text) IS
    'Moves the collection at path (with what it holds) into new_parent (NULL or '''' for the top); returns its new path';

CREATE FUNCTION modb.delete_collection(path text, with_clips boolean DEFAULT false)
RETURNS bigint
LANGUAGE plpgsql VOLATILE STRICT PARALLEL UNSAFE SECURITY DEFINER
SET search_path = pg_catalog, pg_temp
AS $$
DECLARE
    subtree bigint[] := modb.collection_subtree(path);
    n_clips bigint;
BEGIN
    IF cardinality(subtree) = 0 THEN
        PERFORM modb._collection_id(path);  -- raises, naming the path
    END IF;
    SELECT count(*) INTO n_clips FROM modb.clips WHERE collection_id = ANY (subtree);
    IF n_clips > 0 AND NOT with_clips THEN
        RAISE EXCEPTION 'collection "%" holds % clips', path, n_clips
            USING ERRCODE = 'dependent_objects_still_exist',
                  HINT = 'delete them with it (with_clips => true), or move them out first';
    END IF;
    DELETE FROM modb.clips WHERE collection_id = ANY (subtree);
    DELETE FROM modb.collections WHERE id = ANY (subtree);
    RETURN n_clips;
END
$$;
COMMENT ON FUNCTION modb.delete_collection(text, boolean) IS
    'Deletes the collection at path and every collection below it; with clips only when with_clips (their versions and snippets go too); returns how many clips went';

CREATE FUNCTION modb.delete_clip(clip bigint)
RETURNS int
LANGUAGE plpgsql VOLATILE STRICT PARALLEL UNSAFE SECURITY DEFINER
SET search_path = pg_catalog, pg_temp
AS $$
DECLARE
    n_versions int;
BEGIN
    SELECT count(*) INTO n_versions FROM modb.clip_versions WHERE clip_id = clip;
    DELETE FROM modb.clips WHERE id = clip;
    IF NOT FOUND THEN
        RAISE EXCEPTION 'no clip %', clip USING ERRCODE = 'no_data_found', HINT = '`modb list` shows the stored clips';
    END IF;
    RETURN n_versions;
END
$$;
COMMENT ON FUNCTION modb.delete_clip(bigint) IS
    'Deletes a clip with every version, its snippets and the clips cut from it (modb.split_by_annotation); returns how many versions went';

CREATE FUNCTION modb.delete_clip_version(clip bigint, version int)
RETURNS int
LANGUAGE plpgsql VOLATILE STRICT PARALLEL UNSAFE SECURITY DEFINER
SET search_path = pg_catalog, pg_temp
AS $$
DECLARE
    versions int[];
BEGIN
    PERFORM FROM modb.clips c WHERE c.id = clip FOR UPDATE;  -- one version delete of a clip at a time
    SELECT array_agg(v.version ORDER BY v.version) INTO versions FROM modb.clip_versions v WHERE v.clip_id = clip;
    IF NOT (delete_clip_version.version = ANY (coalesce(versions, '{}'))) THEN
        RAISE EXCEPTION 'clip % has no version %', clip, delete_clip_version.version
            USING ERRCODE = 'no_data_found', HINT = 'SELECT version FROM modb.clip_versions WHERE clip_id = ... lists them';
    END IF;
    IF cardinality(versions) = 1 THEN
        RAISE EXCEPTION 'version % is the only version of clip %', delete_clip_version.version, clip
            USING ERRCODE = 'dependent_objects_still_exist', HINT = 'delete the clip instead (modb.delete_clip)';
    END IF;
    DELETE FROM modb.clip_versions v WHERE v.clip_id = clip AND v.version = delete_clip_version.version;
    RETURN (SELECT max(v.version) FROM modb.clip_versions v WHERE v.clip_id = clip);
END
$$;
COMMENT ON FUNCTION modb.delete_clip_version(bigint, int) IS
    'Deletes one version of a clip (not its only one) with its snippets; returns the version now current. When that is an older one, cut it again: SELECT modb.build_snippets(clip => ...)';

CREATE FUNCTION modb.restore_clip_version(clip bigint, version int)
RETURNS int
LANGUAGE plpgsql VOLATILE STRICT PARALLEL UNSAFE
AS $$
DECLARE
    made int;
BEGIN
    -- Versions are immutable and the newest is current, so "current again" is a new version with the old
    -- one's motion and meta, saying where it came from; the history stays whole.
    INSERT INTO modb.clip_versions (clip_id, skeleton_id, fps, n_frames, rotations, translations, source_file,
                                    source_sha256, load_params, meta)
    SELECT v.clip_id, v.skeleton_id, v.fps, v.n_frames, v.rotations, v.translations, v.source_file, v.source_sha256,
           v.load_params || jsonb_build_object('restored_from', v.version), v.meta
      FROM modb.clip_versions v
     WHERE v.clip_id = clip AND v.version = restore_clip_version.version
    RETURNING clip_versions.version INTO made;
    IF made IS NULL THEN
        RAISE EXCEPTION 'clip % has no version %', clip, restore_clip_version.version
            USING ERRCODE = 'no_data_found', HINT = 'SELECT version FROM modb.clip_versions WHERE clip_id = ... lists them';
    END IF;
    RETURN made;
END
$$;
COMMENT ON FUNCTION modb.restore_clip_version(bigint, int) IS
    'Makes an older version current again: a new version with its motion and meta (load_params.restored_from says which); returns its number. Cut it: SELECT modb.build_snippets(clip => ...)';

REVOKE EXECUTE ON FUNCTION modb.rename_collection(text, text), modb.move_collection(text, text),
    modb.delete_collection(text, boolean), modb.delete_clip(bigint), modb.delete_clip_version(bigint, int),
    modb.restore_clip_version(bigint, int) FROM PUBLIC;
GRANT EXECUTE ON FUNCTION modb.rename_collection(text, text), modb.move_collection(text, text),
    modb.delete_collection(text, boolean), modb.delete_clip(bigint), modb.delete_clip_version(bigint, int),
    modb.restore_clip_version(bigint, int) TO modb_loader;
