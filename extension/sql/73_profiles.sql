-- The shipped match profiles. An upsert, so that upgrade scripts include this file and shipped rows follow
-- the release (rows a user added are never touched; shipped rows are not in pg_dump's output).
--
-- default (0.3.0): each joint's angle threshold is about 0.6 of its 99th percentile change between
-- consecutive frames of real walking and running (Bandai dataset 2 locomotion, 30 fps: neck 2.1, spine
-- 2.7, knees 21 degrees per frame), so that a seam looks like a natural step (README "Synthesis
-- quality"); a heading term of 1 m per radian turns the avatar toward its goal. strict: half of it.

INSERT INTO modb.match_profiles AS p (name, settings, comment, shipped) VALUES
('default', '{"joints": ["pelvis", "spine", "chest", "neck", "head", "left_hip", "left_knee", "left_ankle", "left_toe",
              "right_hip", "right_knee", "right_ankle", "right_toe", "left_shoulder", "left_elbow", "left_wrist",
              "right_shoulder", "right_elbow", "right_wrist"],
              "norm": "l2", "position_threshold": {"default": 0.12, "left_wrist": 0.2, "right_wrist": 0.2,
              "left_elbow": 0.16, "right_elbow": 0.16},
              "angle_threshold": {"default": 0.2, "pelvis": 0.07, "spine": 0.03, "chest": 0.06, "neck": 0.025,
              "head": 0.04, "left_hip": 0.14, "right_hip": 0.14, "left_knee": 0.22, "right_knee": 0.22,
              "left_ankle": 0.2, "right_ankle": 0.2, "left_toe": 0.21, "right_toe": 0.21, "left_shoulder": 0.17,
              "right_shoulder": 0.17, "left_elbow": 0.2, "right_elbow": 0.2, "left_wrist": 0.055, "right_wrist": 0.055},
              "velocity_threshold": {"default": 0.6, "left_wrist": 1.0, "right_wrist": 1.0, "left_elbow": 0.8,
              "right_elbow": 0.8},
              "angular_velocity_threshold": {"default": 4.0}, "velocity_terms": true, "heading_weight": 1.0}',
 'Whole body: feet, hands and head within centimetres, each joint within about 0.6 of its natural frame-to-frame change at 30 fps, velocities matched, turning toward the goal', true),
('strict', '{"joints": ["pelvis", "spine", "chest", "neck", "head", "left_hip", "left_knee", "left_ankle", "left_toe",
             "right_hip", "right_knee", "right_ankle", "right_toe", "left_shoulder", "left_elbow", "left_wrist",
             "right_shoulder", "right_elbow", "right_wrist"],
             "norm": "l2", "position_threshold": {"default": 0.06},
             "angle_threshold": {"default": 0.1, "pelvis": 0.035, "spine": 0.015, "chest": 0.03, "neck": 0.0125,
             "head": 0.02, "left_hip": 0.07, "right_hip": 0.07, "left_knee": 0.11, "right_knee": 0.11,
             "left_ankle": 0.1, "right_ankle": 0.1, "left_toe": 0.105, "right_toe": 0.105, "left_shoulder": 0.085,
             "right_shoulder": 0.085, "left_elbow": 0.1, "right_elbow": 0.1, "left_wrist": 0.0275, "right_wrist": 0.0275},
             "velocity_threshold": {"default": 0.3}, "angular_velocity_threshold": {"default": 2.0},
             "velocity_terms": true, "heading_weight": 1.0}',
 'Half the default thresholds: smoother seams, more relaxation', true),
('locomotion', '{"joints": ["pelvis", "left_hip", "left_knee", "left_ankle", "left_toe", "right_hip", "right_knee",
                 "right_ankle", "right_toe"],
                 "norm": "l1", "position_threshold": {"default": 0.15}, "angle_threshold": {"default": 0.5},
                 "velocity_threshold": {"default": 0.7}, "angular_velocity_threshold": {"default": 5.0},
                 "velocity_terms": true, "heading_weight": 0.3}',
 'Lower body only, L1 positions, and a heading term: for walking to goals', true)
ON CONFLICT (name) DO UPDATE SET settings = excluded.settings, comment = excluded.comment
 WHERE p.shipped;
