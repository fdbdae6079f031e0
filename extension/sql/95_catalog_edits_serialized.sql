-- 0.15.0: catalogue edits that run at the same time cannot undo each other's checks. Two moves ("a into
-- b" and "b into a") each saw a tree without the other's move and could store a loop; two deletes of a
-- clip's last two versions each saw the other version and could leave none. Moves now queue on one
-- advisory lock (moves are rare) and a version's delete on its clip's row. CREATE OR REPLACE: upgrades
-- include this file.
CREATE OR REPLACE FUNCTION modb.collections_before_update()
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

CREATE OR REPLACE FUNCTION modb.delete_clip_version(clip bigint, version int)
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
