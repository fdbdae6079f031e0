-- 0.30.0: editing motion by hand (issue 64): edit scripts gain the ik and rotate commands, run by the kernel.

-- The commands the table's comment lists (98_edit_scripts.sql).
COMMENT ON TABLE modb.edit_scripts IS
    'Edit scripts: [{"op": "mirror" | "trim" (start, end) | "smooth" (seconds) | "resample" (fps) | "time_stretch" (factor) | "copy_joints" (clip, joints, start, end, source_start, blend) | "retarget" (skeleton) | "ik" (joint, time, offset, orientation, chain, before, after) | "rotate" (joint, time, rotation, before, after)}, ...], applied in order by modb.apply_edit_script';
