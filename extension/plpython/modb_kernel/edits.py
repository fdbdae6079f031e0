"""Edit scripts: JSON lists of commands that turn a clip's frames into new frames, re-playable on
any clip (modb.edit_scripts; modb.apply_edit_script and `modb edit apply` run them, each result a
new version). A clip here is a dict: skeleton (retarget.skeleton(...)), fps, rotations (F, J, 4)
and translations (F, K, 3). Plain numpy (server and client).

Commands ("op" and its fields):
  mirror                                  the clip as if captured in a mirror (mirror pairs needed)
  trim        start, end                  frames start..end (0-based, inclusive)
  smooth      seconds                     a Gaussian of that standard deviation over time:
                                          rotations by weighted quaternion means (Markley),
                                          translations linearly
  resample    fps                         the same motion at another frame rate
  time_stretch factor                     factor times as long (2: half speed), same frame rate
  copy_joints clip, joints, start, end,   those joints' rotations from frames of another clip (same
              [source_start], [blend]     skeleton) over start..end, slerped in and out over `blend`
                                          frames at both ends
  retarget    skeleton                    onto another skeleton (the result is on that skeleton)
"""

import math

import numpy as np

from . import mirror as mirroring
from . import quaternion, resample, retarget


class EditError(ValueError):
    """A command that cannot run on this clip, and why."""


def _number(command, key, low, high):
    value = command.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not low <= value <= high:
        raise EditError(f'{command.get("op")}: "{key}" must be a number from {low} to {high}')
    return float(value)


def _frame(command, key, n_frames, default=None):
    value = command.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < n_frames:
        raise EditError(f'{command.get("op")}: "{key}" must be a frame from 0 to {n_frames - 1}')
    return value


def gaussian_weights(sigma_frames):
    """Normalised weights at offsets -r..r, r = int(3 sigma + 0.5) (scipy.ndimage's radius)."""
    radius = int(3.0 * sigma_frames + 0.5)
    offsets = np.arange(-radius, radius + 1, dtype=np.float64)
    weights = np.exp(-0.5 * (offsets / sigma_frames) ** 2)
    return offsets.astype(int), weights / weights.sum()


def smooth_rotations(rotations, weights_at):
    """Each frame's rotation the weighted mean (Markley: the top eigenvector of sum w q q^T) of its
    neighbours', the clip's ends repeated."""
    offsets, weights = weights_at
    n = rotations.shape[0]
    m = np.zeros(rotations.shape[:-1] + (4, 4))
    for k, w in zip(offsets, weights):
        q = rotations[np.clip(np.arange(n) + k, 0, n - 1)]
        m += w * q[..., :, None] * q[..., None, :]
    return quaternion.canonical(np.linalg.eigh(m)[1][..., -1])


def smooth_values(values, weights_at):
    offsets, weights = weights_at
    n = values.shape[0]
    return sum(w * values[np.clip(np.arange(n) + k, 0, n - 1)] for k, w in zip(offsets, weights))


def _copy_joints(clip, command, fetch):
    other = fetch(command.get("clip"))
    if other is None:
        raise EditError(f"copy_joints: no clip {command.get('clip')}")
    names = clip["skeleton"]["names"]
    if other["skeleton"]["names"] != names:
        raise EditError("copy_joints: the other clip is on another skeleton (retarget it first)")
    joints = command.get("joints")
    if not isinstance(joints, list) or not joints or any(j not in names for j in joints):
        raise EditError(f"copy_joints: joints must be a list of this skeleton's joints: {names}")
    n = clip["rotations"].shape[0]
    start, end = _frame(command, "start", n), _frame(command, "end", n)
    if end < start:
        raise EditError("copy_joints: end comes before start")
    source_start = _frame(command, "source_start", other["rotations"].shape[0], start)
    if source_start + (end - start) >= other["rotations"].shape[0]:
        raise EditError("copy_joints: the other clip ends before the range does")
    blend = int(_number(command, "blend", 0, 10000)) if "blend" in command else 0
    frames = np.arange(start, end + 1)
    # weight 1 inside, ramping from 0 over `blend` frames at both ends (smooth step)
    ramp = np.ones(len(frames))
    if blend:
        edge = np.minimum(frames - start + 1, end + 1 - frames) / (blend + 1)
        ramp = np.where(edge < 1, 0.5 - 0.5 * np.cos(np.pi * np.minimum(edge, 1)), 1.0)
    index = [names.index(j) for j in joints]
    rotations = clip["rotations"].copy()
    own = rotations[start : end + 1][:, index]
    theirs = other["rotations"][source_start : source_start + len(frames)][:, index]
    theirs = np.where(np.sum(own * theirs, axis=-1, keepdims=True) < 0, -theirs, theirs)
    step = quaternion.multiply(quaternion.conjugate(own), theirs)
    rotations[start : end + 1, index] = quaternion.canonical(
        quaternion.multiply(own, quaternion.power(step, ramp[:, None, None]))
    )
    return dict(clip, rotations=rotations)


