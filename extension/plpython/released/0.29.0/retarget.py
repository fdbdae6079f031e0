"""Retargeting between skeletons, after the DFKI motion database's Algorithm 1: each mapped joint
has a coordinate system of two axes, a twist axis (toward the joint it moves: the knee for the
hip) and a swing axis (across it); the destination joint's world rotation is the one that lays
its axes on the source joint's axes in the source's pose, parents first. Bone directions between
mapped joints are then the source's; lengths stay the destination's. The travel is the source
pelvis's, scaled by the legs' length ratio, and the clip is lifted or lowered so its lowest foot
is as high as the source's.

Axes are derived automatically (joint_axes): no T-pose is needed. Plain numpy (server and
client)."""

import numpy as np

from . import kinematics, quaternion

# Where each standard joint's twist axis points: the first of these joints lying away from it in the
# standing pose
# (None: along the joint's own children, its End Site, else on from its parent).
TWIST_TOWARD = {
    "pelvis": ("spine", "chest", "neck"),
    "spine": ("chest", "neck"),
    "chest": ("neck", "head"),
    "neck": ("head",),
    "head": None,
    "left_hip": ("left_knee",),
    "left_knee": ("left_ankle",),
    "left_ankle": ("left_toe",),
    "left_toe": None,
    "right_hip": ("right_knee",),
    "right_knee": ("right_ankle",),
    "right_ankle": ("right_toe",),
    "right_toe": None,
    "left_shoulder": ("left_elbow",),
    "left_elbow": ("left_wrist",),
    "left_wrist": None,
    "right_shoulder": ("right_elbow",),
    "right_elbow": ("right_wrist",),
    "right_wrist": None,
}
# The swing axis: the body's left (hip to hip) for the trunk and legs, its forward for the arms
# (which may point left in a T-pose or down in an A-pose; forward is across both), made square to
# the twist.
SWING_ALONG_FORWARD = {
    "left_shoulder",
    "left_elbow",
    "left_wrist",
    "right_shoulder",
    "right_elbow",
    "right_wrist",
}
MIN_BONE_M = 0.01  # a joint nearer than this to its target gives no direction
HINGE_MIN_BEND_DEGREES = 15  # an elbow or knee bent less than this shows no hinge axis
HINGE_MIN_FRAMES = 10


def _unit(v):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


def _children(parents, j):
    return [k for k, p in enumerate(parents) if p == j]


def _body_axes(positions, at):
    """The body's left, up and forward (world, unit) in a pose: hip to hip, pelvis to neck."""
    left = _unit(positions[at["left_hip"]] - positions[at["right_hip"]])
    up = positions[at["neck"] if "neck" in at else at["chest"]] - positions[at["pelvis"]]
    up = _unit(up - left * np.dot(up, left))
    return left, up, np.cross(left, up)


def upright(parents, offsets, names, joint_map):
    """Whether the rest pose stands: the trunk within 30 degrees of +Y and the ankles below the hips
    (Bandai's BVH rest pose folds every bone along +X, for one)."""
    rest = kinematics.rest_positions(parents, offsets)
    index = {n: i for i, n in enumerate(names)}
    at = {s: index[j] for s, j in joint_map.items() if j in index}
    _, up, _ = _body_axes(rest, at)
    legs = [rest[at[f"{side}_hip"], 1] - rest[at[f"{side}_ankle"], 1] for side in ("left", "right")]
    return bool(
        up[1] > np.cos(np.radians(30))
        and min(legs) > 0.5 * leg_length(parents, offsets, names, joint_map)
    )


def mean_rotations(rotations):
    """Per joint the mean of (frames, joints, 4) unit quaternions (Markley: the top eigenvector of
    sum q q^T), w >= 0."""
    m = np.einsum("fji,fjk->jik", rotations, rotations)
    return quaternion.canonical(np.linalg.eigh(m)[1][..., -1])


def _body_axes_all(positions, at):
    """Per frame the body's left and forward (world, unit): hip to hip; pelvis to neck for up."""
    left = _unit(positions[:, at["left_hip"]] - positions[:, at["right_hip"]])
    up = positions[:, at["neck"] if "neck" in at else at["chest"]] - positions[:, at["pelvis"]]
    up = _unit(up - left * np.sum(up * left, axis=-1, keepdims=True))
    return left, np.cross(left, up)


