"""Coming to rest and standing, for synthesis from models where the graph has no stop to play (the
shipped walks hold none): the trailing foot is carried beside the planted one by the kernel's IK
while the body blends into standing frames, and then standing goes on from captured standing.

Standing comes in pieces: a sample of the graph's idle model, or the graph's captured "standing"
frames (a still stretch of the collection's capture), played forward and backward in turn. Every
piece stands on one spot: its feet's midpoint on the spot's centre, its hip heading the spot's, so
the character does not drift while it idles; pieces are joined by the seams' inertialization.

Pieces are raised or lowered onto the floor the walk's step models stood on (their "stance"
heights), as captures of standing and of walking may stand on floors a centimetre or two apart.

The settle: the first piece is placed so that its foot on the planted side stands where the walk's
planted foot is, facing the way the last step travelled. Its frames are joined to the walk by a
seam of SETTLE_HALFLIFE_S (slower than a step's: the body decelerates into standing), and its legs
are set by two-bone IK: the planted foot stays and turns flat over PLANT_S; the trailing foot
lifts by LIFT_LEGS of the leg, moves and lands beside it within SWING_SHARE of SETTLE_S. From then
on the feet stay where they are (every later piece's legs set by the same IK) and every later
piece starts with its pelvis where the first piece's started: the pieces' pelvis, spine and arms
move as standing people do, the feet do not shuffle and the body does not wander between pieces."""

import numpy as np

from . import ik, kinematics, quaternion, steps
from .placement import placed
from .step_search import hip_heading, rotate_y

SETTLE_S = 0.8
SETTLE_HALFLIFE_S = 0.2
PLANT_S = 0.2
RAMP_S = 0.15  # the settle's IK takes the legs over from the walk's within this
SWING_SHARE = 0.7
LIFT_LEGS = 0.05
MIN_STANDING_S = 0.5  # captured standing shorter than this is no idle
MAX_SETTLE_TURN = np.radians(60.0)  # the most a settle turns from the walk to face a point


class StandingError(ValueError):
    pass


