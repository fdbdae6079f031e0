"""Mirroring a clip through the skeleton's left/right pairing: the same motion as if captured in a
mirror.

World positions are reflected by S = diag(-1, 1, 1) (x -> -x) with every paired joint swapped. The
mirrored joint m(c) takes the world orientation S O_c M_c, where M_c (orthogonal, det -1) says how
m(c)'s frame sits against c's in the rig. Parent-relative, a joint c with parent j takes M_j R_c M_c
(S R_root M_root at the root), and a translated joint's translation becomes M_j t (S t at the root).
Positions are exact whatever M is, as far as the captured skeleton is symmetric; rotations are what
the same rig would report for the mirrored motion only with the rig's own M, and only then can
mirrored snippets follow captured ones.

Finding M_c. Every candidate must map c's child offsets (and end site, and translations that never
change) onto its partner's: M_c off_k = off_m(k). Rigs use axis-aligned conventions, so candidates
are the 24 signed permutations of determinant -1, allowed 15 degrees of capture asymmetry. Where
that leaves a choice (a bone's twist is invisible in its offsets):
- an unpaired joint (pelvis, spine, neck) flips the axis of its frame nearest the body's left-right
  axis as seen in that frame (the principal axis of the hips' and clavicles' separations over the
  clip, which no yaw or gesture changes) if it lies within 30 degrees of one; else, as in a joint
  that does not turn with the body (a root above the pelvis), or a head held turned for a whole
  clip, it keeps its parent's;
- a paired joint keeps its parent's M where that fits (a rig whose frames follow its symmetry: CMU's
  ASF, S everywhere), else -I where that fits (a Maya-style rig mirrors the right side's axes as a
  whole);
- anything else takes the candidate whose mirrored rotations come nearest, on average, to the
  partner's.
A rig that is not axis-aligned gets the best fit of its offsets instead.
"""

import itertools

import numpy as np

from . import kinematics, quaternion

WORLD_REFLECTION = np.diag([-1.0, 1.0, 1.0])
# A captured skeleton's two sides differ by a few degrees (CMU 131's neck leans 7 degrees): within
# this the axis-aligned convention is taken as the rig's, and the difference as capture asymmetry.
ALIGNED_COS = np.cos(np.radians(15.0))
LATERAL_STEADINESS = 0.8  # share of the separations' spread along the axis it takes to be one
# relative spread under which a translation channel counts as a fixed offset
STEADY_TRANSLATION = 1e-3


