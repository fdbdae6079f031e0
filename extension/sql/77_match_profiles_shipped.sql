-- The shipped match profiles. An upsert, so that upgrade scripts include this file and shipped rows follow
-- the release (rows a user added are never touched; shipped rows are not in pg_dump's output).
--
-- default: each joint's angle threshold is its 99th percentile change between consecutive
-- frames of real walking and running (Bandai dataset 2 locomotion, 30 fps: neck 2.1, spine 2.7, knees 21
-- degrees per frame), so that a seam looks like a natural step (docs/synthesis.md "Synthesis quality");
-- a heading
-- term of 1 m per radian turns the avatar toward its goal, and continuity_weight 0.6 m per unit of
-- continuity ratio (0.3 before 0.6.0: with a graph's cost-to-go, which prices seams by it too, 0.6 gave
-- smoother seams on six seeded courses, the 10-minute one and the right-angle one, with every counted goal
-- within 2x; BENCHMARKS.md "Cost-to-go") keeps the
-- smoother candidate unless another leads clearly better; lookahead_distance
-- 2.5 m (about where a walk leads in the 1.5 s the objective sees) scores a far goal as a point that far
-- along the way, so that it does not favour runs, which in this data never turn (docs/synthesis.md
-- "Synthesis quality"). strict: half the thresholds.

INSERT INTO modb.match_profiles AS p (name, settings, comment, shipped) VALUES
('default', '{"joints": ["pelvis", "spine", "chest", "neck", "head", "left_hip", "left_knee", "left_ankle", "left_toe",
              "right_hip", "right_knee", "right_ankle", "right_toe", "left_shoulder", "left_elbow", "left_wrist",
              "right_shoulder", "right_elbow", "right_wrist"],
              "norm": "l2", "position_threshold": {"default": 0.12, "left_wrist": 0.2, "right_wrist": 0.2,
              "left_elbow": 0.16, "right_elbow": 0.16},
              "angle_threshold": {"default": 0.3, "pelvis": 0.11, "spine": 0.047, "chest": 0.093, "neck": 0.037,
              "head": 0.066, "left_hip": 0.23, "right_hip": 0.23, "left_knee": 0.37, "right_knee": 0.37,
              "left_ankle": 0.34, "right_ankle": 0.34, "left_toe": 0.36, "right_toe": 0.36, "left_shoulder": 0.29,
              "right_shoulder": 0.29, "left_elbow": 0.34, "right_elbow": 0.34, "left_wrist": 0.093, "right_wrist": 0.093},
              "velocity_threshold": {"default": 0.6, "left_wrist": 1.0, "right_wrist": 1.0, "left_elbow": 0.8,
              "right_elbow": 0.8},
              "angular_velocity_threshold": {"default": 4.0}, "velocity_terms": true, "heading_weight": 1.0,
              "continuity_weight": 0.6, "lookahead_distance": 2.5}',
 'Whole body: feet, hands and head within centimetres, each joint within its natural frame-to-frame change at 30 fps, velocities matched; the smoother candidate wins unless another leads clearly better toward the goal', true),
('strict', '{"joints": ["pelvis", "spine", "chest", "neck", "head", "left_hip", "left_knee", "left_ankle", "left_toe",
             "right_hip", "right_knee", "right_ankle", "right_toe", "left_shoulder", "left_elbow", "left_wrist",
             "right_shoulder", "right_elbow", "right_wrist"],
             "norm": "l2", "position_threshold": {"default": 0.06},
             "angle_threshold": {"default": 0.15, "pelvis": 0.055, "spine": 0.0235, "chest": 0.0465, "neck": 0.0185,
             "head": 0.033, "left_hip": 0.115, "right_hip": 0.115, "left_knee": 0.185, "right_knee": 0.185,
             "left_ankle": 0.17, "right_ankle": 0.17, "left_toe": 0.18, "right_toe": 0.18, "left_shoulder": 0.145,
             "right_shoulder": 0.145, "left_elbow": 0.17, "right_elbow": 0.17, "left_wrist": 0.0465, "right_wrist": 0.0465},
             "velocity_threshold": {"default": 0.3}, "angular_velocity_threshold": {"default": 2.0},
             "velocity_terms": true, "heading_weight": 1.0, "continuity_weight": 0.3,
             "lookahead_distance": 2.5}',
 'Half the default thresholds: smoother seams, more relaxation', true),
('locomotion', '{"joints": ["pelvis", "left_hip", "left_knee", "left_ankle", "left_toe", "right_hip", "right_knee",
                 "right_ankle", "right_toe"],
                 "norm": "l1", "position_threshold": {"default": 0.15}, "angle_threshold": {"default": 0.5},
                 "velocity_threshold": {"default": 0.7}, "angular_velocity_threshold": {"default": 5.0},
                 "velocity_terms": true, "heading_weight": 0.3, "lookahead_distance": 2.5}',
 'Lower body only, L1 positions, and a heading term: for walking to goals', true)
ON CONFLICT (name) DO UPDATE SET settings = excluded.settings, comment = excluded.comment
 WHERE p.shipped;
