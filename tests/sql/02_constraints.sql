-- Constraints and triggers reject bad rows; known-value forward kinematics in the server.
BEGIN;
CREATE EXTENSION IF NOT EXISTS pgtap;
SELECT plan(22);

-- A two-joint skeleton: root with position channels, child 1 m along +X.
INSERT INTO modb.skeletons (id, name, hierarchy, joint_map, mirror_pairs) VALUES (
    1000, 'test', '{"format": "bvh", "unit_m": 1, "translated": [0], "joints": [
        {"name": "Hips", "parent": -1, "offset": [0, 0, 0], "channels": ["Xposition", "Yposition", "Zposition", "Yrotation"], "rotation_order": "Y", "end_site": null},
        {"name": "Arm", "parent": 0, "offset": [1, 0, 0], "channels": ["Yrotation"], "rotation_order": "Y", "end_site": [0, 0, 1]}]}',
    '{"pelvis": "Hips"}', '[]');
INSERT INTO modb.collections (id, name) VALUES (1000, 'tests');
INSERT INTO modb.clips (id, collection_id, name) VALUES (1000, 1000, 'clip');

-- Rotation of 90 degrees about +Y: (cos 45, 0, sin 45, 0).
SELECT lives_ok($$INSERT INTO modb.clip_versions (clip_id, skeleton_id, fps, n_frames, rotations, translations)
    VALUES (1000, 1000, 30, 2, '{{{0.70710678,0,0.70710678,0},{1,0,0,0}},{{1,0,0,0},{1,0,0,0}}}',
            '{{{1,2,3}},{{0,0,0}}}')$$, 'a valid clip version');
SELECT is((SELECT version FROM modb.clip_versions WHERE clip_id = 1000), 1, 'first version is 1');
SELECT results_eq(
    $$SELECT frame, joint, round(x::numeric, 6), round(y::numeric, 6), round(z::numeric, 6)
        FROM modb.world_positions(1000) ORDER BY frame, joint_index$$,
    $$VALUES (0, 'Hips', 1.0, 2.0, 3.0), (0, 'Arm', 1.0, 2.0, 2.0), (1, 'Hips', 0.0, 0.0, 0.0), (1, 'Arm', 1.0, 0.0, 0.0)$$,
    'forward kinematics: the arm turns with the root (+X becomes -Z under +90 degrees about Y)');

PREPARE insert_version(real[], real[], int) AS
    INSERT INTO modb.clip_versions (clip_id, skeleton_id, fps, n_frames, rotations, translations)
    VALUES (1000, 1000, 30, $3, $1, $2);
SELECT throws_ok($$EXECUTE insert_version('{{{0.9,0,0.1,0},{1,0,0,0}}}', '{{{0,0,0}}}', 1)$$,
                 '23514', NULL, 'non-unit quaternion rejected');
SELECT throws_ok($$EXECUTE insert_version('{{{-1,0,0,0},{1,0,0,0}}}', '{{{0,0,0}}}', 1)$$,
                 '23514', NULL, 'quaternion with w < 0 rejected (not canonical)');
SELECT throws_ok($$EXECUTE insert_version('{{{1,0,0,0},{1,0,0,0}}}', '{{{0,0,0}}}', 2)$$,
                 '23514', NULL, 'frame count that does not match the rotations rejected');
SELECT throws_ok($$EXECUTE insert_version('{{{1,0,0,0},{1,0,0,0}},{{1,0,0,0},{1,0,0,0}}}', '{{{0,0,0}}}', 2)$$,
                 '23514', NULL, 'frame count that does not match the translations rejected');
SELECT throws_ok($$EXECUTE insert_version('{{{1,0,0,0}}}', '{{{0,0,0}}}', 1)$$,
                 '23514', 'rotations has 1 joints, skeleton 1000 has 2', 'joint count that does not match the skeleton rejected');
SELECT throws_ok($$EXECUTE insert_version('{{{1,0,0,0},{1,0,0,0}}}', NULL, 1)$$,
                 '23514', NULL, 'missing translations for a joint with position channels rejected');
SELECT throws_ok($$EXECUTE insert_version('{{{1,0,0,0},{1,0,0,0}}}', '{{{0,NaN,0}}}', 1)$$,
                 '23514', NULL, 'NaN translation rejected');
SELECT throws_ok($$EXECUTE insert_version('{{{1,0,0,0,0},{1,0,0,0,0}}}', '{{{0,0,0}}}', 1)$$,
                 '23514', NULL, 'five-component rotations rejected');
SELECT throws_ok($$INSERT INTO modb.clip_versions (clip_id, skeleton_id, fps, n_frames, rotations, translations, meta)
    VALUES (1000, 1000, 30, 1, '{{{1,0,0,0},{1,0,0,0}}}', '{{{0,0,0}}}', '{"annotations": [{"name": "x", "start": 0, "end": 5}]}')$$,
                 '23514', NULL, 'annotation past the last frame rejected');
SELECT lives_ok($$EXECUTE insert_version('{{{1,0,0,0},{1,0,0,0}}}', '{{{0,0,0}}}', 1)$$, 'a second version');
SELECT is((SELECT max(version) FROM modb.clip_versions WHERE clip_id = 1000), 2, 'versions are numbered newest + 1');
SELECT is((SELECT version FROM modb.current_clips WHERE clip_id = 1000), 2, 'current_clips shows the newest version');

SELECT throws_ok($$UPDATE modb.clip_versions SET fps = 60 WHERE clip_id = 1000 AND version = 1$$,
                 '55000', 'clip 1000 version 1 is immutable: only meta may change', 'a version''s motion is immutable');
SELECT lives_ok($$UPDATE modb.clip_versions SET meta = '{"annotations": [{"name": "step", "start": 0, "end": 1}], "tags": ["t"]}'
                  WHERE clip_id = 1000 AND version = 1$$, 'meta (annotations, tags) may be edited');

SELECT throws_ok($$UPDATE modb.skeletons SET joint_map = '{"pelvis": "NoSuchJoint"}' WHERE id = 1000$$,
                 '23514', NULL, 'joint map onto a missing joint rejected');
SELECT throws_ok($$UPDATE modb.skeletons SET mirror_pairs = '[["Hips", "Arm"], ["Arm", "Hips"]]' WHERE id = 1000$$,
                 '23514', NULL, 'a joint in two mirror pairs rejected');
SELECT throws_ok($$INSERT INTO modb.collections (name) VALUES ('a/b')$$, '23514', NULL, 'collection names have no "/"');
SELECT throws_ok($$UPDATE modb.skeletons SET hierarchy = jsonb_set(hierarchy, '{unit_m}', '2') WHERE id = 1000$$,
                 '55000', NULL, 'a skeleton''s hierarchy is immutable');
SELECT lives_ok($$UPDATE modb.skeletons SET joint_map = '{"pelvis": "Hips", "left_shoulder": "Arm"}', name = 'renamed'
                  WHERE id = 1000$$, 'the joint map and name may be edited');

SELECT * FROM finish();
ROLLBACK;
