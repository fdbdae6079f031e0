"""An action done standing (raise a hand, wave) found in a clip from its motion: which hand acts,
the action's keyframes, and the standing lead-in and lead-out around it.

- The body frame: a wrist's position relative to the pelvis, turned by the hip heading so that it
  does not change when the body turns (x to the side, y up, z ahead), smoothed over SMOOTH_S.
- A hand acts where its wrist, in the body frame, spans more than MOVE_ARMS of the arm's length
  (shoulder to elbow to wrist at rest) over the clip; of two, both act when the lesser path length
  is at least BOTH_SHARE of the greater, else the one with the longer path. None acting: no action.
- Standing throughout: the pelvis stays within TRAVEL_LEGS leg lengths of where it began on the
  ground, else the clip is a walk, no action done standing.
- Repeated (a wave): an acting wrist turns back and forth along one of the body frame's axes,
  each turn a zigzag's of TURN_ARMS of the arm (a marker's jitter, or a raised arm's sway, makes
  none), in a run of at least MIN_SWINGS like swings (each at least LIKE_SHARE of the median
  swing); keyframes: the run's first and last turning points (the earliest and latest over the
  acting wrists), where the repetition starts and ends.
- Else a reach: the keyframe is the middle of the plateau where the acting wrist (the mean height
  of both, for two) is highest: the frames around the highest one within PLATEAU_M of it.
- Lead-in and lead-out: standing still at the clip's start or end (primitives.stillness: the
  pelvis slow on the ground, the wrists and head slow relative to it, the wrists below the
  shoulders) for at least standing.MIN_STANDING_S; named `idle`, the family's standing primitive.
  The action runs from the lead-in's last frame to the lead-out's first (the clip's ends without
  them)."""

import numpy as np

from . import kinematics
from . import primitives
from . import steps as S
from .standing import MIN_STANDING_S
from .step_search import hip_heading, rotate_y

MOVE_ARMS = 0.25
BOTH_SHARE = 0.5
TRAVEL_LEGS = 1.0
TURN_ARMS = 0.2
MIN_SWINGS = 4
LIKE_SHARE = 0.5
PLATEAU_M = 0.01
SMOOTH_S = 0.1
SIDES = ("left", "right")


class ActionError(ValueError):
    pass


def smoothed(points, fps, span=SMOOTH_S):
    """(frames, ...) points averaged over about span seconds (a centred window, shrunk at the
    ends)."""
    k = max(0, int(round(span * fps / 2)))
    if k == 0 or len(points) < 3:
        return points
    n = len(points)
    padded = np.concatenate([np.repeat(points[:1], k, 0), points, np.repeat(points[-1:], k, 0)])
    sums = np.cumsum(np.concatenate([np.zeros_like(points[:1]), padded]), axis=0)
    return (sums[2 * k + 1 : 2 * k + 1 + n] - sums[:n]) / (2 * k + 1)


def zigzag(signal, threshold):
    """The frames of the signal's turning points: each extreme from which it goes back by more
    than threshold (a first rise or fall of more than threshold starts the count)."""
    turns = []
    high = low = 0  # the frames of the running highest and lowest since the last turn
    direction = 0  # +1 rising, -1 falling, 0 not yet known
    for t in range(1, len(signal)):
        v = signal[t]
        if direction >= 0 and v > signal[high]:
            high = t
        elif direction <= 0 and v < signal[low]:
            low = t
        if direction == 0:
            if v - signal[low] > threshold:
                direction, high = 1, t
            elif signal[high] - v > threshold:
                direction, low = -1, t
        elif direction > 0 and signal[high] - v > threshold:
            turns.append(high)
            direction, low = -1, t
        elif direction < 0 and v - signal[low] > threshold:
            turns.append(low)
            direction, high = 1, t
    return turns


def repetition(points, threshold):
    """(first, last) turning point of the longest run of like swings (each at least LIKE_SHARE
    of the median swing) along the body-frame axis where it is longest, when that run has at least
    MIN_SWINGS swings; else None."""
    best = None
    for axis in range(points.shape[1]):
        turns = zigzag(points[:, axis], threshold)
        if len(turns) < 2:
            continue
        swings = np.abs(np.diff(points[turns, axis]))
        like = swings >= LIKE_SHARE * np.median(swings)
        for a, b in primitives.runs(like):
            if b - a >= MIN_SWINGS and (best is None or b - a > best[0]):
                best = (b - a, turns[a], turns[b])
    return None if best is None else best[1:]