def smooth(u):
    u = np.clip(u, 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def slerp(a, b, w):
    """Per row: from quaternion a toward b by w (0..1)."""
    step = quaternion.canonical(quaternion.multiply(quaternion.conjugate(a), b))
    return quaternion.canonical(quaternion.multiply(a, quaternion.power(step, w[:, None])))


class Spot:
    """Where the character stands: the feet's midpoint (x, z) and the hip heading; once it has
    settled, where each ankle is and how it is turned ({side: (position, orientation)}) and where
    each piece's pelvis starts (x, z)."""

    def __init__(self, centre, heading):
        self.centre, self.heading = np.asarray(centre, dtype=np.float64), float(heading)
        self.feet = None
        self.pelvis = None
        self.placement = None  # (yaw, shift) of the first piece: captured standing keeps it
        self.lift = 0.0  # metres every piece is raised: its feet on the walk's floor


def feet_centre(rig, positions):
    return (positions[rig.ankle["left"]][[0, 2]] + positions[rig.ankle["right"]][[0, 2]]) / 2


def on_spot(rig, rotations, translations, spot, same_capture=False):
    """The piece turned and moved so that its first frame stands on the spot: its pelvis where
    every piece's starts once the spot has one (the feet are set by IK, pinned), else its feet's
    midpoint on the spot's centre. Pieces of one capture (same_capture: captured standing played
    forward and backward) are all placed as the first was, so each goes on where the last ended."""
    if same_capture and spot.placement is not None:
        return placed(rig, rotations, translations, *spot.placement, spot.lift)
    first = rig.positions(rotations[:1], translations[:1])[0]
    yaw = spot.heading - float(hip_heading(first, rig.left_hip, rig.right_hip))
    at, point = ((spot.pelvis, first[rig.pelvis][[0, 2]]) if spot.pelvis is not None
                 else (spot.centre, feet_centre(rig, first)))  # fmt: skip
    spot.placement = spot.placement or (yaw, at - rotate_y(point, yaw))
    return placed(rig, rotations, translations, yaw, at - rotate_y(point, yaw), spot.lift)


def floor_lift(rig, rotations, translations, floors):
    """How far to raise a piece of standing so that its feet stand on the floors the walk's
    models stood on ({(side, "toe" or "ankle"): metres}, foot_hold's); 0 where none is known."""
    first = rig.positions(rotations[:1], translations[:1])[0]
    gaps = []
    for side, ankle in rig.ankle.items():
        toe = rig.joint_map.get(f"{side}_toe")
        point, joint = ("toe", rig.names.index(toe)) if toe in rig.names else ("ankle", ankle)
        if (side, point) in floors:
            gaps.append(floors[(side, point)] - first[joint, 1])
    return float(np.mean(gaps)) if gaps else 0.0


def settle_spot(rig, rotations, translations, planted, at, heading):
    """The spot of a first piece whose `planted` ankle stands at `at` (x, z), facing heading."""
    first = rig.positions(rotations[:1], translations[:1])[0]
    yaw = heading - float(hip_heading(first, rig.left_hip, rig.right_hip))
    shift = at - rotate_y(first[rig.ankle[planted]][[0, 2]], yaw)
    return Spot(rotate_y(feet_centre(rig, first), yaw) + shift, heading)


class Legs:
    """The leg chains (hip, knee, ankle) of a rig, by its joint map."""

    def __init__(self, rig):
        index = {name: rig.names.index(joint) for name, joint in rig.joint_map.items()
                 if joint in rig.names}  # fmt: skip
        try:
            self.chains = {side: tuple(index[f"{side}_{p}"] for p in ("hip", "knee", "ankle"))
                           for side in ("left", "right")}  # fmt: skip
        except KeyError as e:
            raise StandingError(f"the joint map lacks {e.args[0]}: no legs to stand on") from None
        self.rig = rig
        self.length = steps.leg_length(rig.parents, rig.offsets, {
            f"{side}_{part}": j for side, chain in self.chains.items()
            for part, j in zip(("hip", "knee", "ankle"), chain)})  # fmt: skip

    def set(self, rotations, translations, side, targets, orientations):
        """The leg's ankle set at targets, turned to orientations; the knee bends forward (a
        standing leg is nearly straight: its own bend's direction is noise, and would flip)."""
        rig = self.rig
        hips = rig.positions(rotations, translations)
        heading = hip_heading(hips, rig.left_hip, rig.right_hip)
        forward = np.stack([np.sin(heading), np.zeros_like(heading), np.cos(heading)], axis=-1)
        out, _, _ = ik.two_bone(rig.parents, rig.offsets, rotations, translations,
                                rig.translated, self.chains[side], targets, poles=forward,
                                end_orientations=orientations)  # fmt: skip
        return out


def feet_paths(rig, legs, last, piece, planted, fps):
    """{side: (targets (frames, 3), orientations (frames, 4))} over the piece's frames: the
    planted foot from where it stands to where the piece has it, the trailing one stepping beside
    it; both then stay where the piece has them at the settle's end."""
    n = len(piece[0])
    end = min(n, int(round(SETTLE_S * fps))) - 1
    before_p, before_o = kinematics.world_transforms(rig.parents, rig.offsets, last[0][-1:],
                                                      last[1][-1:], rig.translated)  # fmt: skip
    held = np.minimum(np.arange(n), end)
    after_p, after_o = kinematics.world_transforms(rig.parents, rig.offsets, piece[0][held],
                                                    piece[1][held], rig.translated)  # fmt: skip
    k = np.arange(n) / fps
    out = {}
    for side, ankle in rig.ankle.items():
        if side == planted:
            w = turning = smooth(k / PLANT_S)
            lift = np.zeros(n)
        else:  # it leaves on its toes: flat again within the first half of its swing, so the
            # toe rises as the ankle comes down
            u = k / (SETTLE_S * SWING_SHARE)
            w, turning = smooth(u), smooth(2 * u)
            lift = LIFT_LEGS * legs.length * np.sin(np.pi * np.clip(u, 0.0, 1.0))
        start, goal = before_p[0, ankle], after_p[:, ankle]
        targets = start + (goal - start) * w[:, None]
        targets[:, 1] += lift
        turn = slerp(np.broadcast_to(before_o[0, ankle], (n, 4)), after_o[:, ankle], turning)
        out[side] = targets, turn
    return out


def at_least(rotations, translations, n):
    """The piece played forward, then backward, and so on, until it has at least n frames (each
    turn starts at the frame the last ended on, which it leaves out)."""
    r, t, forward = [rotations], [translations], False
    while sum(len(x) for x in r) < n and len(rotations) > 1:
        order = slice(1, None) if forward else slice(-2, None, -1)
        r.append(rotations[order])
        t.append(translations[order])
        forward = not forward
    return np.concatenate(r), np.concatenate(t)


def feet_at(rig, rotations, translations, frame=0):
    """{side: (ankle position, orientation)} at one frame."""
    positions, orientations = kinematics.world_transforms(
        rig.parents, rig.offsets, rotations[frame : frame + 1], translations[frame : frame + 1],
        rig.translated)  # fmt: skip
    return {side: (positions[0, j], orientations[0, j]) for side, j in rig.ankle.items()}


def pinned(legs, rotations, translations, feet):
    """The frames with each ankle set where feet has it: {side: (targets, orientations)}, one
    per frame or one for all."""
    n = len(rotations)
    for side, (targets, turns) in feet.items():
        rotations = legs.set(rotations, translations, side,
                             np.broadcast_to(targets, (n, 3)), np.broadcast_to(turns, (n, 4)))
    return rotations


def settle(rig, legs, seams, last, piece, planted, fps):
    """The first standing piece joined to the walk: (rotations, translations, feet): feet is
    {side: (ankle position, orientation)} where the feet stand from the settle's end on. last:
    the walk's last two frames (rotations, translations); piece: the piece placed on its spot."""
    rotations, translations = seams.inertialize(last[0], last[1], piece[0], piece[1], fps,
                                                SETTLE_HALFLIFE_S)  # fmt: skip
    paths = feet_paths(rig, legs, last, piece, planted, fps)
    solved = pinned(legs, rotations, translations, paths)
    # the IK's legs (their knees bend forward) taken over from the walk's within RAMP_S
    joints = sorted({j for chain in legs.chains.values() for j in chain})
    w = smooth(np.arange(len(rotations)) / (RAMP_S * fps))
    for j in joints:
        solved[:, j] = slerp(rotations[:, j], solved[:, j], w)
    return solved, translations, {side: (p[0][-1], p[1][-1]) for side, p in paths.items()}


def travel_heading(rig, rotations, translations, fallback):
    """The heading of the pelvis's travel over the frames (the way the last step went), or
    fallback where it hardly moved."""
    ends = rig.positions(rotations[[0, -1]], translations[[0, -1]])[:, rig.pelvis][:, [0, 2]]
    moved = ends[1] - ends[0]
    if np.linalg.norm(moved) < 0.05:
        return float(fallback)
    return float(np.arctan2(moved[0], moved[1]))


class CapturedStanding:
    """The graph's "standing" frames as pieces, forward and backward in turn."""

    def __init__(self, document, rig):
        try:
            rotations = np.asarray(document["rotations"], dtype=np.float64)
            translations = np.asarray(document.get("translations") or np.zeros(
                (len(rotations), 0, 3)), dtype=np.float64)  # fmt: skip
            fps = float(document["fps"])
        except (KeyError, TypeError, ValueError) as e:
            raise StandingError(f'its "standing" frames are malformed ({e})') from None
        shape_ok = (rotations.ndim == 3 and rotations.shape[1:] == (len(rig.names), 4)
                    and translations.shape == (len(rotations), len(rig.translated), 3))  # fmt: skip
        if not shape_ok or not np.all(np.isfinite(rotations)) or not np.all(
                np.isfinite(translations)):  # fmt: skip
            raise StandingError('its "standing" frames do not fit its skeleton: rebuild the graph '
                                "(modb model graph NAME --collection C)")  # fmt: skip
        if len(rotations) < max(2, MIN_STANDING_S * fps):
            raise StandingError(f'its "standing" frames last under {MIN_STANDING_S:g} s')
        self.rotations = quaternion.canonical(rotations)
        self.translations, self.fps = translations, fps
        self.played = 0

    def piece(self, rng):
        """The next piece: the frames forward, then backward, and so on."""
        forward = self.played % 2 == 0
        self.played += 1
        order = slice(None) if forward else slice(None, None, -1)
        return self.rotations[order].copy(), self.translations[order].copy()

