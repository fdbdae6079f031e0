"""The one motion data model shared by loader, client and tests.

A `Skeleton` is the joint hierarchy as loaded (offsets already in metres, the
source's channels kept so a file can be written back in its own layout). A
`Motion` is one clip version: per frame, a unit quaternion per joint (relative
to the parent) and a translation for every joint that has position channels.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from modb_kernel import kinematics
from modb_kernel.joints import STANDARD_JOINTS  # noqa: F401  (part of the model's vocabulary)


@dataclass(frozen=True)
class Joint:
    name: str
    parent: int  # index into Skeleton.joints, -1 for the root
    offset: tuple[float, float, float]  # metres, in the parent's frame
    channels: tuple[str, ...]  # as loaded, e.g. ('Xposition', ..., 'Zrotation', ...)
    rotation_order: str  # axes of the rotation channels in file order, e.g. 'ZXY'; '' for none
    end_site: tuple[float, float, float] | None = None  # metres

    @property
    def has_position(self) -> bool:
        """Position channels: BVH 'Xposition'..., ASF root 'TX'..."""
        return any(
            c.lower().endswith("position") or c.lower() in ("tx", "ty", "tz") for c in self.channels
        )


@dataclass
class Skeleton:
    joints: list[Joint]
    unit_m: float  # metres per source length unit
    source_format: str  # 'bvh' | 'asf'
    joint_map: dict[str, str] = field(default_factory=dict)  # standard name -> joint name
    mirror_pairs: list[tuple[str, str]] = field(default_factory=list)  # (left, right)
    name: str = ""
    # standard name -> twist and swing axes, and the pose they come from (modb_kernel.retarget);
    # empty: derived when needed
    joint_axes: dict[str, Any] = field(default_factory=dict)

    @property
    def names(self) -> list[str]:
        return [j.name for j in self.joints]

    @property
    def parents(self) -> list[int]:
        return [j.parent for j in self.joints]

    @property
    def offsets(self) -> np.ndarray:
        return np.array([j.offset for j in self.joints], dtype=np.float64)

    @property
    def translated(self) -> list[int]:
        """Indices of joints whose frames carry a translation (those with position channels)."""
        return [i for i, j in enumerate(self.joints) if j.has_position]

    def index(self, name: str) -> int:
        return self.names.index(name)

    def above_pelvis(self) -> list[int]:
        """The pelvis's ancestors, nearest first: frames of reference (Bandai's joint_Root on the
        ground at the capture origin), not the body. Empty when the pelvis is the top joint or the
        joint map names none."""
        if "pelvis" not in self.joint_map:
            return []
        out, k = [], self.parents[self.index(self.joint_map["pelvis"])]
        while k >= 0:
            out.append(k)
            k = self.parents[k]
        return out

    def rest_positions(self) -> np.ndarray:
        return kinematics.rest_positions(self.parents, self.offsets)

    def hierarchy_json(self) -> dict[str, Any]:
        """The immutable part, in modb.skeletons.hierarchy; its sha256 identifies the skeleton."""
        return {
            "format": self.source_format,
            "unit_m": self.unit_m,
            "joints": [
                {
                    "name": j.name,
                    "parent": j.parent,
                    "offset": list(j.offset),
                    "channels": list(j.channels),
                    "rotation_order": j.rotation_order,
                    "end_site": None if j.end_site is None else list(j.end_site),
                }
                for j in self.joints
            ],
            "translated": self.translated,
            "rest_positions": np.round(self.rest_positions(), 9).tolist(),
        }

    @classmethod
    def from_row(
        cls,
        hierarchy: dict[str, Any],
        joint_map: dict[str, str],
        mirror_pairs: list[list[str]],
        name: str = "",
        joint_axes: dict[str, Any] | None = None,
    ) -> Skeleton:
        joints = [
            Joint(
                name=j["name"],
                parent=int(j["parent"]),
                offset=tuple(j["offset"]),
                channels=tuple(j["channels"]),
                rotation_order=j["rotation_order"],
                end_site=None if j.get("end_site") is None else tuple(j["end_site"]),
            )
            for j in hierarchy["joints"]
        ]
        return cls(
            joints=joints,
            unit_m=float(hierarchy["unit_m"]),
            source_format=hierarchy["format"],
            joint_map=dict(joint_map),
            mirror_pairs=[(a, b) for a, b in mirror_pairs],
            name=name,
            joint_axes=dict(joint_axes or {}),
        )


@dataclass
class Source:
    path: str
    sha256: str
    units_rule: str  # how unit_m was chosen, as printed to the user


@dataclass
class Motion:
    skeleton: Skeleton
    fps: float
    rotations: np.ndarray  # (frames, joints, 4) float64, unit, w >= 0
    translations: np.ndarray  # (frames, len(skeleton.translated), 3) metres
    name: str
    source: Source | None = None
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        return int(self.rotations.shape[0])

    def world_positions(self) -> np.ndarray:
        """(frames, joints, 3) world positions of every joint, metres."""
        return kinematics.world_positions(
            self.skeleton.parents,
            self.skeleton.offsets,
            self.rotations,
            self.translations,
            self.skeleton.translated,
        )
