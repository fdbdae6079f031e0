"""Foot contacts and the steps between them, from forward-kinematics positions of ankles and toes.

A foot is in contact where its slower point (ankle or toe: the heel lands first, the toes leave
    last)
moves slower than SPEED_LEGS_PER_S leg lengths a second and its lower point lies within HEIGHT_LEGS
leg lengths of the clip's ground (the 5th percentile of both feet's lower points). Thresholds scale
with the leg (hip to knee to ankle at rest), speeds are central differences over 1/60 s whatever the
rate, and runs are cleaned in seconds: a contact broken for less than GAP_S is one contact, one
    shorter
than MIN_CONTACT_S is none. A touchdown is the first frame of a contact that starts inside the clip.

A step is the swing between two touchdowns of alternate feet: a `left_step` runs from a touchdown of
the right foot to the next touchdown of the left (the left foot swings), both frames its keyframes;
at least MIN_STEP_S long (a sprinter's steps take about 0.2 s: shorter is a foot found planted
twice, not a step) and at most MAX_STEP_S (longer is a pause, not a step). A mirrored clip gives
the mirrored steps."""

import numpy as np

from . import kinematics

SPEED_LEGS_PER_S = 0.5
HEIGHT_LEGS = 0.1
GAP_S = 0.1
MIN_CONTACT_S = 0.05
MIN_STEP_S = 0.2
MAX_STEP_S = 1.5
VELOCITY_SPAN_S = 1.0 / 60
SIDES = ("left", "right")
NEEDED = tuple(f"{side}_{part}" for side in SIDES for part in ("hip", "knee", "ankle"))


class StepError(ValueError):
    pass


def joint_indices(names, joint_map):
    """Index of each joint the detection reads (hips, knees, ankles, toes), by standard name; a rig
    without toes in its joint map stands on its ankles."""
    missing = [s for s in NEEDED if joint_map.get(s) not in names]
    if missing:
        raise StepError("the joint map lacks " + ", ".join(missing))
    index = {s: names.index(joint_map[s]) for s in NEEDED}
    for side in SIDES:
        toe = joint_map.get(f"{side}_toe")
        index[f"{side}_toe"] = names.index(toe) if toe in names else index[f"{side}_ankle"]
    return index


def leg_length(parents, offsets, index):
    """Hip to knee to ankle at rest, both legs averaged (metres)."""
    rest = kinematics.rest_positions(parents, offsets)
    lengths = [
        np.linalg.norm(rest[index[f"{s}_hip"]] - rest[index[f"{s}_knee"]])
        + np.linalg.norm(rest[index[f"{s}_knee"]] - rest[index[f"{s}_ankle"]])
        for s in SIDES
    ]
    return float(np.mean(lengths))


def speeds(points, fps, span=VELOCITY_SPAN_S):
    """|velocity| (m/s) of (frames, 3) points by central differences over about span seconds."""
    n = len(points)
    k = max(1, int(round(span * fps / 2)))
    before = np.clip(np.arange(n) - k, 0, n - 1)
    after = np.clip(np.arange(n) + k, 0, n - 1)
    span = np.maximum(after - before, 1) / fps
    return np.linalg.norm(points[after] - points[before], axis=-1) / span


def cleaned(contact, fps):
    """Gaps shorter than GAP_S filled, then contacts shorter than MIN_CONTACT_S dropped."""
    out = contact.copy()
    for value, longest in ((False, GAP_S), (True, MIN_CONTACT_S)):
        k = 0
        while k < len(out):
            if out[k] != value:
                k += 1
                continue
            end = k
            while end < len(out) and out[end] == value:
                end += 1
            inside = k > 0 and end < len(out)  # a run at either end of the clip is kept
            if inside and (end - k) / fps < longest:
                out[k:end] = not value
            k = end
    return out


def contacts(positions, index, leg, fps):
    """Per side, whether the foot is in contact at each frame (see the module's description)."""
    low = {
        s: np.minimum(positions[:, index[f"{s}_ankle"], 1], positions[:, index[f"{s}_toe"], 1])
        for s in SIDES
    }
    ground = np.percentile(np.concatenate([low[s] for s in SIDES]), 5)
    out = {}
    for s in SIDES:
        speed = np.minimum(
            speeds(positions[:, index[f"{s}_ankle"]], fps),
            speeds(positions[:, index[f"{s}_toe"]], fps),
        )
        planted = (speed < SPEED_LEGS_PER_S * leg) & (low[s] < ground + HEIGHT_LEGS * leg)
        out[s] = cleaned(planted, fps)
    return out


def touchdowns(contact):
    """First frames of the contacts that start inside the clip."""
    starts = np.flatnonzero(contact[1:] & ~contact[:-1]) + 1
    return starts.tolist()


def steps_from(contact, fps):
    """[(name, start, end)]: the steps between touchdowns of alternate feet, in frame order. A foot
    may touch down twice before the other does (a contact broken mid-stance): the step then starts
    at the later touchdown, or at the earlier one where the later leaves less than MIN_STEP_S."""
    events = sorted((f, s) for s in SIDES for f in touchdowns(contact[s]))
    runs = []  # [side, [its touchdowns before the other foot's next]]
    for frame, side in events:
        if runs and runs[-1][0] == side:
            runs[-1][1].append(frame)
        else:
            runs.append([side, [frame]])
    out = []
    for (planted, starts), (landed, ends) in zip(runs, runs[1:]):
        end = ends[0]
        fits = [f for f in starts if MIN_STEP_S <= (end - f) / fps <= MAX_STEP_S]
        if fits:
            out.append((f"{landed}_step", fits[-1], end))
    return out


def find(parents, offsets, rotations, translations, translated, names, joint_map, fps):
    """The clip's steps [(name, start, end)] and its contacts {side: bool per frame}."""
    index = joint_indices(names, joint_map)
    positions = kinematics.world_positions(parents, offsets, rotations, translations, translated)
    found = contacts(positions, index, leg_length(parents, offsets, index), fps)
    return steps_from(found, fps), found
