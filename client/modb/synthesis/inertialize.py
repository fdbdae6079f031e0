"""Inertialization at the seams of snippet chains: the kernel's (modb_kernel.inertialization, which
synthesis from motion models uses too) for a Skeleton and the chain's Frames."""

from __future__ import annotations

import numpy as np

from modb_kernel import inertialization
from modb_kernel.inertialization import HALFLIFE_SECONDS, decay

from modb.motion import Skeleton

from .chain import Frame

__all__ = ["HALFLIFE_SECONDS", "Seams", "decay"]


class Seams(inertialization.Seams):
    """The kernel's seams (modb_kernel.inertialization) for a Skeleton and the chain's Frames."""

    def __init__(self, skeleton: Skeleton) -> None:
        pelvis = skeleton.index(skeleton.joint_map["pelvis"])
        super().__init__(skeleton.parents, skeleton.offsets, skeleton.translated, pelvis)

    def inertialize_after(
        self,
        before: tuple[Frame, Frame] | None,
        rotations: np.ndarray,
        translations: np.ndarray,
        fps: float,
    ) -> tuple[np.ndarray, np.ndarray]:
        """The snippet's frames (its first stands in for before[1]) with the seam's offsets decaying
        over them. `before`: the previous snippet's last two frames played, None at the start."""
        if before is None:
            return rotations, translations
        old_r = np.stack([before[0].rotations, before[1].rotations])
        old_t = np.stack([before[0].translations, before[1].translations])
        return self.inertialize(old_r, old_t, rotations, translations, fps)