def joint_axes(parents, offsets, end_sites, names, joint_map, reference=None):
    """({standard name: {"joint", "twist", "swing"}}, pose) for every mapped standard joint: unit
    vectors in the joint's own frame, and the local rotations (joints, 4) of the pose they fit,
    which retarget() gives unmapped joints. From the rest pose, or from `reference` = (rotations
    (frames, joints, 4), translations (frames, translated, 3), translated) of captured frames: the
    twist points toward the mapped joint the joint moves (else its children or End Site) in the
    frames' mean pose; the swing is the body's left (trunk, legs) or forward (arms) seen from the
    joint, averaged over the frames (one frame's arm swing or roll would otherwise set it)."""
    index = {n: i for i, n in enumerate(names)}
    at = {s: index[j] for s, j in joint_map.items() if j in index}
    if reference is None:
        pose = np.tile([1.0, 0.0, 0.0, 0.0], (len(parents), 1))
        rotations, translations, translated = pose[None], np.zeros((1, 0, 3)), []
    else:
        rotations, translations, translated = reference
        rotations = np.asarray(rotations, dtype=np.float64).reshape(-1, len(parents), 4)
        translations = np.asarray(translations, dtype=np.float64).reshape(len(rotations), -1, 3)
        pose = mean_rotations(rotations)
    still = (pose[None], translations.mean(axis=0)[None], translated)
    positions, orientations = (x[0] for x in kinematics.world_transforms(parents, offsets, *still))
    frame_positions, frame_orientations = kinematics.world_transforms(
        parents, offsets, rotations, translations, translated
    )
    left, forward = _body_axes_all(frame_positions, at)
    hinges = {}  # a limb's hinge axis (upper cross lower) per frame, where it bends enough to tell
    for side in ("left", "right"):
        for limb, (top, middle, end) in (("arm", ("shoulder", "elbow", "wrist")),
                                          ("leg", ("hip", "knee", "ankle"))):  # fmt: skip
            names_ = [f"{side}_{n}" for n in (top, middle, end)]
            if all(n in at for n in names_):
                upper = _unit(frame_positions[:, at[names_[1]]] - frame_positions[:, at[names_[0]]])
                lower = _unit(frame_positions[:, at[names_[2]]] - frame_positions[:, at[names_[1]]])
                axis = np.cross(upper, lower)
                bent = np.linalg.norm(axis, axis=-1) > np.sin(np.radians(HINGE_MIN_BEND_DEGREES))
                if bent.sum() >= HINGE_MIN_FRAMES:
                    hinges[(side, limb)] = (_unit(axis), bent)
    out = {}
    for standard, toward in TWIST_TOWARD.items():
        if standard not in at:
            continue
        j = at[standard]
        twist = None
        for target in (t for t in toward or () if t in at):
            ahead = positions[at[target]] - positions[j]  # through unmapped joints in this pose
            if np.linalg.norm(ahead) > MIN_BONE_M:
                twist = quaternion.rotate(quaternion.conjugate(orientations[j]), ahead)
                break
        if twist is None:
            ahead = [np.asarray(offsets[k], dtype=np.float64) for k in _children(parents, j)]
            if end_sites[j] is not None:
                ahead.append(np.asarray(end_sites[j], dtype=np.float64))
            ahead = [v for v in ahead if np.linalg.norm(v) > MIN_BONE_M]
            twist = (
                np.mean([_unit(v) for v in ahead], axis=0)
                if ahead
                else np.asarray(offsets[j], dtype=np.float64)
            )
        twist = _unit(twist)
        seen = quaternion.conjugate(frame_orientations[:, j])  # world into the joint's frame
        side, _, part = standard.partition("_")
        limb = "arm" if part in ("shoulder", "elbow", "wrist") else "leg" if part else None
        swing = np.zeros(3)
        if (side, limb) in hinges:  # the limb's own hinge: the same anatomy whatever the rig
            axis, bent = hinges[(side, limb)]
            mean = quaternion.rotate(seen[bent], axis[bent]).mean(axis=0)
            swing = mean - twist * np.dot(mean, twist)
        if np.linalg.norm(swing) < 0.1:
            for across in (forward, left) if standard in SWING_ALONG_FORWARD else (left, forward):
                mean = quaternion.rotate(seen, across).mean(axis=0)
                swing = mean - twist * np.dot(mean, twist)
                if np.linalg.norm(swing) >= 0.1:  # else the twist lies along it: the other axis
                    break
        out[standard] = {"joint": names[j], "twist": twist.tolist(), "swing": _unit(swing).tolist()}
    return out, pose


class RetargetError(ValueError):
    """A skeleton that cannot be retargeted to or from, and what to do."""


NEEDED = ("pelvis", "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle",
          "left_toe", "right_toe")  # fmt: skip


