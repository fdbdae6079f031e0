"""Pose edits (issue 64): the edit-script commands `ik` (move a joint to a target at one instant)
and `rotate` (turn a joint there), each change spread over the frames around that instant by the
DFKI motion editor's cubic B-spline falloff (ik.falloff, ik.spread_from); frames outside the range
keep their rotations byte for byte, and no translation ever changes (bone lengths are kept).

  {"op": "ik", "joint": "right_wrist", "time": 1.2, "offset": [0.0, 0.1, 0.05],
   "orientation": [0, 0, 30], "chain": 3, "before": 0.5, "after": 0.5}
  {"op": "rotate", "joint": "left_elbow", "time": 1.2, "rotation": [0, 0, -20],
   "before": 0.5, "after": 0.5}

- joint: a standard joint name (joints.STANDARD_JOINTS: pelvis, left_wrist, right_ankle, ...),
  found through the skeleton's joint map, so a script replays on any skeleton that maps it.
- time: seconds from the clip's first frame; the frame nearest it, round(time * fps), is edited.
- before, after: seconds (0 to 10): the change is whole at that frame and falls smoothly to nothing
  this long before and after it (0: that side is not touched).
- offset (ik): metres [x, y, z] (each from -2 to 2) from where the joint is at that frame, in the
  character's heading frame there (x: its left, y: up, z: forward; the heading of
  terminators.headings: the hips' axis averaged over +-0.25 s), so the same script moves a hand
  forward whichever way the character faces, on any clip.
- orientation (ik, optional): degrees (each from -360 to 360), a rotation vector [rx, ry, rz] in
  the same heading frame: the joint's world orientation is turned by it; without it the joint keeps
  its world orientation (a dragged hand or foot is not turned by the arm's or leg's change).
- chain (ik, optional): how many joints above the joint may turn (1 to 10); by default its ancestors
  up to the nearest joint with more than one child, exclusive (a wrist: forearm, upper arm and
  clavicle; an ankle: shin and thigh). Never the skeleton's top joint nor the pelvis: the body's
  travel and facing stay as they were.
- rotation (rotate): degrees (each from -360 to 360), a rotation vector [rx, ry, rz] in the
  joint's parent frame: the joint's local rotation at the frame becomes this rotation times the
  original (q_rot * q_joint), the frames around it turned by a share of it (the same axis, the
  shorter way round).

The IK at the frame is the kernel's chain solver (ik.solve, the one the actions' arm uses): least
squares of the joint's position over the chain's turns, each turn a rotation vector in its joint's
own frame, an elbow or a knee (the joint map's) turned only about the axis the motion itself bends
it about (ik.hinge_axis), so the limb bends as a hinge; each turn costs a little (TURN_COST), so
the smallest turns that meet the target win. A target the chain cannot reach ends at the nearest
point it reaches; edit() returns that point and its distance (a note), and the edit is kept.
"""

import math

import numpy as np

from . import kinematics, quaternion, terminators

# ik (scipy's BSpline) is imported where a pose is edited: edits.py, which checks every script
# saved, imports this module for its parameters alone.

REACHED_M = 1e-3  # a target counts as met within this distance
LIMB_MIDDLES = ("left_knee", "right_knee", "left_elbow", "right_elbow")  # hinges when in a chain
# What a chain's joints' turns cost (metres per radian, as reach.REGULARIZE): the two nearest the
# end (a limb's middle and root: elbow and shoulder, knee and hip) least, those above (a clavicle,
# CMU's hip bone) three times as much, as people reach with the arm before the shoulder.
TURN_COST = {"near": 1e-3, "far": 3e-3}

OFFSET_M = 2.0  # an ik offset's components are from -2 to 2 metres
MOST_DEGREES = 360.0  # rotation vectors' components (ik's orientation, rotate's rotation): degrees
CHAIN_RANGE = (1, 10)
BLEND_RANGE = (0.0, 10.0)  # before, after: seconds
TIME_RANGE = (0.0, 86400.0)

PARAMETERS = {
    "ik": {
        "joint": ("joint", True),
        "time": (TIME_RANGE, True),
        "offset": ("offset", True),
        "orientation": ("degrees", False),
        "chain": ("chain", False),
        "before": (BLEND_RANGE, True),
        "after": (BLEND_RANGE, True),
    },
    "rotate": {
        "joint": ("joint", True),
        "time": (TIME_RANGE, True),
        "rotation": ("degrees", True),
        "before": (BLEND_RANGE, True),
        "after": (BLEND_RANGE, True),
    },
}


class PoseEditError(ValueError):
    """A pose edit that cannot run on this clip, and why (edits.EditError wraps it)."""


