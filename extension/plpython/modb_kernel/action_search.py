"""The scores of an action's motion model whose hand meets a target (after the DFKI pipeline's
constrained actions): the same beam search down the model's k-means tree and the same refinement
(the mixture's likelihood as the prior) as a step's (step_search), the constraint being where the
acting wrist (or wrists) is at the action's keyframe, relative to where the action starts (every
sample starts with its pelvis above the origin, facing +Z).

The keyframe is the model's: the inner bound of its sections (the reference example's keyframe
that alignment pinned every example's onto, motion_model "keyframes"), a canonical frame, so the
wrist there is the spatial B-spline's value at that frame: one row of the basis against the
coefficients, and forward kinematics of the arm's chain only. Which hands act: those whose wrist
the model's mean motion moves (relative to the pelvis) at least half as far as the most moved one.
"""

import numpy as np

from . import kinematics, motion_model
from .step_search import StepModel

ACTING_SHARE = 0.5  # a wrist moving at least this share of the most moved one's way acts
ACTION_PRIOR_WEIGHT_M = 0.005  # metres of hand error per unit of Mahalanobis distance
SIDES = ("left", "right")


class ActionModel(StepModel):
    """A motion model of an action prepared for its constraint (read-only once made, as a step's).
    keyframe: the canonical frame of its constraint, or None (no inner keyframe: a motion such as a
    wave with a start and an end of its repetition has two, and takes no hand target); hands: the
    acting sides; usual_wrists: (hands, 3) where the mean motion has them at the keyframe.

    Its refinement may take the scores as far as the mixture draws its samples (max_mahalanobis2,
    a wall there) under a lighter prior than a step's: a hand's target is one point, which many
    poses of the examples' spread meet (a step's constraints pin more of it); the step's weight
    left the box's corners 3-10 cm off, this one within 2 cm but for corners no example reaches."""

    prior_weight = ACTION_PRIOR_WEIGHT_M
    within_mass = True

    def __init__(self, model, tree, rig):
        self._prepare(model, tree, rig)  # its search passes the quickest, as a step's
        inner = list(model.get("keyframes", []))[1:-1]
        self.keyframe = int(inner[0]) if len(inner) == 1 else None
        self.repetition = tuple(int(k) for k in inner) if len(inner) == 2 else None
        spatial = model["spatial"]
        k = spatial["n_basis"]
        at = self.keyframe if self.keyframe is not None else (model["n_frames"] - 1) // 2
        row = motion_model.basis(model["n_frames"], k)[at]
        mean = np.asarray(spatial["mean"], dtype=np.float64).reshape(k, -1)
        components = np.asarray(spatial["components"], dtype=np.float64).reshape(self.split, k, -1)
        self.key_mean, self.key_components = row @ mean, components.transpose(0, 2, 1) @ row
        wrists = {s: rig.names.index(rig.joint_map[f"{s}_wrist"]) for s in SIDES
                  if rig.joint_map.get(f"{s}_wrist") in rig.names}  # fmt: skip
        if not wrists:
            raise ValueError("its joint map names no wrist (left_wrist, right_wrist)")
        self._chain(list(wrists.values()))
        moved = self._moved(wrists)
        self.hands = tuple(s for s in wrists if moved[s] >= ACTING_SHARE * max(moved.values()))
        self.wrist_joints = [wrists[s] for s in self.hands]
        self.usual_wrists = self.wrists(np.zeros((1, self.dimensions)))[0]
        self.swing = None
        self.seconds = (model["n_frames"] - 1) / model["fps"]
        self._freeze()

    def _chain(self, ends):
        """The joints forward kinematics of the wrists needs: theirs and their ancestors'."""
        rig, chain = self.rig, set()
        for j in ends:
            while j >= 0 and j not in chain:
                chain.add(j)
                j = rig.parents[j]
        self.arm = sorted(chain)
        at = {j: k for k, j in enumerate(self.arm)}
        self.arm_at = at
        self.arm_parents = [at.get(rig.parents[j], -1) for j in self.arm]
        self.arm_translated = [k for k, j in enumerate(self.arm) if j in rig.translated]
        self.arm_columns = [rig.translated.index(j) for j in self.arm if j in rig.translated]

    def _moved(self, wrists):
        """Per side, how far the mean motion moves the wrist relative to the pelvis (metres)."""
        model, rig = self.model, self.rig
        rotations, translations = motion_model.canonical_frames(model, np.zeros(self.split))
        p = kinematics.world_positions(rig.parents, rig.offsets, rotations, translations,
                                       rig.translated)  # fmt: skip
        out = {}
        for side, j in wrists.items():
            relative = p[:, j] - p[:, rig.pelvis]
            out[side] = float(np.linalg.norm(np.diff(relative, axis=0), axis=-1).sum())
        return out

    def wrists(self, scores):
        """(rows, hands, 3): the acting wrists at the keyframe, for rows of joined scores."""
        scores = np.atleast_2d(scores)
        flat = self.key_mean + scores[:, : self.split] @ self.key_components
        m, n_t = len(scores), len(self.model["translated"])
        translations = flat[:, : 3 * n_t].reshape(m, n_t, 3)
        rotations = flat[:, 3 * n_t :].reshape(m, -1, 4) / self.weights[:, None]
        rotations /= np.maximum(np.linalg.norm(rotations, axis=-1, keepdims=True), 1e-12)
        if "limits" in self.model:
            rotations = motion_model.within_limits(rotations, self.model["limits"])
        positions = kinematics.world_positions(self.arm_parents, self.rig.offsets[self.arm],
                                               rotations[:, self.arm],
                                               translations[:, self.arm_columns],
                                               self.arm_translated)  # fmt: skip
        return positions[:, [self.arm_at[j] for j in self.wrist_joints]]

    def errors(self, scores, target):
        """Per row: the acting wrists' distance to target (hands, 3) at the keyframe (metres; the
        root mean square over the hands)."""
        miss = self.wrists(scores) - np.asarray(target, dtype=np.float64).reshape(1, -1, 3)
        return np.sqrt(np.mean(np.sum(miss**2, axis=-1), axis=-1))

    def constraint_residuals(self, scores, target):
        miss = self.wrists(scores) - np.asarray(target, dtype=np.float64).reshape(1, -1, 3)
        return miss.reshape(len(miss), -1)

    def search(self, target, rng=None):
        """(scores, candidates examined): the leaf sample of least error the beam reaches."""
        held, examined = self.beam(target)
        e = self.errors_past_quickest(held, target)
        return held[int(np.argmin(e))], len(held) + examined