def skeleton(hierarchy, joint_map, joint_axes=None, mirror_pairs=()):
    """What retarget() (and an edit script) needs of a skeleton, from its modb.skeletons row."""
    joints = hierarchy["joints"]
    return {
        "parents": [j["parent"] for j in joints],
        "offsets": np.array([j["offset"] for j in joints], dtype=np.float64),
        "end_sites": [j.get("end_site") for j in joints],
        "names": [j["name"] for j in joints],
        "joint_map": dict(joint_map),
        "translated": list(hierarchy.get("translated", [])),
        "stored_axes": joint_axes or {},
        "mirror_pairs": [list(p) for p in mirror_pairs],
    }


def with_axes(sk, reference=None):
    """The skeleton with its axes and the pose they fit: its stored joint_axes when it has them,
    else derived from `reference` = (rotations, translations) of captured frames (a clip of this
    skeleton), else from its rest pose when it stands."""
    missing = [s for s in NEEDED if s not in sk["joint_map"]]
    if missing:
        raise RetargetError(f"its joint map lacks {', '.join(missing)}: complete it first")
    stored = sk["stored_axes"]
    identity = np.tile([1.0, 0.0, 0.0, 0.0], (len(sk["parents"]), 1))
    if stored.get("joints"):
        pose = (
            identity if stored.get("pose") is None else np.asarray(stored["pose"], dtype=np.float64)
        )
        return dict(sk, axes=stored["joints"], pose=pose)
    frames = None if reference is None else (reference[0], reference[1], sk["translated"])
    if frames is None and not upright(sk["parents"], sk["offsets"], sk["names"], sk["joint_map"]):
        raise RetargetError(
            "its rest pose does not stand and it has no clip to take a standing pose from: load "
            "one first, or store its joint_axes"
        )
    axes, pose = joint_axes(
        sk["parents"], sk["offsets"], sk["end_sites"], sk["names"], sk["joint_map"], frames
    )
    return dict(sk, axes=axes, pose=pose)


def stored_form(sk):
    """The skeleton's axes as modb.skeletons.joint_axes keeps them."""
    identity = np.allclose(sk["pose"], [1.0, 0.0, 0.0, 0.0])
    return {"joints": sk["axes"], "pose": None if identity else np.round(sk["pose"], 9).tolist()}


def _frame(twist, swing):
    """Rotation matrices (..., 3, 3): columns twist, swing (made square) and their cross."""
    t = _unit(twist)
    s = _unit(swing - t * np.sum(swing * t, axis=-1, keepdims=True))
    return np.stack([t, s, np.cross(t, s)], axis=-1)


