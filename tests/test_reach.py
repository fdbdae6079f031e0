"""A hand meeting a target at an action's keyframe (issue 63, item 4: modb_kernel.reach) on
Bandai's hand raises, judged by the tests' own forward kinematics (scipy).

Joint limits and the wrists' peak box come from 60 clips of each raise; the reach is tried on
held-out clips at the keyframe (the middle of the plateau where the wrist is highest) over a grid
of targets fixed before tuning (support/reach_grid.py: the box's centre, 10, 20 and 30 cm beyond
it in six directions, one 1.5 m above). Where the shoulder is within the arm's length (less
2 cm) the wrist must meet the target within 1 cm, unless the joint limits stop it, which must
then be said (the nearest point, its distance); every target: the pose natural (moved joints
within the examples' range plus 10 degrees, elbows bent the way the examples bend them), bones
kept, frames outside the falloff and joints not moved byte-equal, no jump above the source's
p99.9."""

from __future__ import annotations

import numpy as np
import pytest
from support import reach_grid as grid
from support.data import MOCAP

from modb_kernel import reach

if not (MOCAP / "bandai-2-dev" / "data").exists():
    pytest.skip(f"Bandai's dataset 2 is not at {MOCAP / 'bandai-2-dev' / 'data'} (../shared/mocap "
                "beside the project, or set MODB_MOCAP)", allow_module_level=True)  # fmt: skip

MET_M = 0.01  # the bound (the solver aims at reach.REACHED_M, 1 mm)
JUMP_SHARE = 1.2  # of the source's p99.9 per-frame joint displacement (see BENCHMARKS)
HELD_OUT = {"right": 2, "left": 1, "both": 1}  # held-out clips tried per action


@pytest.fixture(scope="module", params=list(grid.ACTIONS))
def action(request):
    return grid.action(request.param)


def solve(motion, frame, targets, limits, **options):
    sk = motion.skeleton
    return reach.reach(sk.parents, sk.offsets, sk.translated, sk.names, sk.joint_map,
                       motion.rotations, motion.translations, frame, targets, limits=limits,
                       **options)  # fmt: skip


def grid_cases(action):
    """[(motion, keyframe, group, distance, targets)] over the held-out clips: each target of the
    grid, both sides at once for the both-hands raise (the same group on either side)."""
    out = []
    for motion in action.held_out[: HELD_OUT[action.name]]:
        frame = grid.keyframe(motion, action.sides)
        per_side = {s: action.targets(s) for s in action.sides}
        for k, (group, distance, _) in enumerate(per_side[action.sides[0]]):
            out.append((motion, frame, group, distance,
                        {s: per_side[s][k][2] for s in action.sides}))  # fmt: skip
    return out


def test_the_grid_is_met_where_reachable_and_the_pose_stays_natural(action):
    met_by_length = stopped_by_limits = 0
    for motion, frame, group, distance, targets in grid_cases(action):
        result = solve(motion, frame, targets, action.limits)
        seen = grid.checks(motion, result, action.sides, frame, targets, action.limits)
        where = f"{action.name} {group} {distance} m"
        for s in action.sides:
            # what it says is what the pose does
            assert seen["error"][s] == pytest.approx(result.after[s], abs=1e-6), where
            assert result.after[s] <= result.before[s] + 1e-9, where
            if result.met[s]:
                assert seen["error"][s] <= reach.REACHED_M + 1e-6 < MET_M, where
                assert result.nearest[s] is None
            else:
                nearest = np.asarray(result.nearest[s])
                wrist = grid.positions(motion, result.rotations)[
                    frame, grid.joint(motion, s, "wrist")
                ]
                assert np.abs(nearest - wrist).max() < 1e-6, where
                assert np.linalg.norm(nearest - targets[s]) == pytest.approx(result.after[s])
            if grid.reachable_by_length(motion, s, frame, targets[s]):
                if result.met[s]:
                    met_by_length += 1
                else:  # only the limits may stop it: a moved joint at its allowance
                    stopped_by_limits += 1
                    excess = grid.limit_excess_degrees(
                        motion,
                        action.limits,
                        result.rotations[frame : frame + 1],
                        [motion.skeleton.index(n) for n in result.joints],
                    )
                    assert excess.max() > grid.SLACK_DEGREES - 2.0, where
        if group == "out of reach":
            assert not result.reachable
            arm = grid.arm_length(motion, action.sides[0])
            assert min(result.after.values()) > grid.OUT_OF_REACH_M - arm - 0.3
        # natural: within the examples' range plus 10 degrees, elbows not reversed
        assert seen["past_range_deg"] <= grid.SLACK_DEGREES + 1e-6, where
        assert seen["least_bend_deg"] >= -0.01, where
        assert seen["bone_change_m"] < 1e-9, where
        assert seen["others_equal"], where
        # a hand sent 20-30 cm farther in the same time moves up to 16% faster than the clip's
        # fastest frame (its p99.9 is nearly its largest): allowed that much, a pop is not
        assert seen["jump_m"] <= JUMP_SHARE * seen["jump_bound_m"], where
        assert result.rotations[0].tobytes() == motion.rotations[0].tobytes()
        assert result.rotations[-1].tobytes() == motion.rotations[-1].tobytes()
    assert met_by_length >= 4 * max(stopped_by_limits, 1)  # the limits rarely stop a reach