def arm_length(parents, offsets, index, side):
    rest = kinematics.rest_positions(parents, offsets)
    s, e, w = (index[f"{side}_{p}"] for p in ("shoulder", "elbow", "wrist"))
    return float(np.linalg.norm(rest[s] - rest[e]) + np.linalg.norm(rest[e] - rest[w]))


def plateau_middle(height, plateau=PLATEAU_M):
    """The middle frame of the run of frames around the highest within plateau of it."""
    top = int(np.argmax(height))
    high = height >= height[top] - plateau
    first, past = top, top + 1
    while first > 0 and high[first - 1]:
        first -= 1
    while past < len(height) and high[past]:
        past += 1
    return (first + past - 1) // 2


def find(parents, offsets, rotations, translations, translated, names, joint_map, fps):
    """{"action": (start, end, keyframes, hands, kind), "idle": [(start, end)]} (see the module's
    description); ActionError when the clip shows no action done standing."""
    needed = ["pelvis"] + [f"{s}_{p}" for s in SIDES for p in ("hip", "knee", "ankle")]
    missing = [n for n in needed if joint_map.get(n) not in names]
    if missing:
        raise ActionError("the joint map lacks " + ", ".join(missing))
    index = {n: names.index(j) for n, j in joint_map.items() if j in names}
    sides = [s for s in SIDES
             if all(f"{s}_{p}" in index for p in ("shoulder", "elbow", "wrist"))]  # fmt: skip
    if not sides:
        raise ActionError("the joint map names no arm (shoulder, elbow and wrist of a side)")
    positions = kinematics.world_positions(parents, offsets, rotations, translations, translated)
    n = len(positions)
    pelvis = positions[:, index["pelvis"]]
    leg = S.leg_length(parents, offsets, index)
    travel = float(np.max(np.linalg.norm((pelvis - pelvis[0])[:, [0, 2]], axis=1)))
    if travel > TRAVEL_LEGS * leg:
        raise ActionError(f"the body travels {travel:.2f} m over the ground (more than "
                          f"{TRAVEL_LEGS:g} leg length): no action done standing")  # fmt: skip
    heading = hip_heading(positions, index["left_hip"], index["right_hip"])
    heading = np.unwrap(heading)
    local, path, span, arm = {}, {}, {}, {}
    for side in sides:
        rel = positions[:, index[f"{side}_wrist"]] - pelvis
        ground = rotate_y(rel[:, [0, 2]], -heading)
        local[side] = smoothed(np.stack([ground[:, 0], rel[:, 1], ground[:, 1]], axis=1), fps)
        path[side] = float(np.sum(np.linalg.norm(np.diff(local[side], axis=0), axis=1)))
        span[side] = float(np.max(np.ptp(local[side], axis=0)))
        arm[side] = arm_length(parents, offsets, index, side)
    moving = [s for s in sides if span[s] > MOVE_ARMS * arm[s]]
    if not moving:
        widest = max(sides, key=lambda s: span[s])
        raise ActionError(
            f"no hand moves relative to the body (the {widest} wrist spans "
            f"{100 * span[widest]:.0f} cm, less than {MOVE_ARMS:g} of the arm's "
            f"{100 * arm[widest]:.0f} cm)")  # fmt: skip
    most = max(path[s] for s in moving)
    hands = [s for s in moving if path[s] >= BOTH_SHARE * most]

    slow, calm = primitives.stillness(positions, joint_map, names, fps)
    still = slow & calm
    least = int(np.ceil(MIN_STANDING_S * fps))
    begin, end = 0, n - 1
    idle = []
    runs = primitives.runs(still)
    if runs and runs[0][0] == 0 and runs[0][1] >= least and runs[0][1] < n:
        begin = runs[0][1] - 1
        idle.append((0, begin))
    if runs and runs[-1][1] == n and n - runs[-1][0] >= least and runs[-1][0] > begin + 1:
        end = runs[-1][0]
        idle.append((end, n - 1))

    spans = [repetition(local[side][begin : end + 1], TURN_ARMS * arm[side]) for side in hands]
    spans = [r for r in spans if r is not None]
    if spans:
        first, last = begin + min(r[0] for r in spans), begin + max(r[1] for r in spans)
        keyframes, kind = [begin, first, last, end], "repeat"
    else:
        height = np.mean([positions[begin : end + 1, index[f"{s}_wrist"], 1] for s in hands], 0)
        keyframes, kind = [begin, begin + plateau_middle(height), end], "reach"
    keyframes = sorted(set(keyframes))
    return {"action": (begin, end, keyframes, hands, kind), "idle": idle}
