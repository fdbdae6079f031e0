"""A statistical model of a motion primitive (after the DFKI pipeline): functional PCA of its
aligned examples and a Gaussian mixture on their scores. This module holds what turns a model back
into motion, with numpy and scipy only, so that it can move into the kernel (modb_kernel) for the
server's modb.sample_motion at the release that adds it; build.py builds models (scikit-learn).

A model is a JSON document:
- "n_frames": the canonical frame count (the reference example's); "translated", "n_joints": the
  skeleton's translated joints and its joint count; "keyframes": the reference's section bounds.
- "spatial": a cubic B-spline fit of every channel of the canonical frames (each translated joint's
  translation divided by "scale", then every joint's quaternion, signs made consistent), its
  "n_basis" coefficients per channel flattened, reduced by PCA: "mean", "components" (rows),
  "explained" (the variance each keeps).
- "temporal": the time function (the example's frame at each canonical frame, made strictly
  increasing) as the log of its steps, fitted by a B-spline of "n_basis" coefficients, reduced by
  PCA the same way.
- "mixture": a Gaussian mixture ("weights", "means", "covariances") on the joined scores, spatial
  first.
"""

import numpy as np
from modb_kernel import quaternion

DEGREE = 3
MIN_STEP = 1e-3  # the least mean step of a time function, in example frames
MIN_STEP_SHARE = 0.25  # the least step, a share of the mean step


def basis(n_frames, n_basis):
    """(n_frames, n_basis) cubic B-spline basis on frames 0..n_frames-1, knots clamped, uniform."""
    from scipy.interpolate import BSpline  # here: a session that never samples does not import it

    n_basis = max(DEGREE + 1, int(n_basis))
    inner = np.linspace(0.0, n_frames - 1.0, n_basis - DEGREE + 1)
    knots = np.concatenate([[inner[0]] * DEGREE, inner, [inner[-1]] * DEGREE])
    frames = np.arange(n_frames, dtype=np.float64)
    return BSpline.design_matrix(frames, knots, DEGREE).toarray()


def spatial_channels(rotations, translations, scale):
    """(frames, channels): translations / scale, then quaternions, one row per frame."""
    rotations = np.asarray(rotations, dtype=np.float64)
    translations = np.asarray(translations, dtype=np.float64)
    n = rotations.shape[0]
    return np.concatenate([translations.reshape(n, -1) / scale, rotations.reshape(n, -1)], axis=1)


def consistent_signs(rotations, reference):
    """Each joint's quaternions flipped where needed so they lie on the reference's hemisphere
    (frame by frame: q and -q are one rotation, the fit needs one of them)."""
    rotations = np.array(rotations, dtype=np.float64)
    flip = np.sum(rotations * np.asarray(reference), axis=-1) < 0
    rotations[flip] *= -1
    return rotations


def time_steps(time_function):
    """log of the time function's steps (length n_frames - 1), made strictly increasing first: each
    step at least MIN_STEP_SHARE of the mean step (a warp's pauses would otherwise rule the log),
    the total kept."""
    steps = np.diff(np.asarray(time_function, dtype=np.float64))
    total = max(steps.sum(), MIN_STEP * len(steps))
    floor = MIN_STEP_SHARE * total / len(steps)
    steps = np.maximum(steps, floor)
    return np.log(steps * total / steps.sum())


def coefficients(values, n_basis):
    """Least-squares B-spline coefficients (n_basis, channels) of (frames, channels) values."""
    values = np.asarray(values, dtype=np.float64)
    if values.ndim == 1:
        values = values[:, None]
    b = basis(values.shape[0], n_basis)
    return np.linalg.lstsq(b, values, rcond=None)[0]


def _back(part, scores):
    return np.asarray(part["mean"]) + np.asarray(scores) @ np.asarray(part["components"])


def frames_from_scores(model, spatial_scores, temporal_scores):
    """(rotations, translations, time function) of one motion: canonical frames rebuilt from the
    spatial scores, then played at the times the temporal scores give."""
    n = model["n_frames"]
    spatial = model["spatial"]
    k = spatial["n_basis"]
    coef = _back(spatial, spatial_scores).reshape(k, -1)
    channels = basis(n, k) @ coef
    n_t = len(model["translated"])
    translations = channels[:, : 3 * n_t].reshape(n, n_t, 3) * spatial["scale"]
    rotations = channels[:, 3 * n_t :].reshape(n, model["n_joints"], 4)
    temporal = model["temporal"]
    log_steps = basis(n - 1, temporal["n_basis"]) @ _back(temporal, temporal_scores)
    times = np.concatenate([[0.0], np.cumsum(np.exp(log_steps))])
    # played at its own pace: one frame per whole step of the time function
    out_frames = np.arange(int(np.floor(times[-1] + 1e-9)) + 1, dtype=np.float64)
    at = np.interp(out_frames, times, np.arange(n, dtype=np.float64))
    lo = np.minimum(np.floor(at).astype(int), n - 2) if n > 1 else np.zeros(len(at), dtype=int)
    hi = np.minimum(lo + 1, n - 1)
    w = (at - lo)[:, None, None]
    rotations = rotations[lo] * (1 - w) + rotations[hi] * w
    translations = translations[lo] * (1 - w) + translations[hi] * w
    rotations /= np.maximum(np.linalg.norm(rotations, axis=-1, keepdims=True), 1e-12)
    return quaternion.canonical(rotations), translations, times


def draw_scores(mixture, n, seed):
    """n draws from the mixture (rows of joined scores), reproducible from the seed."""
    rng = np.random.default_rng(seed)
    weights = np.asarray(mixture["weights"], dtype=np.float64)
    means = np.asarray(mixture["means"], dtype=np.float64)
    covariances = np.asarray(mixture["covariances"], dtype=np.float64)
    chosen = rng.choice(len(weights), size=n, p=weights / weights.sum())
    out = np.empty((n, means.shape[1]))
    for k in range(len(weights)):
        rows = np.flatnonzero(chosen == k)
        if len(rows):
            out[rows] = rng.multivariate_normal(
                means[k], covariances[k], size=len(rows), method="cholesky"
            )
    return out


def sample(model, n, seed):
    """n motions [(rotations, translations, time function)] drawn from the model."""
    split = len(model["spatial"]["components"])
    return [
        frames_from_scores(model, scores[:split], scores[split:])
        for scores in draw_scores(model["mixture"], n, seed)
    ]