def _number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def parameter_error(op, key, kind):
    """Why a value of the kinds this module adds is refused, as a function of the value (None: it
    is not one of them)."""
    if kind == "joint":
        return lambda v: None if isinstance(v, str) and 0 < len(v) <= 100 else (
            f'{op}: "{key}" must be a standard joint name, e.g. "right_wrist" or "left_ankle"')
    if kind == "chain":
        low, high = CHAIN_RANGE
        return lambda v: None if (isinstance(v, int) and not isinstance(v, bool)
                                  and low <= v <= high) else (
            f'{op}: "{key}" must be how many joints above the joint may turn, {low} to {high}')
    if kind in ("offset", "degrees"):
        most, what = (OFFSET_M, "metres") if kind == "offset" else (MOST_DEGREES, "degrees")
        frame = "the joint's parent frame" if key == "rotation" else (
            "the character's heading frame (x: its left, y: up, z: forward)")

        def check(v):
            ok = isinstance(v, list) and len(v) == 3 and all(_number(x) for x in v)
            if ok and all(-most <= x <= most for x in v):
                return None
            return (f'{op}: "{key}" must be 3 numbers [x, y, z] from {-most:g} to {most:g} '
                    f"{what}, in {frame}")

        return check
    return None


def skeleton_joint(sk, standard, op="ik"):
    """The index of the skeleton's joint the joint map names for a standard name."""
    name = sk["joint_map"].get(standard) if isinstance(standard, str) else None
    if name not in sk["names"]:
        known = ", ".join(s for s, n in sk["joint_map"].items() if n in sk["names"])
        raise PoseEditError(f'{op}: "joint" must be a standard joint name of the skeleton\'s joint '
                            f"map ({known}), got {standard!r}")
    return sk["names"].index(name)


def frame_at(clip, command):
    """The frame nearest the command's time; refused outside the clip."""
    n, fps = clip["rotations"].shape[0], float(clip["fps"])
    time = command.get("time")
    last = (n - 1) / fps
    if not _number(time) or not 0 <= time <= last + 0.5 / fps:
        raise PoseEditError(f'{command.get("op")}: "time" must be within the clip: seconds from '
                            f"0 to {last:.3f} ({n} frames at {fps:g} fps), got {time!r}")
    return min(int(round(time * fps)), n - 1)


def weights(clip, command, frame):
    """The falloff (frames,): 1 at the frame, 0 `before` and `after` seconds away and past."""
    from . import ik

    fps = float(clip["fps"])
    return ik.falloff(clip["rotations"].shape[0], frame, float(command["before"]) * fps,
                      float(command["after"]) * fps)  # fmt: skip


def default_chain(parents, joint, fixed):
    """The joint's ancestors up to the nearest one with more than one child (exclusive), nearest
    first, none of `fixed`."""
    children = np.bincount([p for p in parents if p >= 0], minlength=len(parents))
    out, j = [], parents[joint]
    while j >= 0 and children[j] == 1 and j not in fixed:
        out.append(j)
        j = parents[j]
    return out


def chain_of(sk, joint, count=None):
    """The joints ik may turn for a joint, nearest first: `count` ancestors (fewer where the top
    joint or the pelvis comes first), or default_chain's."""
    parents = sk["parents"]
    fixed = {j for j, p in enumerate(parents) if p < 0}
    pelvis = sk["joint_map"].get("pelvis")
    if pelvis in sk["names"]:
        fixed.add(sk["names"].index(pelvis))
    if count is None:
        return default_chain(parents, joint, fixed)
    out, j = [], parents[joint]
    while j >= 0 and j not in fixed and len(out) < count:
        out.append(j)
        j = parents[j]
    return out


def _heading_turn(clip, frame):
    """The rotation about +Y taking the character's heading frame at the frame to the world."""
    sk = clip["skeleton"]
    at = sk["joint_map"]
    if at.get("left_hip") not in sk["names"] or at.get("right_hip") not in sk["names"]:
        raise PoseEditError("ik: the skeleton's joint map lacks left_hip or right_hip: the heading "
                            "frame of the offset is taken from them")
    fps = float(clip["fps"])
    half = int(round(terminators.HEADING_HALF_WINDOW_S * fps))
    n = clip["rotations"].shape[0]
    lo, hi = max(0, frame - half), min(n, frame + half + 1)
    positions = kinematics.world_positions(sk["parents"], sk["offsets"], clip["rotations"][lo:hi],
                                           clip["translations"][lo:hi], sk["translated"])
    theta = terminators.headings(positions, sk["names"].index(at["left_hip"]),
                                 sk["names"].index(at["right_hip"]), fps)[frame - lo]
    return quaternion.about_axis("Y", theta)


def _spread(clip, frame, changed_pose, joints, falloff):
    from . import ik

    rotations = clip["rotations"]
    out = ik.spread_from(rotations, frame, changed_pose, joints, falloff)
    untouched = falloff <= 0.0
    out[untouched] = rotations[untouched]  # byte for byte
    return out


