"""Inertialization at seams (Bollo, GDC 2016; Holden's critically damped offsets): the jump between
the previous snippet's (or model step's) last frame and this one's first, in pose and in velocity,
is carried as an offset that decays smoothly to nothing, so the new motion shows at once and the
seam has no jump in position or speed. Plain numpy: both synthesis families use it, in the client
and in the server.

The offsets are taken where a seam is naturally continuous: the pelvis's world transform (the
chain places each snippet's pelvis where the last one left it) and every joint below the pelvis
relative to its parent. Joints above the pelvis (Bandai's `joint_Root` at the capture origin, which
jumps metres between clips) stay as placed, and the pelvis is re-expressed below them.
"""

import math

import numpy as np

from . import kinematics, quaternion

HALFLIFE_SECONDS = 0.1  # the offset halves in this time: gone (< 1%) within about 0.7 s


def decay(offset, velocity, times, halflife):
    """A critically damped spring's offset at `times` from `offset` moving at `velocity`:
    e^(-y t) (x0 + (v0 + y x0) t), y = 2 ln 2 / halflife (per time, then per offset element)."""
    y = 2.0 * math.log(2.0) / halflife
    t = times.reshape((-1,) + (1,) * offset.ndim)
    return np.exp(-y * t) * (offset + (velocity + y * offset) * t)


class Seams:
    """The skeleton's parts: the pelvis, the joints below it, the chain of joints above it."""

    def __init__(self, parents, offsets, translated, pelvis):
        self.parents, self.offsets, self.translated = list(parents), offsets, list(translated)
        self.pelvis = pelvis
        below = []
        for k in range(len(parents)):  # parents come before their children
            if parents[k] == self.pelvis or parents[k] in below:
                below.append(k)
        self.below = below
        self.translated_below = [k for k in below if k in self.translated]

    def _world(self, rotations, translations):
        return kinematics.world_transforms(
            self.parents, self.offsets, rotations, translations, self.translated
        )

    def inertialize(self, old_r, old_t, rotations, translations, fps, halflife=HALFLIFE_SECONDS):
        """The new frames (the first stands in for the last old one) with the seam's offsets
        decaying over them. old_r, old_t: the rotations and translations of the last two frames
        played before."""
        if len(rotations) < 2:
            return rotations, translations
        p = self.pelvis
        old_pos, old_ori = self._world(old_r, old_t)
        new_pos, new_ori = self._world(rotations, translations)
        times = np.arange(len(rotations)) / fps
        out_r, out_t = rotations.copy(), translations.copy()

        def rotation_offsets(old, new):
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

        def translation_offsets(old, new):
            velocity = (old[1] - old[0]) * fps - (new[1] - new[0]) * fps
            return new + decay(old[1] - new[0], velocity, times, halflife)

        if self.below:
            out_r[:, self.below] = rotation_offsets(old_r[:, self.below], rotations[:, self.below])
        for k in self.translated_below:
            t = self.translated.index(k)
            out_t[:, t] = translation_offsets(old_t[:, t], translations[:, t])
        # the pelvis in the world, then below the (unchanged) joints above it
        pelvis_ori = rotation_offsets(old_ori[:, p], new_ori[:, p])
        pelvis_pos = translation_offsets(old_pos[:, p], new_pos[:, p])
        parent = self.parents[p]
        if parent < 0:
            out_r[:, p] = pelvis_ori
            local = pelvis_pos
        else:
            inverse = quaternion.conjugate(new_ori[:, parent])
            out_r[:, p] = quaternion.canonical(quaternion.multiply(inverse, pelvis_ori))
            local = quaternion.rotate(inverse, pelvis_pos - new_pos[:, parent])
        if p in self.translated:  # else its position follows the joints above it
            out_t[:, self.translated.index(p)] = local
        return out_r, out_t
