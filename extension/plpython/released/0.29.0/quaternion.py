"""Quaternion and Euler-angle arithmetic on numpy arrays of shape (..., 4), (w, x, y, z)."""

import numpy as np

_AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}


def canonical(q):
    """Normalise to unit length and choose the sign with w >= 0 (q and -q are one rotation)."""
    q = np.asarray(q, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0.0, -q, q)


def conjugate(q):
    """The inverse of unit quaternions: the same axis, the opposite angle."""
    return np.asarray(q, dtype=np.float64) * np.array([1.0, -1.0, -1.0, -1.0])


def _components(q):
    """The last axis's components as arrays (np.moveaxis's views without its cost per call: the
    synthesis calls these functions tens of thousands of times a second on small arrays)."""
    q = np.asarray(q, dtype=np.float64)
    return [q[..., k] for k in range(q.shape[-1])]


def _cross(a, b):
    """a x b over the last axis: np.cross's products and differences, in its order."""
    a0, a1, a2 = _components(a)
    b0, b1, b2 = _components(b)
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def multiply(a, b):
    """Hamilton product a * b (apply b first, then a)."""
    aw, ax, ay, az = _components(a)
    bw, bx, by, bz = _components(b)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def rotate(q, v):
    """Rotate vectors v (..., 3) by unit quaternions q (..., 4)."""
    q = np.asarray(q, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * _cross(u, v)
    return v + w * t + _cross(u, t)


def about_axis(axis, angle):
    """Quaternions for rotations by `angle` (radians, any shape) about the principal axis 'X', 'Y'
    or 'Z'."""
    angle = np.asarray(angle, dtype=np.float64)
    q = np.zeros(angle.shape + (4,))
    q[..., 0] = np.cos(angle / 2.0)
    q[..., 1 + _AXIS_INDEX[axis]] = np.sin(angle / 2.0)
    return q


def from_euler(angles, order):
    """Quaternions from Euler angles (radians, shape (..., len(order))).

    `order` lists the axes as the channels do, e.g. 'ZXY' for BVH channels
    'Zrotation Xrotation Yrotation': R = Rz(a0) * Rx(a1) * Ry(a2), so the
    rightmost axis is applied to the vector first (intrinsic rotations).
    """
    angles = np.asarray(angles, dtype=np.float64)
    q = np.zeros(angles.shape[:-1] + (4,))
    q[..., 0] = 1.0
    for i, axis in enumerate(order):
        q = multiply(q, about_axis(axis, angles[..., i]))
    return canonical(q)


def to_matrix(q):
    """Rotation matrices (..., 3, 3) from unit quaternions."""
    w, x, y, z = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=-2,
    )


def is_supported_order(order):
    """Euler orders we can both read and write back: up to three distinct axes."""
    return 0 < len(order) <= 3 and set(order) <= set("XYZ") and len(set(order)) == len(order)


def to_euler(q, order):
    """Euler angles (radians, (..., len(order))) for `order`, the inverse of from_euler.

    Three axes: the middle angle is in [-pi/2, pi/2]. One or two axes: the
    rotation is assumed to have no component about the missing axes (true for
    data read through those channels) and each angle keeps its full range.
    """
    if not is_supported_order(order):
        raise ValueError(f"unsupported Euler order {order!r}: need 1-3 distinct axes of X, Y, Z")
    r = to_matrix(q)
    if len(order) == 1:
        i = _AXIS_INDEX[order]
        j, k = (i + 1) % 3, (i + 2) % 3
        return np.arctan2(r[..., k, j], r[..., j, j])[..., None]
    full = order + "".join(a for a in "XYZ" if a not in order)
    i, j, k = (_AXIS_INDEX[a] for a in full)
    # +1 when (i, j, k) is a cyclic permutation of (x, y, z).
    s = 1.0 if (j - i) % 3 == 1 else -1.0
    if len(order) == 2:
        # R = Ri(a) Rj(b): column j is Ri(a) e_j, row i is e_i^T Rj(b).
        a = np.arctan2(s * r[..., k, j], r[..., j, j])
        b = np.arctan2(s * r[..., i, k], r[..., i, i])
        return np.stack([a, b], axis=-1)
    cos_b = np.hypot(r[..., i, i], r[..., i, j])
    b = np.arctan2(s * r[..., i, k], cos_b)
    a = np.arctan2(-s * r[..., j, k], r[..., k, k])
    c = np.arctan2(-s * r[..., i, j], r[..., i, i])
    # Gimbal lock (middle angle +-90 degrees): only a + c or a - c is defined. Put it all in a with
    # c = 0, read from column j as for two axes: R e_j = Ri(a) e_j.
    locked = cos_b < 1e-9
    if np.any(locked):
        a = np.where(locked, np.arctan2(s * r[..., k, j], r[..., j, j]), a)
        c = np.where(locked, 0.0, c)
    return np.stack([a, b, c], axis=-1)


