"""Why a motion model document (modb.models.data, kind motion_primitive; its layout in
motion_model.py) cannot be sampled or walked: the database runs this on every row written
(modb.model_document_problems), so no writer (SQL, REST, an import, a build) stores one that later
breaks a listing, a sample or a synthesis. Plain numpy (server and client)."""

import math

import numpy as np

from .edits import FPS_RANGE
from .motion_model import DEGREE

MAX_DOCUMENT_BYTES = 16 * 1024 * 1024  # of JSON: a CMU step model has about 4 MB
MAX_FRAMES = 100_000  # canonical frames of one primitive (a step has about 30)
MAX_JOINTS = 1_000
MAX_ABS = 1e6  # any number of a model: metres, quaternions and scores are far smaller
UNIT = 1e-3  # how far a principal component may be from unit length
WEIGHTS_SUM = 1e-6  # how far the mixture's weights may sum from 1
SYMMETRY = 1e-6  # how far a covariance may be from its transpose, relative to its largest entry


class _Problem(ValueError):
    pass


def _int(doc, key, low, high):
    value = doc.get(key)
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise _Problem(f'"{key}" must be a whole number from {low:,} to {high:,} (it is {value!r})')
    return value


def _array(value, where, shape):
    """value as a float array of the shape (None: any length there), every number finite and
    within MAX_ABS."""
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise _Problem(f"{where} must be {_shape_words(shape)} of numbers") from None
    if a.ndim != len(shape) or any(s is not None and n != s for n, s in zip(a.shape, shape)):
        raise _Problem(f"{where} must be {_shape_words(shape)} of numbers (it is {a.shape})")
    if not np.all(np.isfinite(a)) or (a.size and np.abs(a).max() > MAX_ABS):
        raise _Problem(f"{where} holds a number that is not finite or beyond ±{MAX_ABS:g}")
    return a


def _shape_words(shape):
    return " x ".join("n" if s is None else str(s) for s in shape) + " array"


def _part(doc, key, n_values):
    """A PCA part ("spatial" or "temporal"): mean of n_values, orthonormal-ish components rows,
    one explained share per component; returns its number of components."""
    part = doc.get(key)
    if not isinstance(part, dict):
        raise _Problem(f'"{key}" must be an object (mean, components, explained, n_basis)')
    _array(part.get("mean"), f"{key}.mean", (n_values,))
    components = _array(part.get("components"), f"{key}.components", (None, n_values))
    if not len(components):
        raise _Problem(f"{key}.components must hold at least one component")
    if np.abs(np.linalg.norm(components, axis=1) - 1).max() > UNIT:
        raise _Problem(f"{key}.components must be unit vectors (principal components)")
    explained = _array(part.get("explained"), f"{key}.explained", (len(components),))
    if explained.min() < 0 or explained.sum() > 1 + WEIGHTS_SUM:
        raise _Problem(f"{key}.explained must be shares of the variance (>= 0, at most 1 in all)")
    return len(components)


def _n_basis(doc, key, n_frames):
    part = doc.get(key) if isinstance(doc.get(key), dict) else {}
    value = part.get("n_basis")
    if isinstance(value, bool) or not isinstance(value, int) or not DEGREE + 1 <= value <= n_frames:
        raise _Problem(
            f'{key}.n_basis must be a whole number from {DEGREE + 1} to the frames ({n_frames})'
        )
    return value


def _mixture(doc, dims):
    mixture = doc.get("mixture")
    if not isinstance(mixture, dict):
        raise _Problem('"mixture" must be an object (weights, means, covariances)')
    weights = _array(mixture.get("weights"), "mixture.weights", (None,))
    k = len(weights)
    if not k or weights.min() < 0 or abs(weights.sum() - 1) > WEIGHTS_SUM:
        raise _Problem("mixture.weights must be one or more shares >= 0 summing to 1")
    _array(mixture.get("means"), "mixture.means", (k, dims))
    covariances = _array(mixture.get("covariances"), "mixture.covariances", (k, dims, dims))
    for c, cov in enumerate(covariances):
        if np.abs(cov - cov.T).max() > SYMMETRY * max(np.abs(cov).max(), 1e-300):
            raise _Problem(f"mixture.covariances[{c}] must be symmetric")
        try:
            np.linalg.cholesky(cov)
        except np.linalg.LinAlgError:
            raise _Problem(f"mixture.covariances[{c}] must be positive definite") from None
    limit = mixture.get("max_mahalanobis2")
    if limit is not None and (
        isinstance(limit, bool) or not isinstance(limit, (int, float)) or not 0 < limit < math.inf
    ):
        raise _Problem("mixture.max_mahalanobis2 must be a number > 0 (or absent)")


