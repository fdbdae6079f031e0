"""MotionTerminators and snippet descriptors: what the selection query compares, computed once per
clip.

Definitions (docs/querying.md "Snippets and terminators" documents them; tests re-derive them
independently):
- Heading: the forward direction (-l_z, 0, l_x) of the hip axis l = left_hip - right_hip (a
  character's +X is its left), averaged over a centred window of +-round(HEADING_HALF_WINDOW_S *
  fps) frames (cut at the clip's ends) because the pelvis yaws with every step; theta = atan2(f_x,
  f_z).
- Local heading frame of a frame: origin at the pelvis projected on the ground (y = 0), rotated by
  theta about +Y. Positions and velocities of the standard joints are expressed in it.
- Rotations: the pelvis's orientation in the heading frame (its tilt and residual yaw); every other
  joint's rotation relative to its parent.
- Velocities: central differences over the neighbouring frames (one-sided at the clip's ends), in
  the frame's heading frame. Angular velocity: the pelvis's world angular velocity in the heading
  frame; other joints' from their parent-relative rotations, in their own frame.
- Features (the GiST-indexed cube, physical units): pelvis height; head, wrists and ankles
  positions; pelvis and ankles velocities; the first two columns of the neck's, head's and wrists'
  rotation matrices (joints.FEATURES lists the 49 dimensions).
"""

import numpy as np

from . import kinematics, quaternion
from .joints import FEATURE_POSITIONS, FEATURE_ROTATIONS, FEATURE_VELOCITIES, STANDARD_JOINTS

HEADING_HALF_WINDOW_S = 0.25
# Frames computed at a time when a clip is cut into snippets: memory stays bounded whatever its
# length.
CHUNK_FRAMES = 2048


class SkeletonMapError(ValueError):
    pass


def standard_indices(names, joint_map):
    """Joint index of every standard joint; all must be mapped."""
    missing = [s for s in STANDARD_JOINTS if joint_map.get(s) not in names]
    if missing:
        raise SkeletonMapError("the joint map lacks " + ", ".join(missing))
    return [names.index(joint_map[s]) for s in STANDARD_JOINTS]


def _about_y(theta):
    return quaternion.about_axis("Y", theta)


def rotation_features(rotations):
    """The rotation part of the features: for each of joints.FEATURE_ROTATIONS, R e_x then R e_y of
    its rotation (rotations: (..., 19, 4) as stored, standard joint order)."""
    rotations = np.asarray(rotations, dtype=np.float64)
    columns = [
        quaternion.rotate(
            rotations[..., STANDARD_JOINTS.index(j), :], np.array(axis, dtype=np.float64)
        )
        for j in FEATURE_ROTATIONS
        for axis in ((1, 0, 0), (0, 1, 0))
    ]
    return np.concatenate(columns, axis=-1)


def _neighbours(n):
    """Indices (before, after) and their time span in frames, for central differences."""
    before = np.clip(np.arange(n) - 1, 0, n - 1)
    after = np.clip(np.arange(n) + 1, 0, n - 1)
    return before, after, np.maximum(after - before, 1)


def headings(positions, left_hip, right_hip, fps):
    hip_axis = positions[:, left_hip] - positions[:, right_hip]
    forward = np.stack([-hip_axis[:, 2], np.zeros(len(hip_axis)), hip_axis[:, 0]], axis=-1)
    forward /= np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), 1e-12)
    half = int(round(HEADING_HALF_WINDOW_S * fps))
    cumulative = np.vstack([np.zeros((1, 3)), np.cumsum(forward, axis=0)])
    lo = np.clip(np.arange(len(hip_axis)) - half, 0, len(hip_axis))
    hi = np.clip(np.arange(len(hip_axis)) + half + 1, 0, len(hip_axis))
    mean = cumulative[hi] - cumulative[lo]
    return np.arctan2(mean[:, 0], mean[:, 2])