def angle_between(a, b):
    """Rotation angle (radians, 0..pi) taking a to b; q and -q count as the same rotation."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    b = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0.0, -b, b)
    # With t the angle between the 4-vectors, |a-b| = 2 sin(t/2) and |a+b| = 2 cos(t/2), and the
    # rotation angle is 2t: 4*atan2(|a-b|, |a+b|) stays accurate near 0 and pi, where 2*acos(a.b)
    # does not.
    return 4.0 * np.arctan2(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))


def from_matrix(m):
    """Unit quaternions (..., 4) from rotation matrices (..., 3, 3) (Shepperd's method, w >= 0)."""
    m = np.asarray(m, dtype=np.float64)
    t = m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]
    cands = np.stack(
        [
            np.stack(
                [
                    1 + t,
                    m[..., 2, 1] - m[..., 1, 2],
                    m[..., 0, 2] - m[..., 2, 0],
                    m[..., 1, 0] - m[..., 0, 1],
                ],
                -1,
            ),
            np.stack(
                [
                    m[..., 2, 1] - m[..., 1, 2],
                    1 + 2 * m[..., 0, 0] - t,
                    m[..., 0, 1] + m[..., 1, 0],
                    m[..., 0, 2] + m[..., 2, 0],
                ],
                -1,
            ),
            np.stack(
                [
                    m[..., 0, 2] - m[..., 2, 0],
                    m[..., 0, 1] + m[..., 1, 0],
                    1 + 2 * m[..., 1, 1] - t,
                    m[..., 1, 2] + m[..., 2, 1],
                ],
                -1,
            ),
            np.stack(
                [
                    m[..., 1, 0] - m[..., 0, 1],
                    m[..., 0, 2] + m[..., 2, 0],
                    m[..., 1, 2] + m[..., 2, 1],
                    1 + 2 * m[..., 2, 2] - t,
                ],
                -1,
            ),
        ],
        axis=-2,
    )
    # Each row is 4 q_k q (k = w, x, y, z); take the one with the largest |q_k| for accuracy.
    best = np.argmax(
        np.stack(
            [1 + t, 1 + 2 * m[..., 0, 0] - t, 1 + 2 * m[..., 1, 1] - t, 1 + 2 * m[..., 2, 2] - t],
            -1,
        ),
        -1,
    )
    q = np.take_along_axis(cands, best[..., None, None], axis=-2)[..., 0, :]
    return canonical(q)


def to_rotation_vector(q):
    """Axis times angle (radians) of unit quaternions (w, x, y, z), the shorter way round."""
    q = canonical(q)
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(s, q[..., :1])
    return np.where(s > 1e-12, v / np.maximum(s, 1e-300) * angle, 2.0 * v)


def from_rotation_vector(v):
    """Unit quaternions (w, x, y, z) of rotation vectors (axis times angle)."""
    angle = np.linalg.norm(v, axis=-1, keepdims=True)
    axis = np.where(angle > 1e-12, v / np.maximum(angle, 1e-300), 0.0)
    return np.concatenate([np.cos(angle / 2), axis * np.sin(angle / 2)], axis=-1)


def power(q, t):
    """q^t: the same axis, t times the angle (slerp from the identity)."""
    return from_rotation_vector(t * to_rotation_vector(q))
