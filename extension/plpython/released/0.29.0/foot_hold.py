"""Stance feet held: from touchdown to lift-off each foot stays where it touched down, at the height
its source holds it, in both synthesis families.

A synthesized strip is its sources joined: placement and the seams (inertialization) move the body
onto each new piece over a few frames, and a foot that stands through that slides with it; the
seam's velocity offset carries a landing foot's descent on into the floor and slows a lifting one.
Here the pieces' own frames as they were placed, before the seams moved them (the reference),
decide, and the legs follow by ik.two_bone (the knee bending the way the motion bends it):

- when each foot is down: the steps' contact rule (steps.contacts) on the reference's last
  CONTEXT_S seconds. While down, its contact point is held on the ground: the ankle while the heel
  carries the weight, the toe once the ankle moves faster than it (the foot rolls over its toes),
  each from where the strip shows it when it takes over, so nothing jumps. A hold that would take
  the foot more than UNLOCK_M from the strip's is let go until the foot lifts. After lift-off the
  offset dies away from rest (critically damped, RELEASE_S: soon after lift-off, while the foot is
  still slow; later, or carrying the hold's own speed, it hurried the swing).
- at what height, down or not: the ankle and the toe at the reference's heights (the foot pitched
  to put the toe there), never below the FLOOR_PERCENTILE-th percentile of their heights while
  down; where one piece starts higher or lower than the last left off, that jump is taken away and
  decays with a half-life of SEAM_S, so heights stay continuous.

The leg is never made straighter than REACH of its length unless the strip's own leg is (a
straight knee pops). FootHold works on a strip in pieces as it is made (an avatar's stream, a step
at a time): a piece's last frames are judged without the frames that follow them.
"""

import numpy as np

from . import ik, kinematics, quaternion, steps
from .inertialization import HALFLIFE_SECONDS as HALFLIFE_S, decay

UNLOCK_M = 0.15  # metres: a hold this far from the strip's foot is let go
REACH = 0.98  # of the leg's length
CONTEXT_S = 2.0  # seconds of reference frames the contact rule reads (its ground, its speeds)
RELEASE_S = HALFLIFE_S / 2  # the half-life of a hold's offset after lift-off
SEAM_S = HALFLIFE_S / 4  # the half-life of a piece's jump in the reference's heights
FLOOR_PERCENTILE = 25  # a foot's point never lower than this percentile of its standing heights
SIDES = steps.SIDES


class _Foot:
    """One foot's hold: the ground offset (3,) from the strip's ankle to where the held foot's
    ankle goes, the point held (pivot 0 ankle, 1 toe, and where), and the last lift-off."""

    def __init__(self):
        self.offset = np.zeros(3)
        self.pivot, self.point = None, None
        self.let_go = False
        self.released = None  # [frames since lift-off, the offset at lift-off]


