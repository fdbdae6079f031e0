"""The primitives of a character, found from the feet's contacts (steps.py) and the body's speeds:
steps, turning steps, starts, stops and idle.

- Standing: both feet in contact and the pelvis moving slower than STANDING_M_S on the ground.
- A start runs from the last standing frame to the first touchdown after it; named by the foot
  that moves first (`left_start`: the left foot leaves first and lands, the right stays planted, as
  a `left_step` swings the left). Keyframes: its ends and that foot's lift-off. A `right_step`
  follows a `left_start` at its touchdown.
- A stop runs from the touchdown before the last one (the foot that stays planted) through the last
  swing to the first standing frame; named by the foot that moves last (`left_stop`). Keyframes:
  its ends and the last touchdown. It follows a step at that step's touchdown, so a stop's last
  swing is also annotated as a step.
- Idle: standing with the hands and head slower than STILL_M_S relative to the pelvis (a wave or
  a bow is not idle) and the wrists below the shoulders (a reach held at its height is not idle),
  at least IDLE_MIN_S; a long run is cut into pieces of about IDLE_PIECE_S, so that idle examples
  are alike in length. Keyframes: its ends.
- A turning step is a step whose heading changes more than TURN_DEGREES: half the hip heading's
  change over the stride (two steps) centred on it, taken between frames of the same phase so the
  pelvis's sway with each step cancels (straight walks of the shipped capture: at most 7 degrees;
  Bandai's walk-turns: median 9, the sharpest quarter above 20). It keeps its `left_step` /
  `right_step` segment and gains `left_turning_step` / `right_turning_step` over the same frames:
  step models built before see the same segments (they stay current), turning models learn the
  sharp ones.

The graph's node types: a start is type "start", a stop "end", idle "idle", steps and turning
steps "standard" (node_type)."""

import numpy as np

from . import kinematics
from . import steps as S
from .step_search import hip_heading, wrap

STANDING_M_S = 0.15
STILL_M_S = 0.15
IDLE_MIN_S = 0.5
IDLE_PIECE_S = 1.0
TURN_DEGREES = 20.0
MAX_START_S = 2.0  # standing to the first touchdown; longer is not one start
MAX_SETTLE_S = 2.0  # the last touchdown to standing
STILL_POINTS = ("left_wrist", "right_wrist", "head")
STILL_SPAN_S = 0.1  # speeds of stillness over a tenth of a second: a marker's jitter averages out
TYPES = (("_start", "start"), ("_stop", "end"), ("idle", "idle"))


def node_type(primitive):
    """The graph node type of a primitive by its name: start, end, idle or standard."""
    for ending, kind in TYPES:
        if primitive.endswith(ending):
            return kind
    return "standard"


def runs(flags):
    """[(first, past the last)] of the runs of True."""
    edges = np.flatnonzero(np.diff(np.r_[0, flags.astype(np.int8), 0]))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def turns(steps, headings):
    """Per step (name, start, end): its turn in degrees (see the module's description); NaN for a
    step with no neighbour sharing a touchdown."""
    out = []
    for k, (_, start, end) in enumerate(steps):
        halves = []
        if k > 0 and steps[k - 1][2] == start:
            halves.append(wrap(headings[end] - headings[steps[k - 1][1]]) / 2)
        if k + 1 < len(steps) and steps[k + 1][1] == end:
            halves.append(wrap(headings[steps[k + 1][2]] - headings[start]) / 2)
        out.append(float(np.degrees(np.mean(halves))) if halves else float("nan"))
    return out


def starts(standing, contact, fps):
    """[(name, start, end, keyframes)]: standing, then the first foot's swing to its touchdown."""
    out = []
    down = {s: S.touchdowns(contact[s]) for s in S.SIDES}
    for _, past in runs(standing):
        first = min(((t, s) for s in S.SIDES for t in down[s] if t > past), default=None)
        if first is None:
            continue
        touchdown, side = first
        begin = past - 1
        lift = begin + 1 + int(np.argmin(contact[side][begin + 1 : touchdown]))
        if contact[side][lift] or (touchdown - begin) / fps > MAX_START_S:
            continue  # the foot never left the ground, or no start of one swing
        out.append((f"{side}_start", begin, touchdown, [begin, lift, touchdown]))
    return out


