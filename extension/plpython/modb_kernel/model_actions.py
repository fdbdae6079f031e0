"""Actions in a synthesis from models (after the DFKI worker use case): the character walks to where
it stands for the action, comes to rest, performs the action so that its hand meets the target at
the action's keyframe, and goes back to standing.

An action is {"primitive": its graph node (an action model's primitive, e.g. "raise_right_hand"),
"target": [x, y, z] world metres or null, "stand": [x, z] or null, "after": how many of the walk's
goals come before it (default: all)}. Where it stands: `stand` when given, else where the model's
mean motion puts the hand at the target's ground point, facing the way it comes from (within
STAND_RADIUS_M). Meeting the
target: the model's tree search and refinement on the hand at the keyframe in the action's own
frame (as it stands: step_search's prior), then, where the result misses, inverse kinematics of the
arm spread over the action's frames (reach.py); the report has the hand's error after each.
"""

import numpy as np

from . import kinematics, motion_model, reach, standing
from .step_search import rotate_y

MAX_ACTIONS = 100
MAX_REPEAT_SECONDS = 60.0
PACE_MARGIN = 1.01  # an action slowed to its bound plays this much slower again (frames blended)
REPEAT_SPREAD = 0.5  # a repeated motion's scores this near its mixture component's mean
FACE_BEYOND_M = 0.1  # a target nearer the pelvis (or a hand nearer it) says no way to face
STAND_RADIUS_M = 0.15  # an action's stand point reached within a step (Synthesis.arrive_early)
MAX_COORDINATE = 1e6


class ActionError(ValueError):
    pass


def checked(actions, n_goals, primitives):
    """The actions as dicts with numpy points, in the course's order, or ActionError saying which
    and why. primitives: the graph's action nodes."""
    if actions is None:
        return []
    if not isinstance(actions, list) or len(actions) > MAX_ACTIONS:
        raise ActionError(f"actions must be a list of at most {MAX_ACTIONS} objects")
    out = []
    for k, a in enumerate(actions, start=1):
        if not isinstance(a, dict) or not isinstance(a.get("primitive"), str):
            raise ActionError(f'action {k} must be an object with a "primitive" (a node of the '
                              "graph's actions)")  # fmt: skip
        if a["primitive"] not in primitives:
            known = ", ".join(sorted(primitives)) or "none"
            raise ActionError(f'action {k}: the graph has no action "{a["primitive"]:.100}" '
                              f"(its actions: {known})")  # fmt: skip
        unknown = sorted(set(a) - {"primitive", "target", "stand", "after", "seconds"})
        if unknown:
            raise ActionError(f'action {k}: unknown key "{unknown[0]:.50}" (it takes primitive, '
                              "target, stand, after, seconds)")  # fmt: skip
        seconds = a.get("seconds")
        if seconds is not None and (isinstance(seconds, bool) or not isinstance(
                seconds, (int, float)) or not 0 < seconds <= MAX_REPEAT_SECONDS):  # fmt: skip
            raise ActionError(f'action {k}: "seconds" (how long a repeated motion such as a '
                              f"wave goes on) must be above 0, at most "
                              f"{MAX_REPEAT_SECONDS:g}")  # fmt: skip
        target = _point(a.get("target"), 3, k, "target", "[x, y, z]")
        stand = _point(a.get("stand"), 2, k, "stand", "[x, z]")
        if target is None and stand is None:
            raise ActionError(f'action {k}: give a "target" [x, y, z] or where to "stand" [x, z]')
        after = a.get("after", n_goals)
        if isinstance(after, bool) or not isinstance(after, int) or not 0 <= after <= n_goals:
            raise ActionError(f'action {k}: "after" is how many goals come before it: a whole '
                              f"number from 0 to {n_goals}")  # fmt: skip
        out.append({"primitive": a["primitive"], "target": target, "stand": stand, "after": after,
                    "seconds": None if seconds is None else float(seconds)})  # fmt: skip
    return out


def _point(value, n, k, key, form):
    if value is None:
        return None
    ok = (isinstance(value, list) and len(value) == n and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and abs(v) <= MAX_COORDINATE
        for v in value))  # fmt: skip
    if not ok:
        raise ActionError(f'action {k}: "{key}" must be {form} in metres, each finite and at '
                          f"most {MAX_COORDINATE:g} from the origin")  # fmt: skip
    return np.asarray(value, dtype=np.float64)