def _check(doc):
    if not isinstance(doc, dict):
        raise _Problem("a model must be a JSON object")
    fps = doc.get("fps")
    low, high = FPS_RANGE
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not low <= fps <= high:
        raise _Problem(f'"fps" must be a number from {low:g} to {high:g} (it is {fps!r})')
    n_frames = _int(doc, "n_frames", 2, MAX_FRAMES)
    n_joints = _int(doc, "n_joints", 1, MAX_JOINTS)
    translated = doc.get("translated")
    if not isinstance(translated, list) or any(
        isinstance(t, bool) or not isinstance(t, int) or not 0 <= t < n_joints for t in translated
    ):
        raise _Problem(f'"translated" must be a list of joint indices (0 to {n_joints - 1})')
    keyframes = doc.get("keyframes")
    if not isinstance(keyframes, list) or any(
        isinstance(k, bool) or not isinstance(k, int) or not 0 <= k < n_frames for k in keyframes
    ):
        raise _Problem(f'"keyframes" must be a list of frames (0 to {n_frames - 1})')
    joints = doc.get("joints")
    if joints is not None and (
        not isinstance(joints, list) or len(joints) != n_joints
        or not all(isinstance(j, str) for j in joints)
    ):  # fmt: skip
        raise _Problem(f'"joints" must name the {n_joints} joints')
    spatial_basis = _n_basis(doc, "spatial", n_frames)
    temporal_basis = _n_basis(doc, "temporal", n_frames - 1)
    weights = _array(doc["spatial"].get("weights"), "spatial.weights", (n_joints,))
    if weights.min() <= 0:
        raise _Problem("spatial.weights must be > 0 (each joint's lever arm)")
    channels = 3 * len(translated) + 4 * n_joints
    dims = _part(doc, "spatial", spatial_basis * channels) + _part(doc, "temporal", temporal_basis)
    _mixture(doc, dims)
    limits = doc.get("limits")
    if limits is not None:
        if not isinstance(limits, dict):
            raise _Problem('"limits" must be an object (mean, degrees)')
        _array(limits.get("mean"), "limits.mean", (n_joints, 4))
        degrees = _array(limits.get("degrees"), "limits.degrees", (n_joints,))
        if degrees.min() < 0 or degrees.max() > 180:
            raise _Problem("limits.degrees must be angles from 0 to 180")
    stance = doc.get("stance")
    if stance is not None:
        if not isinstance(stance, dict) or set(stance) - {"ankle", "toe"}:
            raise _Problem('"stance" must be an object of "ankle" and "toe" heights in metres')
        for point, height in stance.items():
            if isinstance(height, bool) or not isinstance(height, (int, float)):
                raise _Problem(f"stance.{point} must be a number (metres)")
            _array(height, f"stance.{point}", ())
    pace = doc.get("pace")
    if pace is not None:
        if not isinstance(pace, dict) or set(pace) != {"jump_p999_m"}:
            raise _Problem('"pace" must be an object of "jump_p999_m" (metres per frame)')
        jump = pace["jump_p999_m"]
        if isinstance(jump, bool) or not isinstance(jump, (int, float)) or not 0 < jump < 100:
            raise _Problem("pace.jump_p999_m must be a number of metres above 0")
    inputs = doc.get("inputs")
    if inputs is not None and not (
        isinstance(inputs, list) and all(isinstance(i, dict) for i in inputs)
    ):
        raise _Problem('"inputs" must be a list of objects (the processed data it was built from)')


def problems(doc):
    """Why the document is not a model that can be sampled: a list of at most one message (the
    first thing wrong, naming the field), empty when it can."""
    try:
        _check(doc)
    except _Problem as e:
        return [str(e)]
    return []
