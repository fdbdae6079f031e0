"""Inertialization at seams (Bollo, GDC 2016; Holden's critically damped offsets): the jump between
the previous snippet's last frame and this one's first, in pose and in velocity, is carried as an
offset that decays smoothly to nothing, so the new snippet's motion shows at once and the seam has
no jump in position or speed.

The offsets are taken where a seam is naturally continuous: the pelvis's world transform (the
chain places each snippet's pelvis where the last one left it) and every joint below the pelvis
relative to its parent. Joints above the pelvis (Bandai's `joint_Root` at the capture origin, which
jumps metres between clips) stay as placed, and the pelvis is re-expressed below them.
"""

from __future__ import annotations

import math

import numpy as np

from modb_kernel import kinematics, quaternion

from modb.motion import Skeleton

from .chain import Frame

HALFLIFE_SECONDS = 0.1  # the offset halves in this time: gone (< 1%) within about 0.7 s


def decay(
    offset: np.ndarray, velocity: np.ndarray, times: np.ndarray, halflife: float
) -> np.ndarray:
    """A critically damped spring's offset at `times` from `offset` moving at `velocity`:
    e^(-y t) (x0 + (v0 + y x0) t), y = 2 ln 2 / halflife (per time, then per offset element)."""
    y = 2.0 * math.log(2.0) / halflife
    t = times.reshape((-1,) + (1,) * offset.ndim)
    return np.exp(-y * t) * (offset + (velocity + y * offset) * t)


class Seams:
    """The skeleton's parts: the pelvis, the joints below it, the chain of joints above it."""

    def __init__(self, skeleton: Skeleton) -> None:
        self.skeleton = skeleton
        self.pelvis = skeleton.index(skeleton.joint_map["pelvis"])
        below, parents = [], skeleton.parents
        for k in range(len(parents)):  # parents come before their children
            if parents[k] == self.pelvis or parents[k] in below:
                below.append(k)
        self.below = below
        self.translated_below = [k for k in below if k in skeleton.translated]

    def _world(self, rotations: np.ndarray, translations: np.ndarray):
        sk = self.skeleton
        return kinematics.world_transforms(
            sk.parents, sk.offsets, rotations, translations, sk.translated
        )

    def inertialize(
        self,
        before: tuple[Frame, Frame] | None,
        rotations: np.ndarray,
        translations: np.ndarray,
        fps: float,
        halflife: float = HALFLIFE_SECONDS,
    ) -> tuple[np.ndarray, np.ndarray]:
        """The snippet's frames (its first stands in for before[1]) with the seam's offsets decaying
        over them. `before`: the previous snippet's last two frames played, None at the start."""
        if before is None or len(rotations) < 2:
            return rotations, translations
        sk, p = self.skeleton, self.pelvis
        old_r = np.stack([before[0].rotations, before[1].rotations])
        old_t = np.stack([before[0].translations, before[1].translations])
        old_pos, old_ori = self._world(old_r, old_t)
        new_pos, new_ori = self._world(rotations, translations)
        times = np.arange(len(rotations)) / fps
        out_r, out_t = rotations.copy(), translations.copy()

        def rotation_offsets(old: np.ndarray, new: np.ndarray) -> np.ndarray:
            """Per frame of the new snippet: its rotations turned by the decaying offset."""
            offset = quaternion.to_rotation_vector(
                quaternion.multiply(old[1], quaternion.conjugate(new[0]))
            )
            old_turn = quaternion.to_rotation_vector(
                quaternion.multiply(old[1], quaternion.conjugate(old[0]))
            )
            new_turn = quaternion.to_rotation_vector(
                quaternion.multiply(new[1], quaternion.conjugate(new[0]))
            )
            moved = decay(offset, (old_turn - new_turn) * fps, times, halflife)
            return quaternion.canonical(
                quaternion.multiply(quaternion.from_rotation_vector(moved), new)
            )

        def translation_offsets(old: np.ndarray, new: np.ndarray) -> np.ndarray:
            velocity = (old[1] - old[0]) * fps - (new[1] - new[0]) * fps
            return new + decay(old[1] - new[0], velocity, times, halflife)

        if self.below:
            out_r[:, self.below] = rotation_offsets(old_r[:, self.below], rotations[:, self.below])
        for k in self.translated_below:
            t = sk.translated.index(k)
            out_t[:, t] = translation_offsets(old_t[:, t], translations[:, t])
        # the pelvis in the world, then below the (unchanged) joints above it
        pelvis_ori = rotation_offsets(old_ori[:, p], new_ori[:, p])
        pelvis_pos = translation_offsets(old_pos[:, p], new_pos[:, p])
        parent = sk.parents[p]
        if parent < 0:
            out_r[:, p] = pelvis_ori
            local = pelvis_pos
        else:
            inverse = quaternion.conjugate(new_ori[:, parent])
            out_r[:, p] = quaternion.canonical(quaternion.multiply(inverse, pelvis_ori))
            local = quaternion.rotate(inverse, pelvis_pos - new_pos[:, parent])
        if p in sk.translated:  # else its position follows the joints above it
            out_t[:, sk.translated.index(p)] = local
        return out_r, out_t
