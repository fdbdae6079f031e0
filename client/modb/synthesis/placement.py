"""Where snippets go in the world: the avatar's ground point and heading, moved by each snippet.

The same arithmetic as modb.local_to_world / modb.synthesis_step_end in the extension, operation for
operation (libm's sin/cos/atan2 on both sides), so the Python Avatar and modb.synthesize place a
chain identically. Heading theta faces (sin theta, 0, cos theta); a character's +X is its left.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from modb_kernel import quaternion

Point = tuple[float, float, float]


@dataclass(frozen=True)
class Placement:
    """The avatar between snippets: pelvis on the ground at `position`, facing `heading`."""

    position: Point
    heading: float


def local_to_world(origin: Point, heading: float, local: Point) -> Point:
    c, s = math.cos(heading), math.sin(heading)
    return (
        origin[0] + (local[0] * c + local[2] * s),
        origin[1] + local[1],
        origin[2] + (local[2] * c - local[0] * s),
    )


def after(
    placement: Placement, net_translation: tuple[float, ...], net_heading: float
) -> Placement:
    """Where a snippet placed at `placement` leaves the avatar: its ground travel and its turn."""
    position = local_to_world(
        placement.position, placement.heading, (net_translation[0], 0.0, net_translation[2])
    )
    turned = placement.heading + net_heading
    return Placement(position, math.atan2(math.sin(turned), math.cos(turned)))


def ground_distance(position: Point, goal: tuple[float, ...]) -> float:
    """Distance on the ground to a goal {x, z} or {x, y, z} (its last value is z)."""
    dx, dz = position[0] - goal[0], position[2] - goal[-1]
    return math.sqrt(dx * dx + dz * dz)


def place_root(
    rotations: np.ndarray,
    translations: np.ndarray,
    source_ground: np.ndarray,
    source_heading: float,
    placement: Placement,
) -> tuple[np.ndarray, np.ndarray]:
    """The root's rotations (F, 4) and translations (F, 3) moved so that the source frame whose
    pelvis stands on `source_ground` facing `source_heading` stands on the placement instead."""
    turn = quaternion.about_axis("Y", placement.heading - source_heading)
    placed_rotations = quaternion.canonical(quaternion.multiply(turn, rotations))
    shift = np.asarray(placement.position) - quaternion.rotate(turn, source_ground)
    return placed_rotations, quaternion.rotate(turn, translations) + shift