def stops(standing, contact, fps):
    """[(name, start, end, keyframes)]: the last swing from the planted foot's touchdown, then the
    body coming to standing."""
    out = []
    events = sorted((t, s) for s in S.SIDES for t in S.touchdowns(contact[s]))
    for first, _ in runs(standing):
        before = [e for e in events if e[0] < first]
        if len(before) < 2:
            continue
        (last, side), (planted, other) = before[-1], before[-2]
        swing = (last - planted) / fps
        if other == side or not S.MIN_STEP_S <= swing <= S.MAX_STEP_S:
            continue  # no last swing between alternate feet
        if (first - last) / fps > MAX_SETTLE_S or first <= last:
            continue
        out.append((f"{side}_stop", planted, first, [planted, last, first]))
    return out


def idle(still, fps):
    """[(name, start, end, keyframes)]: runs of stillness, cut into pieces of about IDLE_PIECE_S."""
    out = []
    for first, past in runs(still):
        seconds = (past - first) / fps
        if seconds < IDLE_MIN_S:
            continue
        n = max(1, int(round(seconds / IDLE_PIECE_S)))
        bounds = np.linspace(first, past - 1, n + 1).round().astype(int).tolist()
        out += [("idle", a, b, [a, b]) for a, b in zip(bounds, bounds[1:])]
    return out


def stillness(positions, joint_map, names, fps):
    """(standing, still) per frame: the pelvis slow on the ground; and besides, the hands and head
    slow relative to it, the wrists below the shoulders (those the joint map names)."""
    pelvis = positions[:, names.index(joint_map["pelvis"])]
    slow = S.speeds(pelvis * np.array([1.0, 0.0, 1.0]), fps, STILL_SPAN_S) < STANDING_M_S
    calm = np.ones(len(positions), dtype=bool)
    for point in STILL_POINTS:
        if joint_map.get(point) in names:
            moving = positions[:, names.index(joint_map[point])] - pelvis
            calm &= S.speeds(moving, fps, STILL_SPAN_S) < STILL_M_S
    for side in S.SIDES:
        wrist, shoulder = (joint_map.get(f"{side}_{p}") for p in ("wrist", "shoulder"))
        if wrist in names and shoulder in names:
            calm &= positions[:, names.index(wrist), 1] < positions[:, names.index(shoulder), 1]
    return slow, calm


def find(parents, offsets, rotations, translations, translated, names, joint_map, fps):
    """[(name, start, end, keyframes)] of the clip's primitives, in frame order."""
    index = S.joint_indices(names, joint_map)
    if "pelvis" not in joint_map or joint_map["pelvis"] not in names:
        raise S.StepError("the joint map lacks pelvis")
    positions = kinematics.world_positions(parents, offsets, rotations, translations, translated)
    contact = S.contacts(positions, index, S.leg_length(parents, offsets, index), fps)
    steps = S.steps_from(contact, fps)
    slow, calm = stillness(positions, joint_map, names, fps)
    standing = S.cleaned(contact["left"] & contact["right"] & slow, fps)
    headings = hip_heading(positions, index["left_hip"], index["right_hip"])
    found = [(name, a, b, [a, b]) for name, a, b in steps]
    found += [(f"{name.split('_')[0]}_turning_step", a, b, [a, b])
              for (name, a, b), turn in zip(steps, turns(steps, headings))
              if abs(turn) > TURN_DEGREES]  # fmt: skip
    found += starts(standing, contact, fps) + stops(standing, contact, fps)
    found += idle(standing & calm, fps)
    return sorted(found, key=lambda p: (p[1], p[2], p[0]))