def compute(parents, offsets, rotations, translations, translated, std, fps):
    """Per-frame terminator data for a whole clip (arrays over frames)."""
    rotations = np.asarray(rotations, dtype=np.float64)
    positions, orientations = kinematics.world_transforms(
        parents, offsets, rotations, translations, translated
    )
    n = len(rotations)
    pelvis = std[STANDARD_JOINTS.index("pelvis")]
    theta = headings(
        positions,
        std[STANDARD_JOINTS.index("left_hip")],
        std[STANDARD_JOINTS.index("right_hip")],
        fps,
    )
    h_inv = quaternion.conjugate(_about_y(theta))[:, None, :]
    ground = positions[:, pelvis] * np.array([1.0, 0.0, 1.0])
    world = positions[:, std]
    local_positions = quaternion.rotate(h_inv, world - ground[:, None, :])
    before, after, span = _neighbours(n)
    rate = (fps / span)[:, None, None]
    local_velocities = quaternion.rotate(h_inv, (world[after] - world[before]) * rate)

    canonical = quaternion.canonical(rotations)
    local_rotations = canonical[:, std]
    pelvis_s = STANDARD_JOINTS.index("pelvis")
    pelvis_local = quaternion.canonical(quaternion.multiply(h_inv[:, 0], orientations[:, pelvis]))
    local_rotations[:, pelvis_s] = pelvis_local
    angular = (
        quaternion.to_rotation_vector(
            quaternion.multiply(
                quaternion.conjugate(rotations[before][:, std]), rotations[after][:, std]
            )
        )
        * rate
    )
    pelvis_world = quaternion.to_rotation_vector(
        quaternion.multiply(
            orientations[after, pelvis], quaternion.conjugate(orientations[before, pelvis])
        )
    )
    angular[:, pelvis_s] = quaternion.rotate(h_inv[:, 0], pelvis_world * rate[:, 0])

    configuration = canonical.copy()
    configuration[:, pelvis] = pelvis_local
    ancestor = parents[pelvis]
    while ancestor >= 0:  # joints above the pelvis carry no pose of their own in the heading frame
        configuration[:, ancestor] = (1.0, 0.0, 0.0, 0.0)
        ancestor = parents[ancestor]

    idx = {s: k for k, s in enumerate(STANDARD_JOINTS)}
    features = np.concatenate(
        [local_positions[:, [pelvis_s], 1]]
        + [local_positions[:, idx[j]] for j in FEATURE_POSITIONS]
        + [local_velocities[:, idx[j]] for j in FEATURE_VELOCITIES]
        + [rotation_features(local_rotations)],
        axis=1,
    )
    return {
        "heading": theta,
        "pelvis": positions[:, pelvis],
        "pelvis_height": positions[:, pelvis, 1],
        "positions": local_positions,
        "rotations": local_rotations,
        "velocities": local_velocities,
        "angular_velocities": angular,
        "configuration": configuration,
        "features": features,
    }


def windows(n_frames, fps, window_s, stride_s):
    """(first frames, frames per snippet, stride): a snippet advances window_s seconds, starts every
    stride_s."""
    length = int(round(window_s * fps)) + 1
    stride = max(1, int(round(stride_s * fps)))
    return np.arange(0, max(n_frames - length + 1, 0), stride), length, stride


def snippet_rate_error(fps, window_s=0.5):
    """Why clips at this rate cannot be cut into snippets of window_s seconds (a window needs two
    frames), None when they can."""
    length = int(round(window_s * fps)) + 1
    if length >= 2:
        return None
    lowest = int(0.5 / window_s) + 1  # round() takes 0.5 to 0: more than half a frame is needed
    return (
        f"a {window_s:g} s snippet holds {length} frame at {fps:g} fps and snippets need 2: "
        f"use a rate of {lowest} fps or more"
    )


def chunks(n_frames, fps, firsts, length, chunk_frames=CHUNK_FRAMES):
    """Runs of the snippet starts `firsts` (ascending, evenly spaced) whose frames, with the margins
    the heading's window and the central differences reach, span about chunk_frames: yields (lo, hi,
    starts). compute() over frames lo..hi-1 gives at every frame of those snippets what it gives
    over the whole clip (to rounding: the heading's running sums start at lo)."""
    margin = int(round(HEADING_HALF_WINDOW_S * fps)) + 1
    stride = int(firsts[1] - firsts[0]) if len(firsts) > 1 else 1
    per_chunk = max(1, (chunk_frames - length - 2 * margin) // stride + 1)
    for i in range(0, len(firsts), per_chunk):
        starts = firsts[i : i + per_chunk]
        yield (
            max(0, int(starts[0]) - margin),
            min(n_frames, int(starts[-1]) + length + margin),
            starts,
        )


def net_motion(terms, first, last):
    """Net pelvis translation (in the first frame's heading frame) and heading change of frames
    first..last: for one snippet, or for many when first and last are arrays."""
    theta = terms["heading"]
    h_inv = quaternion.conjugate(_about_y(theta[first]))
    translation = quaternion.rotate(h_inv, terms["pelvis"][last] - terms["pelvis"][first])
    turn = np.angle(np.exp(1j * (theta[last] - theta[first])))
    return translation, turn, _about_y(turn)