def _axis_aligned_reflections():
    """The 24 signed permutation matrices with determinant -1: every axis-aligned mirror
    convention."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            m = np.zeros((3, 3))
            m[list(perm), range(3)] = signs
            if np.linalg.det(m) < 0:
                out.append(m)
    return out


CANDIDATES = _axis_aligned_reflections()


def partner_index(names, pairs):
    index = {n: k for k, n in enumerate(names)}
    partner = list(range(len(names)))
    for left, right in pairs:
        partner[index[left]], partner[index[right]] = index[right], index[left]
    return partner


def _unit(v):
    v = np.asarray(v, dtype=np.float64)
    norm = np.linalg.norm(v)
    return v / norm if norm > 1e-9 else None


def _flips_one_axis(m):
    return np.allclose(m, np.diag(np.diag(m))) and np.isclose(np.trace(m), 1.0)


def _turning(a, b):
    """The smallest rotation taking unit a onto unit b (a half turn about a perpendicular when
    opposite)."""
    axis = np.cross(a, b)
    s, c = np.linalg.norm(axis), float(np.dot(a, b))
    if s < 1e-12:
        if c > 0:
            return np.eye(3)
        axis, s, c = np.cross(a, np.eye(3)[np.argmin(np.abs(a))]), 0.0, -1.0
    axis = axis / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)


def _improper_fit(sources, targets):
    """The orthogonal matrix of determinant -1 that best maps unit sources onto unit targets
    (Kabsch)."""
    u, _, vt = np.linalg.svd(np.asarray(targets).T @ np.asarray(sources))
    return u @ np.diag([1.0, 1.0, -np.linalg.det(u @ vt)]) @ vt


def _chains(parents, partner):
    """The pairs _lateral_axes may take, per starting pair: the pairs hung from one unpaired parent
    (hips, clavicles), each followed down its first children (CMU's hip joints sit on the pelvis,
    their children are apart)."""
    n = len(parents)
    children = [[k for k in range(n) if parents[k] == j] for j in range(n)]
    chains = []
    for c, m in enumerate(partner):
        if c < m and parents[c] == parents[m] >= 0 and partner[parents[c]] == parents[c]:
            chain = [(c, m)]
            while children[c]:
                c = children[c][0]
                chain.append((c, partner[c]))
            chains.append(chain)
    return chains


class ClipStatistics:
    """What finding M needs from a clip's frames, summed chunk by chunk so that a clip of any length
    is mirrored in bounded memory: mean parent-relative rotation matrices, the translations' mean
    and range, the pairs' mean separations and the scatter of their directions in every joint's
    frame, and whether each joint turns."""

    def __init__(self, parents, offsets, partner, translated):
        n = len(parents)
        self.parents, self.offsets, self.partner = parents, offsets, partner
        self.translated = list(translated)
        self.chains = _chains(parents, partner)
        self.pairs = sorted({p for chain in self.chains for p in chain})
        self.frames = 0
        self.rotation_sum = np.zeros((n, 3, 3))
        k = len(self.translated)
        self.translation_sum = np.zeros((k, 3))
        self.translation_min = np.full((k, 3), np.inf)
        self.translation_max = np.full((k, 3), -np.inf)
        self.distance_sum = np.zeros(len(self.pairs))
        self.scatter = np.zeros((len(self.pairs), n, 3, 3))
        self.first_orientation = None
        self.turn = np.zeros(n)

    def add(self, rotations, translations):
        """Adds frames (rotations (F, J, 4), translations (F, K, 3) or None) in clip order."""
        rotations = np.asarray(rotations, dtype=np.float64)
        positions, orientations = kinematics.world_transforms(
            self.parents, self.offsets, rotations, translations, self.translated
        )
        self.frames += len(rotations)
        self.rotation_sum += quaternion.to_matrix(rotations).sum(axis=0)
        if self.translated:
            t = np.asarray(translations, dtype=np.float64)
            self.translation_sum += t.sum(axis=0)
            self.translation_min = np.minimum(self.translation_min, t.min(axis=0))
            self.translation_max = np.maximum(self.translation_max, t.max(axis=0))
        if self.pairs:
            c, m = (list(x) for x in zip(*self.pairs))
            separation = positions[:, c] - positions[:, m]  # (F, P, 3)
            self.distance_sum += np.linalg.norm(separation, axis=-1).sum(axis=0)
            separation /= np.maximum(np.linalg.norm(separation, axis=-1, keepdims=True), 1e-12)
            local = quaternion.rotate(
                quaternion.conjugate(orientations)[:, :, None, :], separation[:, None, :, :]
            )  # (F, J, P, 3)
            self.scatter += np.einsum("fjpa,fjpb->pjab", local, local)
        if self.first_orientation is None:
            self.first_orientation = orientations[0]
        self.turn = np.maximum(
            self.turn, np.abs(orientations - self.first_orientation).max(axis=(0, 2))
        )

    def fixed_offsets(self):
        """Offsets, with those of translated joints whose translation never changes taken from
        it."""
        offsets = np.array(self.offsets, dtype=np.float64)
        for k, j in enumerate(self.translated):
            mean = self.translation_sum[k] / self.frames
            spread = max(
                (self.translation_max[k] - mean).max(), (mean - self.translation_min[k]).max()
            )
            offsets[j] = mean if spread <= STEADY_TRANSLATION * np.linalg.norm(mean) else 0.0
        return offsets

    def lateral_axes(self):
        """Per joint, the body's left-right axis in the joint's own frame: the principal axis of the
        separations of the pairs hung from one unpaired parent (hips, clavicles; or the first pair
        below them that is apart), over all frames; zero where no axis holds (a root above the
        pelvis that does not turn with the body)."""
        n = len(self.parents)
        slot = {p: k for k, p in enumerate(self.pairs)}
        chosen = []
        for chain in self.chains:
            k = 0
            while k + 1 < len(chain) and self.distance_sum[slot[chain[k]]] / self.frames < 1e-3:
                k += 1
            chosen.append(slot[chain[k]])
        if not chosen:
            return np.zeros((n, 3))
        values, vectors = np.linalg.eigh(self.scatter[chosen].sum(axis=0))  # (J, 3, 3)
        steady = values[:, -1] >= LATERAL_STEADINESS * values.sum(axis=1)
        turning = self.turn > 1e-9  # a fixed frame is the world's
        return vectors[:, :, -1] * (steady & turning)[:, None]

    def reflections(self, end_sites):
        """M_j of every joint (see the module docstring)."""
        return frame_reflections(
            self.parents,
            self.fixed_offsets(),
            end_sites,
            self.partner,
            self.lateral_axes(),
            self.rotation_sum / self.frames,
        )


def _direction_pairs(j, children, offsets, end_sites, partner):
    """(direction, partner's direction) of j's child offsets and end site, where both are
    non-zero."""
    pairs = [(offsets[c], offsets[partner[c]]) for c in children[j]]
    if end_sites[j] is not None and end_sites[partner[j]] is not None:
        pairs.append((end_sites[j], end_sites[partner[j]]))
    units = [(_unit(a), _unit(b)) for a, b in pairs]
    return [(a, b) for a, b in units if a is not None and b is not None]


def _nearest_flip(candidates, axis):
    """The single-axis flip whose axis lies within 30 degrees of `axis`, if any (a head held turned
    for a whole clip is no evidence of its frame)."""
    best = max(candidates, key=lambda m: np.linalg.norm((np.eye(3) - m) @ axis))  # 2 |n . axis|
    return (
        best if np.linalg.norm((np.eye(3) - best) @ axis) >= 2 * np.cos(np.radians(30.0)) else None
    )


def frame_reflections(parents, offsets, end_sites, partner, lateral_axes, mean_rotations):
    """Per joint, M_j (3 x 3, det -1) as the module docstring finds it. lateral_axes: (J, 3);
    mean_rotations: (J, 3, 3) averages of the clip's parent-relative rotation matrices."""
    n_joints = len(parents)
    children = [[c for c in range(n_joints) if parents[c] == j] for j in range(n_joints)]
    out = np.empty((n_joints, 3, 3))
    for j in range(n_joints):  # parents come before children
        if partner[j] < j:  # the right side of a pair: its frame relates back to the left one's
            out[j] = out[partner[j]].T
            continue
        above = WORLD_REFLECTION if parents[j] < 0 else out[parents[j]]
        pairs = _direction_pairs(j, children, offsets, end_sites, partner)
        candidates = [
            m for m in CANDIDATES if all(np.dot(m @ a, b) > ALIGNED_COS for a, b in pairs)
        ]
        if partner[j] == j:
            candidates = [m for m in candidates if _flips_one_axis(m)]
        if not candidates:  # not axis-aligned: fit the offsets
            sources = np.array([a for a, _ in pairs])
            if np.linalg.matrix_rank(sources, tol=1e-3) >= 2:
                out[j] = _improper_fit(sources, [b for _, b in pairs])
                continue
            candidates = [_turning(m @ pairs[0][0], pairs[0][1]) @ m for m in CANDIDATES]
        if len(candidates) == 1:
            out[j] = candidates[0]
        elif partner[j] == j and (flip := _nearest_flip(candidates, lateral_axes[j])) is not None:
            out[j] = flip
        elif any(np.allclose(m, above) for m in candidates):
            out[j] = above
        elif partner[j] != j and any(np.allclose(m, -np.eye(3)) for m in candidates):
            out[j] = -np.eye(3)
        else:
            target = mean_rotations[partner[j]]
            out[j] = min(
                candidates, key=lambda m: np.linalg.norm(above @ mean_rotations[j] @ m - target)
            )
    return out


def clip_reflections(parents, offsets, end_sites, partner, rotations, translations, translated):
    """M_j of every joint, found from a whole clip of the skeleton (see the module docstring)."""
    statistics = ClipStatistics(parents, offsets, partner, translated)
    statistics.add(rotations, translations)
    return statistics.reflections(end_sites)


def reflect(frames, parents, partner, rotations, translations, translated):
    """Mirrored (rotations (F, J, 4), translations (F, K, 3)) of frames, given the clip's M
    (clip_reflections, or ClipStatistics for a clip read in chunks): frame by frame."""
    rotations = np.asarray(rotations, dtype=np.float64)
    r = quaternion.to_matrix(rotations)  # (F, J, 3, 3)
    out_rotations = np.empty_like(rotations)
    for c, p in enumerate(parents):
        above = WORLD_REFLECTION if p < 0 else frames[p]
        out_rotations[:, partner[c]] = quaternion.from_matrix(above @ r[:, c] @ frames[c])
    if not len(translated):
        return out_rotations, translations
    translations = np.asarray(translations, dtype=np.float64)
    out_translations = np.empty_like(translations)
    slot = {j: k for k, j in enumerate(translated)}
    for k, c in enumerate(translated):
        above = WORLD_REFLECTION if parents[c] < 0 else frames[parents[c]]
        out_translations[:, slot[partner[c]]] = translations[:, k] @ above.T
    return out_rotations, out_translations


def mirror(parents, offsets, end_sites, partner, rotations, translations, translated):
    """Mirrored (rotations (F, J, 4), translations (F, K, 3)) of a whole clip."""
    frames = clip_reflections(
        parents, offsets, end_sites, partner, rotations, translations, translated
    )
    return reflect(frames, parents, partner, rotations, translations, translated)