def _changed_frames(falloff):
    moved = np.flatnonzero(falloff > 0.0)
    return [int(moved[0]), int(moved[-1])]


def rotate(clip, command):
    """(clip, note): the `rotate` command (see the module's docstring)."""
    sk = clip["skeleton"]
    joint = skeleton_joint(sk, command["joint"], "rotate")
    frame = frame_at(clip, command)
    falloff = weights(clip, command, frame)
    turn = quaternion.from_rotation_vector(np.radians(np.asarray(command["rotation"], float)))
    pose = np.array(clip["rotations"][frame], dtype=np.float64)
    pose[joint] = quaternion.canonical(quaternion.multiply(turn, pose[joint]))
    rotations = _spread(clip, frame, pose, [joint], falloff)
    note = {"op": "rotate", "joint": command["joint"], "skeleton_joint": sk["names"][joint],
            "frame": frame, "frames": _changed_frames(falloff)}  # fmt: skip
    return dict(clip, rotations=rotations), note


def inverse_kinematics(clip, command):
    """(clip, note): the `ik` command (see the module's docstring). The note: the joint, the frame
    edited and the first and last frames changed, the chain's joints, the target and the point
    reached (world metres, at the frame), their distance (distance_m), whether it is met (within
    REACHED_M) and, when it is not, a message saying so."""
    from . import ik

    sk = clip["skeleton"]
    parents = sk["parents"]
    joint = skeleton_joint(sk, command["joint"], "ik")
    frame = frame_at(clip, command)
    joints = chain_of(sk, joint, command.get("chain"))
    if not joints:
        raise PoseEditError(f'ik: no joint above {command["joint"]} may turn (the pelvis and the '
                            "top joint stay): use rotate")
    rotations, translations = clip["rotations"], clip["translations"]
    local = ik.local_offsets(sk["offsets"], sk["translated"], translations)
    by_name = {sk["names"].index(n): s for s, n in sk["joint_map"].items() if n in sk["names"]}
    hinges = {}
    if len(joints) > 1 and by_name.get(joints[0]) in LIMB_MIDDLES:
        axis = ik.hinge_axis(rotations, local, joints[0], joint)
        if axis is not None:
            hinges[joints[0]] = axis
    heading = _heading_turn(clip, frame)
    pose = np.array(rotations[frame], dtype=np.float64)
    cost = {j: TURN_COST["near" if k < 2 else "far"] for k, j in enumerate(joints)}
    turns = ik.Turns(parents, local[frame], pose, joints, [joint], hinges, cost)
    start_pos, start_ori = kinematics.world_transforms(
        parents, sk["offsets"], pose[None], translations[frame:frame + 1], sk["translated"])
    offset = quaternion.rotate(heading, np.asarray(command["offset"], dtype=np.float64))
    target = start_pos[0, joint] + offset
    solved, _ = ik.solve(turns, target[None])
    # the joint's own rotation: its world orientation kept, or turned by `orientation`
    world = start_ori[0, joint]
    if "orientation" in command:
        turn = np.radians(np.asarray(command["orientation"], dtype=np.float64))
        world = quaternion.multiply(
            quaternion.from_rotation_vector(quaternion.rotate(heading, turn)), world)
    _, solved_ori = kinematics.world_transforms(
        parents, sk["offsets"], solved[None], translations[frame:frame + 1], sk["translated"])
    solved[joint] = quaternion.canonical(
        quaternion.multiply(quaternion.conjugate(solved_ori[0, parents[joint]]), world))
    falloff = weights(clip, command, frame)
    moved = joints + [joint]
    out = _spread(clip, frame, solved, moved, falloff)
    reached = kinematics.world_positions(parents, sk["offsets"], out[frame:frame + 1],
                                         translations[frame:frame + 1], sk["translated"])[0, joint]
    distance = float(np.linalg.norm(reached - target))
    note = {
        "op": "ik",
        "joint": command["joint"],
        "skeleton_joint": sk["names"][joint],
        "frame": frame,
        "frames": _changed_frames(falloff),
        "chain": [sk["names"][j] for j in reversed(joints)],
        "target": [float(x) for x in target],
        "reached": [float(x) for x in reached],
        "distance_m": distance,
        "met": distance <= REACHED_M,
    }
    if not note["met"]:
        note["message"] = (f'ik: {command["joint"]} at frame {frame}: the target is out of the '
                           f"chain's reach ({', '.join(note['chain'])}): the nearest point it "
                           f"reaches is used, {distance * 1000:.1f} mm from the target")
    return dict(clip, rotations=out), note


EDITS = {"ik": inverse_kinematics, "rotate": rotate}


def edit(clip, command):
    """(clip, note): one pose edit whose parameters edits.script_errors has checked (their types
    and ranges: PARAMETERS); a PoseEditError says why it cannot run on this clip."""
    return EDITS[command["op"]](clip, command)