def course(goals, actions, models):
    """[(ground point (x, z), arrival radius or None for the synthesis's, action or None)] in the
    order walked: each action after the goals its "after" counts."""
    out, last = [], np.zeros(2)
    for k in range(len(goals) + 1):
        for a in actions:
            if a["after"] == k:
                out.append(stand_point(a, models[a["primitive"]], last))
                last = out[-1][0]
        if k < len(goals):
            out.append((np.asarray(goals[k], dtype=np.float64), None, None))
            last = out[-1][0]
    return out


def stand_point(action, model, came_from):
    """(where to stand, its arrival radius, the action): `stand` when given, else where the
    model's mean motion puts the hand at the target, facing the way from `came_from` to it."""
    if action["stand"] is not None:
        return action["stand"], None, action
    if model.keyframe is None:  # a repeated motion faces its target from where it stands
        return np.asarray(came_from, dtype=np.float64), np.inf, action
    ground = action["target"][[0, 2]]
    way = ground - np.asarray(came_from, dtype=np.float64)
    heading = float(np.arctan2(way[0], way[1])) if np.linalg.norm(way) > 1e-6 else 0.0
    hand = model.usual_wrists.mean(axis=0)[[0, 2]]
    return ground - rotate_y(hand, heading), STAND_RADIUS_M, action


def facing(action, model, pelvis):
    """The heading from which the model's mean motion puts the hand the way of the target (its
    stand point's when it has none) from the pelvis's ground point; None where too near to say."""
    point = action["target"][[0, 2]] if action["target"] is not None else action["stand"]
    way = point - np.asarray(pelvis, dtype=np.float64)
    hand = model.usual_wrists.mean(axis=0)[[0, 2]] if model.keyframe is not None else np.zeros(2)
    if model.keyframe is None and np.linalg.norm(way) >= FACE_BEYOND_M:
        return float(np.arctan2(way[0], way[1]))  # a repeated motion faces the point
    if np.linalg.norm(way) < FACE_BEYOND_M or np.linalg.norm(hand) < FACE_BEYOND_M:
        return None
    return float(np.arctan2(way[0], way[1]) - np.arctan2(hand[0], hand[1]))


def hand_targets(model, target):
    """(hands, 3) targets: one hand at the target; two keep their usual spacing about it."""
    usual = model.usual_wrists
    return np.asarray(target, dtype=np.float64)[None] + (usual - usual.mean(axis=0))


def canonical(spot, points):
    """World points (..., 3) in the frame of an action placed on the spot."""
    points = np.asarray(points, dtype=np.float64)
    ground = rotate_y(points[..., [0, 2]] - spot.pelvis, -spot.heading)
    return np.stack([ground[..., 0], points[..., 1] - spot.lift, ground[..., 1]], axis=-1)


def repeated(rotations, translations, first, last, n):
    """The frames with their repetition (frames first to last, turning points of the motion:
    at rest there, so a pass played backward joins it) played forward, backward, forward ...
    an odd number of passes (the last forward, so the frames after it follow), about n frames in
    all from first; and the number of passes."""
    if last - first < 2:
        return rotations, translations, 1
    passes = max(1, int(round(n / (last - first))))
    passes += 1 - passes % 2
    order = [np.arange(first)]
    for k in range(passes):
        order.append(np.arange(first, last + 1) if k % 2 == 0 else np.arange(last - 1, first, -1))
    order.append(np.arange(last + 1, len(rotations)))
    at = np.concatenate(order)
    return rotations[at], translations[at], passes


def _slower(rig, natural, after, bound=None):
    """How many times slower the frames `after` play so that no joint moves faster from one frame
    to the next (kinematics.pose_jumps) than in the `natural` frames, nor than `bound` (metres: the
    examples' p99.9, where the model knows it): a hand sent farther takes longer (1 where it is
    no faster)."""
    def worst(frames):
        return float(kinematics.pose_jumps(rig.positions(*frames), rig.pelvis).max())

    fastest = worst(natural) if bound is None else min(worst(natural), bound)
    pace = worst(after) / max(fastest, 1e-9)
    return 1.0 if pace <= 1.0 else PACE_MARGIN * pace  # a blend of frames may overshoot a little


def _played(rotations, translations, pace):
    """The frames played `pace` times slower (blended between neighbours; the first and, where the
    length allows, the last kept)."""
    if pace <= 1.0:
        return rotations, translations
    return motion_model.play(rotations, translations, np.arange(len(rotations)) * pace)


def _rms(misses):
    """The root mean square of distances (metres): of vectors (..., 3), or of distances given."""
    misses = np.asarray(misses, dtype=np.float64)
    squared = np.sum(misses**2, axis=-1) if misses.ndim > 1 else misses**2
    return float(np.sqrt(np.mean(squared)))