def apply_command(clip, command, fetch, fetch_skeleton):
    """One command on a clip; fetch(clip_id) -> clip (copy_joints), fetch_skeleton(id) -> (skeleton,
    a reference frame or None) (retarget)."""
    if not isinstance(command, dict) or not isinstance(command.get("op"), str):
        raise EditError('each command is an object with an "op"')
    op = command["op"]
    n = clip["rotations"].shape[0]
    sk = clip["skeleton"]
    if op == "mirror":
        if not sk.get("mirror_pairs"):
            raise EditError("mirror: the skeleton has no mirror pairs")
        partner = mirroring.partner_index(sk["names"], sk["mirror_pairs"])
        r, t = mirroring.mirror(
            sk["parents"], sk["offsets"], sk["end_sites"], partner,
            clip["rotations"], clip["translations"], sk["translated"],
        )  # fmt: skip
        return dict(clip, rotations=r, translations=t)
    if op == "trim":
        start, end = _frame(command, "start", n), _frame(command, "end", n)
        if end < start:
            raise EditError("trim: end comes before start")
        return dict(clip, rotations=clip["rotations"][start : end + 1],
                    translations=clip["translations"][start : end + 1])  # fmt: skip
    if op == "smooth":
        sigma = _number(command, "seconds", 1e-3, 10.0) * clip["fps"]
        weights = gaussian_weights(sigma)
        return dict(clip, rotations=smooth_rotations(clip["rotations"], weights),
                    translations=smooth_values(clip["translations"], weights))  # fmt: skip
    if op == "resample":
        fps = _number(command, "fps", 1.0, 1000.0)
        frames = resample.fps_frames(n, clip["fps"], fps)
        r, t = resample.sampled(clip["rotations"], clip["translations"], frames)
        return dict(clip, rotations=r, translations=t, fps=fps)
    if op == "time_stretch":
        factor = _number(command, "factor", 0.05, 20.0)
        frames = np.arange(int(math.floor((n - 1) * factor + 1e-9)) + 1) / factor
        r, t = resample.sampled(clip["rotations"], clip["translations"], frames)
        return dict(clip, rotations=r, translations=t)
    if op == "copy_joints":
        return _copy_joints(clip, command, fetch)
    if op == "retarget":
        found = fetch_skeleton(command.get("skeleton"))
        if found is None:
            raise EditError(f"retarget: no skeleton {command.get('skeleton')}")
        destination, reference = found
        try:
            source = retarget.with_axes(sk, (clip["rotations"], clip["translations"]))
            target = retarget.with_axes(destination, reference)
        except retarget.RetargetError as e:
            raise EditError(f"retarget: {e}") from None
        r, t = retarget.retarget(source, target, clip["rotations"], clip["translations"])
        return dict(clip, skeleton=destination, rotations=r, translations=t)
    raise EditError(f'unknown command "{op}": mirror, trim, smooth, resample, time_stretch, '
                    "copy_joints or retarget")  # fmt: skip


def apply(clip, commands, fetch=lambda clip_id: None, fetch_skeleton=lambda skeleton_id: None):
    """The clip after every command in order; an EditError names the command (1-based) that
    failed."""
    if not isinstance(commands, list) or not commands:
        raise EditError("an edit script is a non-empty list of commands")
    for k, command in enumerate(commands, 1):
        try:
            clip = apply_command(clip, command, fetch, fetch_skeleton)
        except EditError as e:
            raise EditError(f"command {k}: {e}") from None
    return clip
