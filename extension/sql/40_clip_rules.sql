-- Rules a constraint cannot express: frame layout against the skeleton, version numbering, immutability.

CREATE FUNCTION modb.clip_versions_before_insert()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
DECLARE
    h jsonb;
    n_translated int;
BEGIN
    SELECT hierarchy INTO h FROM modb.skeletons WHERE id = NEW.skeleton_id;
    IF array_length(NEW.rotations, 2) IS DISTINCT FROM jsonb_array_length(h->'joints') THEN
        RAISE EXCEPTION 'rotations has % joints, skeleton % has %',
            array_length(NEW.rotations, 2), NEW.skeleton_id, jsonb_array_length(h->'joints')
            USING ERRCODE = 'check_violation',
                  HINT = 'rotations is real[n_frames][n_joints][4] with the joints in skeleton order';
    END IF;
    n_translated := coalesce(jsonb_array_length(h->'translated'), 0);
    IF coalesce(array_length(NEW.translations, 2), 0) <> n_translated THEN
        RAISE EXCEPTION 'translations has % joints, skeleton % has % joints with position channels',
            coalesce(array_length(NEW.translations, 2), 0), NEW.skeleton_id, n_translated
            USING ERRCODE = 'check_violation',
                  HINT = 'translations is real[n_frames][n_translated][3], NULL when no joint has position channels';
    END IF;
    -- Every writer of a clip's versions queues on its row (0.17.0), so the newest + 1 read below is
    -- still free when this insert commits; a writer that read the clip locked it already.
    PERFORM FROM modb.clips c WHERE c.id = NEW.clip_id FOR NO KEY UPDATE;
    IF NEW.version IS NULL THEN
        SELECT coalesce(max(version), 0) + 1 INTO NEW.version FROM modb.clip_versions WHERE clip_id = NEW.clip_id;
    END IF;
    RETURN NEW;
END
$$;
COMMENT ON FUNCTION modb.clip_versions_before_insert() IS
    'Trigger: checks the frame arrays against the skeleton, locks the clip''s row (writers of its versions queue there) and numbers the version (newest + 1) when not given';

CREATE TRIGGER clip_versions_before_insert BEFORE INSERT ON modb.clip_versions
    FOR EACH ROW EXECUTE FUNCTION modb.clip_versions_before_insert();

CREATE FUNCTION modb.clip_versions_before_update()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
BEGIN
    IF (NEW.clip_id, NEW.version, NEW.skeleton_id, NEW.fps, NEW.n_frames, NEW.rotations, NEW.translations,
        NEW.source_file, NEW.source_sha256, NEW.load_params, NEW.created_at, NEW.created_by)
       IS DISTINCT FROM
       (OLD.clip_id, OLD.version, OLD.skeleton_id, OLD.fps, OLD.n_frames, OLD.rotations, OLD.translations,
        OLD.source_file, OLD.source_sha256, OLD.load_params, OLD.created_at, OLD.created_by) THEN
        RAISE EXCEPTION 'clip % version % is immutable: only meta may change', OLD.clip_id, OLD.version
            USING ERRCODE = 'object_not_in_prerequisite_state',
                  HINT = 'insert a new version instead (modb load adds one when the file changed)';
    END IF;
    RETURN NEW;
END
$$;
COMMENT ON FUNCTION modb.clip_versions_before_update() IS 'Trigger: a clip version''s motion is immutable, only meta may change';

CREATE TRIGGER clip_versions_before_update BEFORE UPDATE ON modb.clip_versions
    FOR EACH ROW EXECUTE FUNCTION modb.clip_versions_before_update();

CREATE FUNCTION modb.skeletons_before_update()
RETURNS trigger
LANGUAGE plpgsql VOLATILE PARALLEL UNSAFE
AS $$
BEGIN
    IF NEW.hierarchy IS DISTINCT FROM OLD.hierarchy THEN
        RAISE EXCEPTION 'the hierarchy of skeleton % is immutable: clips are stored against it', OLD.id
            USING ERRCODE = 'object_not_in_prerequisite_state',
                  HINT = 'load the motion again with the changed skeleton; joint_map, mirror_pairs, name and meta may be edited';
    END IF;
    RETURN NEW;
END
$$;
COMMENT ON FUNCTION modb.skeletons_before_update() IS
    'Trigger: a skeleton''s hierarchy is immutable (its clips'' frames follow it); the joint map and pairs may change';

CREATE TRIGGER skeletons_before_update BEFORE UPDATE ON modb.skeletons
    FOR EACH ROW EXECUTE FUNCTION modb.skeletons_before_update();