def perform(synthesis, node, action):
    """Plays the action at the spot the character stands on (synthesis.spot, settled) and returns
    its report record."""
    syn, rig, body = synthesis, synthesis.rig, synthesis.body
    model = syn.models[node]
    syn.interrupts()
    target = action["target"]
    record = {"action": node, "model": model.model.get("name"),
              "version": model.model.get("version"), "first_frame": body.n_frames,
              "target": None if target is None else target.tolist()}  # fmt: skip
    world = None if action["target"] is None else hand_targets(model, action["target"])
    scores = found = np.zeros(model.dimensions)
    if world is not None and model.keyframe is not None:
        local = canonical(syn.spot, world)
        found, examined = model.search(local, syn.rng)
        scores = refined = model.refine(found, local)  # within the mixture's mass
        record.update(candidates=examined, tree_error_m=float(model.errors(found, local)[0]),
                      refined_error_m=float(model.errors(refined, local)[0]))  # fmt: skip
        record["error_m"] = record["refined_error_m"]
    if model.keyframe is None:  # a repeated motion: a calm draw of its mixture
        scores = model.calm_draw(syn.rng, REPEAT_SPREAD)
    split = model.split
    rotations, translations, times = motion_model.frames_from_scores(model.model, scores[:split],
                                                                     scores[split:])  # fmt: skip
    if model.repetition is not None and action.get("seconds"):
        first, last = (int(round(float(times[k]))) for k in model.repetition)
        rotations, translations, record["repeats"] = repeated(
            rotations, translations, first, last, int(round(action["seconds"] * syn.fps)))
    piece = standing.on_spot(rig, rotations, translations, syn.spot)
    joined = syn.seams.inertialize(*body.last_two(), *piece, syn.fps)
    joined = (standing.pinned(syn.legs, joined[0], joined[1], syn.spot.feet), joined[1])
    if world is not None and model.keyframe is not None:
        frame = int(round(float(times[model.keyframe])))
        record["keyframe_frame"] = body.n_frames - 1 + frame
        wrists = rig.positions(joined[0][frame:frame + 1], joined[1][frame:frame + 1])[0]
        record["placed_error_m"] = _rms(wrists[model.wrist_joints] - world)
        syn.interrupts()
        # the hand onto the target where the model's motion misses it: the arm's IK, spread over
        # the action's frames (its first, the seam, and its last stay as they are)
        reached = reach.reach(rig.parents, rig.offsets, rig.translated, rig.names, rig.joint_map,
                              joined[0], joined[1], frame, dict(zip(model.hands, world)),
                              limits=model.model.get("limits"))  # fmt: skip
        # no faster than the tree's sample (a natural one: refinement and IK may hurry the hand)
        natural = motion_model.frames_from_scores(model.model, found[:split], found[split:])
        pace = _slower(rig, standing.on_spot(rig, natural[0], natural[1], syn.spot),
                       (reached.rotations, joined[1]),
                       model.model.get("pace", {}).get("jump_p999_m"))  # fmt: skip
        joined, piece = (_played(reached.rotations, joined[1], pace),
                         _played(piece[0], piece[1], pace))  # fmt: skip
        frame = int(round(frame * pace))
        record["keyframe_frame"], record["slowed"] = body.n_frames - 1 + frame, pace
        wrists = rig.positions(joined[0][frame:frame + 1], joined[1][frame:frame + 1])[0]
        record["ik_error_m"] = _rms(wrists[model.wrist_joints] - world)
        record["error_m"] = record["ik_error_m"]
        record["reachable"] = reached.reachable
        if not reached.reachable:
            record["unreached_m"] = record["ik_error_m"]
            # where the hand is at the keyframe as played (the frames may have been slowed)
            record["nearest"] = {s: [float(v) for v in wrists[j]]
                                 for s, j in zip(model.hands, model.wrist_joints)}  # fmt: skip
            syn.notes.append(f'the action "{node}": its target is out of reach; the nearest point '
                             f"reached, {100 * record['ik_error_m']:.1f} cm from it")  # fmt: skip
    syn.append(joined[0][1:], joined[1][1:], (piece[0][1:], piece[1][1:]), hold=False)
    record["n_frames"] = body.n_frames - record["first_frame"]
    record["cut"] = body.n_frames > syn.wanted_frames
    if record["cut"]:
        syn.notes.append(f'the action "{node}" was cut: the strip ends at {syn.seconds:g} s')
    return record