class FootHold:
    def __init__(self, parents, offsets, translated, names, joint_map, fps, floors=None):
        """floors: {(side, "ankle" or "toe"): metres} the capture's floors where known (a motion
        model's "stance", stance_heights), else each is estimated from the reference."""
        self.parents, self.offsets = list(parents), np.asarray(offsets, dtype=np.float64)
        self.translated, self.fps = list(translated), float(fps)
        self.index = steps.joint_indices(list(names), joint_map)
        self.leg = steps.leg_length(self.parents, self.offsets, self.index)
        self.feet = {side: _Foot() for side in SIDES}
        self.context = int(round(CONTEXT_S * self.fps))
        self.history = np.zeros((0, len(self._points), 3))  # the reference's feet, last frames
        self.last_height = {}  # (side, joint) -> the reference's last height of it
        self.down_weight = {}  # side -> how much the foot was down at the last frame
        self.floors = {}  # (side, point) -> its floor at the last frame
        self.known_floors = dict(floors or {})

    @property
    def _points(self):
        return [self.index[f"{s}_{p}"] for s in SIDES for p in ("ankle", "toe")]

    def feed(self, rotations, translations, reference=None):
        """The next frames of the strip with the stance feet held. reference: (rotations,
        translations) of the same frames as their pieces were placed, before the seams moved
        them (None: the strip's own)."""
        rotations = np.asarray(rotations, dtype=np.float64)
        if len(rotations) == 0:
            return rotations
        positions, orientations = kinematics.world_transforms(
            self.parents, self.offsets, rotations, translations, self.translated)  # fmt: skip
        ref = positions if reference is None else kinematics.world_positions(
            self.parents, self.offsets, reference[0], reference[1], self.translated)  # fmt: skip
        down, pivots, floors = self._contacts(ref[:, self._points])
        out = rotations
        across = positions[:, self.index["left_hip"]] - positions[:, self.index["right_hip"]]
        across[:, 1] = 0.0
        across /= np.maximum(np.linalg.norm(across, axis=-1, keepdims=True), 1e-12)
        for side in SIDES:
            ankle, toe = self.index[f"{side}_ankle"], self.index[f"{side}_toe"]
            offsets = self._offsets(self.feet[side], down[side], pivots[side],
                                    positions[:, [ankle, toe]])  # fmt: skip
            heights = [np.maximum(self._height((side, j), ref[:, j, 1]), floors[f"{side}_{part}"])
                       for j, part in ((ankle, "ankle"), (toe, "toe"))]  # fmt: skip
            offsets[:, 1] = heights[0] - positions[:, ankle, 1]
            foot = orientations[:, ankle]
            if toe != ankle:  # a foot down pitched so the toe is at its height too; in the air
                # the strip's pitch, the toe kept above its floor
                shown = positions[:, toe] - positions[:, ankle]
                weight = self._down_weight(side, down[side])
                free = np.maximum(positions[:, toe, 1] + offsets[:, 1], floors[f"{side}_toe"])
                toe_y = weight * heights[1] + (1 - weight) * free
                foot = quaternion.multiply(_pitched(shown, toe_y - heights[0], across), foot)
            out = self._reach(out, translations, side, positions, offsets, foot)
        return out

    def _contacts(self, points):
        """Per side, whether each new frame's foot is down and which of its points carries it,
        by the steps' rule on the last CONTEXT_S seconds of the reference; and per point its
        floor there (FLOOR_PERCENTILE of its heights while its foot was down)."""
        seen = np.concatenate([self.history, points])[-(self.context + len(points)):]
        self.history = seen[-self.context:]
        names = [f"{s}_{p}" for s in SIDES for p in ("ankle", "toe")]
        index = {name: k for k, name in enumerate(names)}
        found = steps.contacts(seen, index, self.leg, self.fps)
        n = len(points)
        pivots, floors = {}, {}
        for s in SIDES:
            ankle = steps.speeds(seen[:, index[f"{s}_ankle"]], self.fps)[-n:]
            toe = steps.speeds(seen[:, index[f"{s}_toe"]], self.fps)[-n:]
            pivots[s] = (toe < ankle).astype(int)  # the slower point carries the foot
            for p in ("ankle", "toe"):
                standing = seen[found[s], index[f"{s}_{p}"], 1]
                floor = self.known_floors.get((s, p), np.percentile(standing, FLOOR_PERCENTILE)
                                              if len(standing) else -np.inf)  # fmt: skip
                # from the last piece's floor to this one's over the piece: no step in it
                last = self.floors.get((s, p), floor)
                self.floors[(s, p)] = floor
                floors[f"{s}_{p}"] = (np.linspace(last, floor, n + 1)[1:] if np.isfinite(last)
                                      else np.full(n, floor))  # fmt: skip
        return {s: found[s][-n:] for s in SIDES}, pivots, floors

    def _down_weight(self, side, down):
        """Per frame, how much the foot is down: 1 down, 0 in the air, moving between them with a
        half-life of SEAM_S (a toe switched at once from its own course to the reference's
        would jump)."""
        weight = self.down_weight.get(side, float(down[0]))
        keep = 0.5 ** (1.0 / (self.fps * SEAM_S))
        out = np.empty(len(down))
        for t, d in enumerate(down):
            weight = keep * weight + (1 - keep) * float(d)
            out[t] = weight
        self.down_weight[side] = weight
        return out

    def _height(self, key, height):
        """A joint's height in the reference, made continuous: a piece that starts higher or
        lower than the last one left off starts with that difference taken away, decaying
        within a few hundredths of a second (the join's velocity is not carried: it sank the
        landing foot and slowed the lifting one)."""
        last = self.last_height.get(key)
        self.last_height[key] = height[-1]
        if last is None:
            return height
        times = np.arange(len(height)) / self.fps
        return height - decay(np.array([height[0] - last]), np.zeros(1), times, SEAM_S)[:, 0]

    def _offsets(self, foot, down, pivots, shown):
        """(frames, 3) ground offsets of the ankle for one foot over the new frames (the module's
        rule); shown: (frames, 2 (ankle, toe), 3) positions in the strip."""
        out = np.zeros((len(down), 3))
        dt = np.array([1.0 / self.fps])
        for t in range(len(down)):
            if down[t] and not foot.let_go:
                if foot.pivot is None or (pivots[t] == 1 and foot.pivot == 0):
                    foot.pivot = int(pivots[t]) if foot.pivot is None else 1
                    foot.point = shown[t, foot.pivot] + foot.offset  # from where it is shown
                wanted = (foot.point - shown[t, foot.pivot]) * (1.0, 0.0, 1.0)
                if np.hypot(wanted[0], wanted[2]) <= UNLOCK_M:
                    foot.offset, foot.released = wanted, None
                    out[t] = wanted
                    continue
                foot.let_go = True  # too far: the foot goes as the strip's until it lifts
            if down[t]:  # let go while down: the offset stays, sliding no more than the strip's
                out[t] = foot.offset
                continue
            foot.let_go, foot.pivot = False, None
            if foot.released is None:
                foot.released = [0, foot.offset.copy()]
            foot.released[0] += 1
            k, offset0 = foot.released
            foot.offset = decay(offset0, np.zeros(3), k * dt, RELEASE_S)[0]  # from rest
            out[t] = foot.offset
        return out

    def _reach(self, rotations, translations, side, positions, offsets, foot):
        """Two-bone IK of the side's leg toward its ankle plus offsets, the foot turned to
        `foot` (world orientations)."""
        chain = [self.index[f"{side}_{p}"] for p in ("hip", "knee", "ankle")]
        hip, knee, ankle = (positions[:, j] for j in chain)
        target = ankle + offsets
        length = np.linalg.norm(knee - hip, axis=-1) + np.linalg.norm(ankle - knee, axis=-1)
        limit = np.maximum(REACH * length, np.linalg.norm(ankle - hip, axis=-1))
        reach = target - hip
        far = np.linalg.norm(reach, axis=-1)
        target = hip + reach * (np.minimum(far, limit) / np.maximum(far, 1e-12))[:, None]
        done, _, _ = ik.two_bone(self.parents, self.offsets, rotations, translations,
                                 self.translated, chain, target, end_orientations=foot)  # fmt: skip
        return done