def _arc(a, b):
    """Per row the shortest rotation taking unit vector a onto unit vector b (a quarter turn about
    any axis square to a where they are opposite)."""
    a, b = np.broadcast_arrays(_unit(a), _unit(b))
    w = 1.0 + np.sum(a * b, axis=-1, keepdims=True)
    axis = np.cross(a, b)
    opposite = w[..., 0] < 1e-9
    if opposite.any():
        other = np.where(np.abs(a[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
        axis = np.where(opposite[..., None], np.cross(a, other), axis)
    return _unit(np.concatenate([w, axis], axis=-1))


def _chain_bend(standard, j, at, now, was):
    """Per frame, the rotation in joint j's own frame that takes its direction toward the next
    mapped joint in the axes' pose (`was`) onto that direction in the frame (`now`): the bend of
    the unmapped joints between them (CMU's upper back and thorax between its spine and chest),
    which j's own rotation does not show. now, was: (positions, orientations) in world; None where
    the next mapped joint is j's own child."""
    for target in (t for t in TWIST_TOWARD.get(standard) or () if t in at):
        ahead = was[0][at[target]] - was[0][j]
        if np.linalg.norm(ahead) > MIN_BONE_M:
            return _arc(
                quaternion.rotate(quaternion.conjugate(was[1][j]), ahead),
                quaternion.rotate(
                    quaternion.conjugate(now[1][:, j]), now[0][:, at[target]] - now[0][:, j]
                ),
            )
    return None


def leg_length(parents, offsets, names, joint_map):
    rest = kinematics.rest_positions(parents, offsets)
    index = {n: i for i, n in enumerate(names)}

    def at(s):
        return rest[index[joint_map[s]]]

    return np.mean(
        [
            np.linalg.norm(at(f"{side}_hip") - at(f"{side}_knee"))
            + np.linalg.norm(at(f"{side}_knee") - at(f"{side}_ankle"))
            for side in ("left", "right")
        ]
    )


def _feet(skeleton):
    index = {n: i for i, n in enumerate(skeleton["names"])}
    return [
        index[skeleton["joint_map"][f"{side}_{part}"]]
        for side in ("left", "right")
        for part in ("ankle", "toe")
    ]


def retarget(source, destination, rotations, translations):
    """The source's frames on the destination skeleton: (rotations, translations) as the destination
    stores them. source and destination: dicts with parents, offsets, end_sites, names, joint_map,
    translated (indices of joints with position channels), axes (joint_axes(...)) and pose (the
    local
    rotations (joints, 4) of the pose the axes came from); rotations and translations: the source's
    frames."""
    legs = {}
    for role, sk in (("source", source), ("destination", destination)):
        legs[role] = leg_length(sk["parents"], sk["offsets"], sk["names"], sk["joint_map"])
        if not np.isfinite(legs[role]) or legs[role] <= 1e-6:
            raise RetargetError(
                f"the {role} skeleton's legs have no length (its hip, knee and ankle joints sit at "
                "one point), and the travel is scaled by the legs' length ratio: map joints with "
                "offsets, or retarget from and to a skeleton whose legs have length"
            )
    src_pos, src_rot = kinematics.world_transforms(
        source["parents"], source["offsets"], rotations, translations, source["translated"]
    )
    n_frames = src_rot.shape[0]
    s_translations = np.asarray(translations, dtype=np.float64).reshape(
        n_frames, len(source["translated"]), 3
    )
    src_pose = [
        x[0]
        for x in kinematics.world_transforms(
            source["parents"],
            source["offsets"],
            np.asarray(source["pose"], dtype=np.float64)[None],
            s_translations.mean(axis=0)[None],
            source["translated"],
        )
    ]
    d_parents, d_offsets = (
        destination["parents"],
        np.asarray(destination["offsets"], dtype=np.float64),
    )
    d_index = {n: i for i, n in enumerate(destination["names"])}
    s_index = {n: i for i, n in enumerate(source["names"])}
    s_at = {s: s_index[j] for s, j in source["joint_map"].items() if j in s_index}
    mapped = {
        d_index[a["joint"]]: (standard, a)
        for standard, a in destination["axes"].items()
        if standard in source["axes"]
    }
    world = np.empty((n_frames, len(d_parents), 4))
    local = np.empty_like(world)
    for j, p in enumerate(d_parents):
        if j in mapped:
            standard, axes = mapped[j]
            s_axes = source["axes"][standard]
            sj = s_index[s_axes["joint"]]
            g = src_rot[:, sj]
            bend = _chain_bend(standard, sj, s_at, (src_pos, src_rot), src_pose)
            if bend is not None:  # the source's axes follow its chain to the next mapped joint
                g = quaternion.multiply(g, bend)
            target = _frame(
                quaternion.rotate(g, np.asarray(s_axes["twist"])),
                quaternion.rotate(g, np.asarray(s_axes["swing"])),
            )
            rest = _frame(np.asarray(axes["twist"]), np.asarray(axes["swing"]))
            world[:, j] = quaternion.from_matrix(target @ rest.T)
            local[:, j] = (
                world[:, j]
                if p < 0
                else quaternion.multiply(quaternion.conjugate(world[:, p]), world[:, j])
            )
        else:  # unmapped joints keep the standing pose's rotation (joint_axes' reference)
            local[:, j] = destination["pose"][j]
            world[:, j] = local[:, j] if p < 0 else quaternion.multiply(world[:, p], local[:, j])
    local = quaternion.canonical(local)
    d_translated = list(destination["translated"])
    d_trans = np.broadcast_to(d_offsets[d_translated], (n_frames, len(d_translated), 3)).copy()

    # The travel: the destination pelvis where the source pelvis is, scaled by the legs' ratio.
    scale = legs["destination"] / legs["source"]
    pelvis = d_index[destination["joint_map"]["pelvis"]]
    goal = src_pos[:, s_index[source["joint_map"]["pelvis"]]] * scale
    carrier = pelvis
    while carrier >= 0 and carrier not in d_translated:
        carrier = d_parents[carrier]
    if carrier >= 0:
        k = d_translated.index(carrier)
        positions = kinematics.world_positions(d_parents, d_offsets, local, d_trans, d_translated)
        parent_rot = (
            world[:, d_parents[carrier]]
            if d_parents[carrier] >= 0
            else np.tile([1.0, 0.0, 0.0, 0.0], (n_frames, 1))
        )
        d_trans[:, k] += quaternion.rotate(
            quaternion.conjugate(parent_rot), goal - positions[:, pelvis]
        )
        # Feet on the floor: the lowest foot joint over the clip as high as the source's, scaled.
        positions = kinematics.world_positions(d_parents, d_offsets, local, d_trans, d_translated)
        lowest = positions[:, _feet(destination), 1].min()
        wanted = src_pos[:, _feet(source), 1].min() * scale
        d_trans[:, k] += quaternion.rotate(
            quaternion.conjugate(parent_rot), np.array([0.0, wanted - lowest, 0.0])
        )
    return local, d_trans