def test_frames_outside_the_falloff_are_unchanged_and_the_change_fades(action):
    motion = action.held_out[0]
    frame = grid.keyframe(motion, action.sides)
    targets = {s: action.targets(s)[1][2] for s in action.sides}  # 10 cm above the box
    targets = {s: t - [0.0, 0.25, 0.0] for s, t in targets.items()}  # in reach
    result = solve(motion, frame, targets, action.limits, before=6, after=4)
    assert result.frames == (frame - 5, frame + 3)
    outside = np.r_[0 : frame - 5, frame + 4 : motion.n_frames]
    assert result.rotations[outside].tobytes() == motion.rotations[outside].tobytes()
    assert result.reachable
    moved = [motion.skeleton.index(n) for n in result.joints]
    change = np.abs(result.rotations[:, moved] - motion.rotations[:, moved]).max(axis=(1, 2))
    # the most at the keyframe, less and less away from it
    assert np.all(np.diff(change[frame - 6 : frame + 1]) >= -1e-12)
    assert np.all(np.diff(change[frame : frame + 5]) <= 1e-12)


def test_the_spine_helps_only_where_the_arm_falls_short():
    action = grid.action("right")
    motion = action.held_out[0]
    frame = grid.keyframe(motion, action.sides)
    inside = {"right": action.targets("right")[0][2]}
    alone = solve(motion, frame, inside, action.limits)
    spine = [motion.skeleton.index(n) for n in ("Spine", "Chest")]
    turned = grid.limit_excess_degrees(motion, action.limits, alone.rotations, spine)
    assert alone.reachable
    base = grid.limit_excess_degrees(motion, action.limits, motion.rotations, spine)
    assert np.abs(turned - base).max() < 2.0  # the arm meets it: the spine turns little
    far = {"right": [t for g, d, t in action.targets("right") if g == "front" and d == 0.2][0]}
    with_spine = solve(motion, frame, far, action.limits)
    without = solve(motion, frame, far, action.limits, spine=False)
    assert with_spine.after["right"] < without.after["right"]


def test_refuses_what_it_cannot_do():
    action = grid.action("right")
    motion = action.held_out[0]
    with pytest.raises(reach.ik.IKError, match="per side"):
        solve(motion, 10, {"middle": [0, 1, 0]}, action.limits)
    with pytest.raises(reach.ik.IKError, match="outside"):
        solve(motion, motion.n_frames, {"right": [0, 1, 0]}, action.limits)
    with pytest.raises(reach.ik.IKError, match="limits"):
        solve(motion, 10, {"right": [0, 1, 0]}, {"mean": [[1, 0, 0, 0]], "degrees": [1.0]})


def test_without_limits_the_elbow_still_bends_the_motions_way():
    action = grid.action("both")
    motion = action.held_out[1]  # its right arm is straight at times
    frame = grid.keyframe(motion, action.sides)
    for k, (group, distance, _) in enumerate(action.targets("right")):
        if group not in ("inside", "below", "front", "back"):
            continue
        targets = {s: action.targets(s)[k][2] for s in action.sides}
        result = solve(motion, frame, targets, None)
        seen = grid.checks(motion, result, action.sides, frame, targets, action.limits)
        assert seen["least_bend_deg"] >= -0.01, (group, distance)
        assert seen["bone_change_m"] < 1e-9