def _pitched(foot, rise, across):
    """The rotations (frames, 4) about the body's horizontal axis `across` (hip to hip) that put
    the toe `rise` above the ankle (as nearly as the foot's length allows), foot: ankle to toe.
    Turning v about a horizontal unit axis a by t gives the height v_y cos t + (a x v)_y sin t;
    of the two turns that reach `rise`, the smaller. (About an axis of the foot's own, a foot that
    points down, as CMU's does, would swing with the axis.)"""
    p = foot[:, 1]
    q = np.cross(across, foot)[:, 1]
    size = np.maximum(np.hypot(p, q), 1e-12)
    phase = np.arctan2(q, p)
    spread = np.arccos(np.clip(rise / size, -1.0, 1.0))
    turns = np.stack([phase - spread, phase + spread])
    turns = (turns + np.pi) % (2 * np.pi) - np.pi
    turn = np.take_along_axis(turns, np.argmin(np.abs(turns), axis=0)[None], 0)[0]
    return quaternion.from_rotation_vector(across * turn[:, None])


def stance_heights(parents, offsets, translated, names, joint_map, side, clips):
    """{"ankle": m, "toe": m}: the FLOOR_PERCENTILE-th percentile of the heights of the `side`
    foot's ankle and toe over clips [(rotations, translations)] on which it stands throughout
    (a step's examples and their stance foot): the floors a FootHold keeps that foot above."""
    index = steps.joint_indices(list(names), joint_map)
    joints = [index[f"{side}_ankle"], index[f"{side}_toe"]]
    heights = np.concatenate([kinematics.world_positions(parents, offsets, r, t, translated)[
        :, joints, 1] for r, t in clips])  # fmt: skip
    floors = np.percentile(heights, FLOOR_PERCENTILE, axis=0)
    return {"ankle": float(floors[0]), "toe": float(floors[1])}
