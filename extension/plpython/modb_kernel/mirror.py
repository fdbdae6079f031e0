"""Mirroring a clip through the skeleton's left/right pairing: the same motion as if captured in a mirror.

World positions are reflected by S = diag(-1, 1, 1) (x -> -x) with every paired joint swapped. A joint c
with parent j then takes the rotation M_j R_c M_c, where M_j is a reflection in joint j's rest frame
that maps j's children's offsets onto their partners' (M_j off_c = off_m(c)), and the root's parent
reflection is S itself. A translated joint's translation becomes M_j t_c, which keeps its world position
exact whatever M_j is; a fixed offset stays exact as far as the captured skeleton is symmetric.
"""
import numpy as np

from . import quaternion


def partner_index(names, pairs):
    index = {n: k for k, n in enumerate(names)}
    partner = list(range(len(names)))
    for left, right in pairs:
        partner[index[left]], partner[index[right]] = index[right], index[left]
    return partner


def _project_out(n, vectors):
    """n minus its components along each of `vectors` (zero vectors ignored)."""
    n = np.array(n, dtype=np.float64)
    for v in vectors:
        norm = np.linalg.norm(v)
        if norm > 1e-9:
            n = n - np.dot(n, v / norm) * (v / norm)
    return n


def _perpendicular(reference, vectors):
    """The unit vector nearest `reference` perpendicular to every one of `vectors`."""
    for start in (reference, *np.eye(3)):  # if reference is spanned by them, any perpendicular will do
        n = _project_out(start, vectors)
        if np.linalg.norm(n) > 1e-9:
            break
    return n / np.linalg.norm(n)


def _direction_difference(a, b):
    """a/|a| - b/|b|: the reflection along it maps the direction of a onto b's exactly, even when a captured
    skeleton's two sides differ a little in length (CMU 131's toes: 12.8 and 11.9 cm)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if np.linalg.norm(a) < 1e-9 or np.linalg.norm(b) < 1e-9:
        return np.zeros(3)
    return a / np.linalg.norm(a) - b / np.linalg.norm(b)


def reflection_normals(parents, offsets, end_sites, partner):
    """Per joint, the normal of the reflection M_j of its rest frame (see the module docstring)."""
    offsets = np.asarray(offsets, dtype=np.float64)
    n_joints = len(parents)
    children = [[c for c in range(n_joints) if parents[c] == j] for j in range(n_joints)]
    normals = np.zeros((n_joints, 3))
    for j in range(n_joints):
        if partner[j] < j:  # the right side of a pair takes its left partner's reflection
            normals[j] = normals[partner[j]]
            continue
        d = np.zeros(3)
        for c in children[j]:
            diff = _direction_difference(offsets[c], offsets[partner[c]])
            d += diff if np.dot(diff, d) >= 0 else -diff
        if end_sites[j] is not None and end_sites[partner[j]] is not None:
            diff = _direction_difference(end_sites[j], end_sites[partner[j]])
            d += diff if np.dot(diff, d) >= 0 else -diff
        if np.linalg.norm(d) > 1e-6:
            normals[j] = d / np.linalg.norm(d)
        else:
            reference = normals[parents[j]] if parents[j] >= 0 else np.array([1.0, 0.0, 0.0])
            kept = [offsets[c] for c in children[j]]
            if end_sites[j] is not None:
                kept.append(np.asarray(end_sites[j], dtype=np.float64))
            normals[j] = _perpendicular(reference, kept)
    return normals


def mirror(parents, offsets, end_sites, partner, rotations, translations, translated):
    """Mirrored (rotations (F, J, 4), translations (F, K, 3)) of a clip."""
    rotations = np.asarray(rotations, dtype=np.float64)
    normals = reflection_normals(parents, offsets, end_sites, partner)
    reflect = np.eye(3) - 2.0 * normals[:, :, None] * normals[:, None, :]  # (J, 3, 3)
    world = np.diag([-1.0, 1.0, 1.0])
    r = quaternion.to_matrix(rotations)  # (F, J, 3, 3)
    out_rotations = np.empty_like(rotations)
    for c, p in enumerate(parents):
        above = world if p < 0 else reflect[p]
        out_rotations[:, partner[c]] = quaternion.from_matrix(above @ r[:, c] @ reflect[c])
    out_translations = np.array(translations, dtype=np.float64, copy=True) if len(translated) else translations
    slot = {j: k for k, j in enumerate(translated)}
    for k, c in enumerate(translated):
        p = parents[c]
        above = world if p < 0 else reflect[p]
        out_translations[:, slot[partner[c]]] = np.asarray(translations, dtype=np.float64)[:, k] @ above.T
    return out_rotations, out_translations
