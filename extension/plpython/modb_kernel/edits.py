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
  ik          joint, time, offset,        a joint (standard name) moved by offset metres (heading
              [orientation], [chain],     frame) at the frame nearest time by inverse kinematics,
              before, after               the change spread over before/after seconds
                                          (pose_edits.py)
  rotate      joint, time, rotation,      a joint's local rotation premultiplied by rotation
              before, after               (degrees, a rotation vector in its parent frame) there,
                                          spread the same way (pose_edits.py)

apply() returns the clip; apply_with_notes() the clip and per command a note (None, or for ik and
rotate a dict: the frames changed and, for ik, the target, the point reached and their distance).
"""

import math

import numpy as np

from . import mirror as mirroring
from . import pose_edits, quaternion, resample, retarget

# The one frame-rate range of the extension (the loader's, `resample`'s and retargeting's).
FPS_RANGE = (1.0, 1000.0)
# The most one result (a clip version from an edit script, a retargeting or a resampling) may hold,
# checked before any work: 50,000 frames is 7 minutes at 120 fps (the longest shipped clip has
# 2,752), and 64 MB of stored frames (float4 rotations and translations) is 50,000 frames of a
# 80-joint skeleton with one translated joint.
MAX_RESULT_FRAMES = 50_000
MAX_RESULT_BYTES = 64 * 1024 * 1024


class EditError(ValueError):
    """A command that cannot run on this clip, and why."""


def result_bytes(n_frames, n_joints, n_translated):
    """The bytes a version of n_frames frames stores (float4 quaternions and translations)."""
    return int(n_frames) * (4 * int(n_joints) + 3 * int(n_translated)) * 4


def check_result_size(n_frames, n_joints, n_translated, what):
    """Raises EditError when a result of this size passes MAX_RESULT_FRAMES or MAX_RESULT_BYTES."""
    size = result_bytes(n_frames, n_joints, n_translated)
    if n_frames > MAX_RESULT_FRAMES or size > MAX_RESULT_BYTES:
        raise EditError(
            f"{what} would have {int(n_frames):,} frames ({size / 2**20:,.1f} MB), more than the "
            f"{MAX_RESULT_FRAMES:,} frames and {MAX_RESULT_BYTES / 2**20:,.0f} MB one result may "
            "have: trim the clip first, or use a smaller factor or frame rate"
        )


def fps_error(fps):
    """Why a frame rate is refused (None when it is in FPS_RANGE)."""
    low, high = FPS_RANGE
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not low <= fps <= high:
        return f"fps must be a number from {low:g} to {high:g}, got {fps!r}"
    return None


# Each command's parameters: name -> (kind, required); kinds: "frame" (an integer >= 0), "id" (an
# integer > 0), "number" with its range, "joints" (a non-empty list of names), and pose_edits'
# "joint" (a standard joint name), "offset" (3 numbers, metres), "degrees" (3 numbers), "chain" (a
# count).
_PARAMETERS = {
    "mirror": {},
    "trim": {"start": ("frame", True), "end": ("frame", True)},
    "smooth": {"seconds": ((1e-3, 10.0), True)},
    "resample": {"fps": (FPS_RANGE, True)},
    "time_stretch": {"factor": ((0.05, 20.0), True)},
    "copy_joints": {
        "clip": ("id", True),
        "joints": ("joints", True),
        "start": ("frame", True),
        "end": ("frame", True),
        "source_start": ("frame", False),
        "blend": ((0, 10000), False),
    },
    "retarget": {"skeleton": ("id", True)},
    **pose_edits.PARAMETERS,
}
COMMANDS = tuple(_PARAMETERS)


def _parameter_error(op, key, kind, value):
    if kind == "frame":
        ok = isinstance(value, int) and not isinstance(value, bool) and value >= 0
        return None if ok else f'{op}: "{key}" must be a frame number (an integer from 0)'
    if kind == "id":
        ok = isinstance(value, int) and not isinstance(value, bool) and value > 0
        return None if ok else f'{op}: "{key}" must be an id (an integer from 1)'
    if kind == "joints":
        ok = isinstance(value, list) and value and all(isinstance(j, str) for j in value)
        return None if ok else f'{op}: "{key}" must be a non-empty list of joint names'
    check = pose_edits.parameter_error(op, key, kind)
    if check is not None:
        return check(value)
    low, high = kind
    number = isinstance(value, (int, float)) and not isinstance(value, bool)
    if not number or not low <= value <= high:
        return f'{op}: "{key}" must be a number from {low:g} to {high:g}'
    return None


def script_errors(commands):
    """Why a stored script cannot run whatever the clip: a list of messages, empty when it is a
    non-empty list of known commands with parameters of the right types and ranges."""
    if not isinstance(commands, list) or not commands:
        return ["an edit script is a non-empty list of commands"]
    errors = []
    for k, command in enumerate(commands, 1):
        if not isinstance(command, dict) or not isinstance(command.get("op"), str):
            got = repr(command)[:80]
            errors.append(f'command {k}: each command is an object with an "op", got {got}')
            continue
        op = command["op"]
        if op not in _PARAMETERS:
            errors.append(f'command {k}: unknown command "{op[:80]}": {", ".join(COMMANDS)}')
            continue
        for key, (kind, required) in _PARAMETERS[op].items():
            if key not in command:
                if required:
                    errors.append(f'command {k}: {op}: "{key}" is missing')
                continue
            problem = _parameter_error(op, key, kind, command[key])
            if problem:
                errors.append(f"command {k}: {problem}")
    return errors


def result_frames(commands, n_frames, fps):
    """The frame count and rate the script's result will have, and the most frames any step makes
    on the way (a stretch trimmed back is as large in between), from its parameters alone (a script
    that script_errors passes): so a result too large is refused before any work."""
    largest = 0
    for command in commands:
        op = command["op"]
        if op == "trim":
            start, end = command["start"], min(command["end"], n_frames - 1)
            n_frames = max(1, end - start + 1)
        elif op == "resample":
            n_frames = len(resample.fps_frames(n_frames, fps, command["fps"]))
            fps = float(command["fps"])
        elif op == "time_stretch":
            n_frames = int(math.floor((n_frames - 1) * command["factor"] + 1e-9)) + 1
        largest = max(largest, n_frames)
    return n_frames, fps, largest


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


def command_with_note(clip, command, fetch, fetch_skeleton):
    """(clip, note): one command on a clip (its parameters checked: script_errors) and its note
    (None but for ik and rotate); fetch(clip_id) -> clip (copy_joints), fetch_skeleton(id) ->
    (skeleton, a reference frame or None) (retarget)."""
    if isinstance(command, dict) and command.get("op") in pose_edits.EDITS:
        try:
            return pose_edits.edit(clip, command)
        except pose_edits.PoseEditError as e:
            raise EditError(str(e)) from None
    return _apply_command(clip, command, fetch, fetch_skeleton), None


def _apply_command(clip, command, fetch, fetch_skeleton):
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
        fps = _number(command, "fps", *FPS_RANGE)
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
            r, t = retarget.retarget(source, target, clip["rotations"], clip["translations"])
        except retarget.RetargetError as e:
            raise EditError(f"retarget: {e}") from None
        return dict(clip, skeleton=destination, rotations=r, translations=t)
    raise EditError(f'unknown command "{op}": {", ".join(COMMANDS)}')


def apply(clip, commands, fetch=lambda clip_id: None, fetch_skeleton=lambda skeleton_id: None):
    """The clip after every command in order; an EditError names the command (1-based) that
    failed."""
    return apply_with_notes(clip, commands, fetch, fetch_skeleton)[0]


def apply_with_notes(clip, commands, fetch=lambda clip_id: None,
                     fetch_skeleton=lambda skeleton_id: None):  # fmt: skip
    """(clip, notes): apply()'s clip and, per command in order, its note: None, or for ik and
    rotate a dict (pose_edits: "frame", "frames" [first, last changed], and for ik "target",
    "reached", "distance_m", "met" and, when not met, "message"), each with its "command" number
    (1-based)."""
    errors = script_errors(commands)
    if errors:
        raise EditError("; ".join(errors))
    notes = []
    for k, command in enumerate(commands, 1):
        try:
            clip, note = command_with_note(clip, command, fetch, fetch_skeleton)
        except EditError as e:
            raise EditError(f"command {k}: {e}") from None
        if note is not None:
            note = {"command": k, **note}
            if "message" in note:
                note["message"] = f"command {k}: {note['message']}"
        notes.append(note)
    return clip, notes
