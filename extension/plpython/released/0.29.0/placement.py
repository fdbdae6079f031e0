"""Frames placed in the world: turned about +Y and moved on the ground by their top joints."""

import numpy as np

from . import quaternion


class PlacementError(ValueError):
    pass


def placed(rig, rotations, translations, yaw, shift, lift=0.0):
    """The frames turned by yaw about +Y, moved by shift (x, z) on the ground and raised by lift
    metres: the top joints carry it (a skeleton whose top joint has no translation cannot
    travel)."""
    turn = quaternion.about_axis("Y", yaw)
    rotations, translations = rotations.copy(), translations.copy()
    for j, parent in enumerate(rig.parents):
        if parent >= 0:
            continue
        if j not in rig.translated:
            raise PlacementError(f"top joint {rig.names[j]} has no translation: it cannot travel")
        k = rig.translated.index(j)
        rotations[:, j] = quaternion.multiply(turn[None], rotations[:, j])
        moved = quaternion.rotate(np.broadcast_to(turn, (len(translations), 4)), translations[:, k])
        translations[:, k] = moved + np.array([shift[0], lift, shift[1]])
    return quaternion.canonical(rotations), translations
