"""A statistical model of a motion primitive (after the DFKI pipeline): functional PCA of its
aligned examples and a Gaussian mixture on their scores. This module turns a model back into motion
with numpy and scipy only (what the server's Python has: modb.sample_motion); the client builds
models (modb.models.build, with scikit-learn).

A model is a JSON document (modb.models.data, kind motion_primitive):
- "primitive", "fps", "joints" (the skeleton's joint names), "translated" (its translated joints),
  "n_joints", "n_frames" (the canonical frame count, the reference example's), "keyframes" (the
  reference's section bounds).
- "spatial": a cubic B-spline fit ("knots") of every channel of the canonical frames (each
  translated joint's translation in metres, then every joint's quaternion, signs made consistent,
  times the joint's "weights": its lever arm, the farthest its descendants are at rest, so that a
  channel's variance is about that of the positions it moves), its "n_basis" coefficients per
  channel flattened, reduced by PCA: "mean",
  "components" (rows, the eigenvectors), "explained" (the share of the variance each keeps).
- "temporal": the time function (the example's frame at each canonical frame, made strictly
  increasing) as the log of its steps, fitted by a B-spline of "n_basis" coefficients ("knots"),
  reduced by PCA the same way.
- "mixture": a Gaussian mixture ("weights", "means", "covariances") on the joined scores, spatial
  first, with the BIC of each number of components tried.
- "inputs" (the processed-data rows and the clip versions they came from), "settings".
Each example is first turned to face +Z with its pelvis starting above the origin, so samples do.
"""

import numpy as np

from . import quaternion

DEGREE = 3
MIN_STEP = 1e-3  # the least mean step of a time function, in example frames
MIN_STEP_SHARE = 0.25  # the least step, a share of the mean step


def basis(n_frames, n_basis):
    """(n_frames, n_basis) cubic B-spline basis on frames 0..n_frames-1, knots clamped, uniform."""
    from scipy.interpolate import BSpline  # here: a session that never samples does not import it

    frames = np.arange(n_frames, dtype=np.float64)
    return BSpline.design_matrix(frames, knots(n_frames, n_basis), DEGREE).toarray()


def knots(n_frames, n_basis):
    """The knot vector of basis(): clamped at frames 0 and n_frames - 1, uniform between."""
    n_basis = max(DEGREE + 1, int(n_basis))
    inner = np.linspace(0.0, n_frames - 1.0, n_basis - DEGREE + 1)
    return np.concatenate([[inner[0]] * DEGREE, inner, [inner[-1]] * DEGREE])


MIN_LEVER_M = 0.05  # the weight of a joint with nothing (or little) below it


def lever_arms(parents, offsets):
    """Per joint, the farthest any of its descendants is from it at rest (metres, at least
    MIN_LEVER_M): how far a turn of the joint moves the body."""
    from . import kinematics

    rest = kinematics.rest_positions(parents, offsets)
    reach = np.full(len(parents), MIN_LEVER_M)
    for j in range(len(parents)):
        a = parents[j]
        while a >= 0:
            reach[a] = max(reach[a], float(np.linalg.norm(rest[j] - rest[a])))
            a = parents[a]
    return reach


def spatial_channels(rotations, translations, weights):
    """(frames, channels): translations, then quaternions times their joint's weight."""
    rotations = np.asarray(rotations, dtype=np.float64)
    translations = np.asarray(translations, dtype=np.float64)
    n = rotations.shape[0]
    weighted = rotations * np.asarray(weights, dtype=np.float64)[None, :, None]
    return np.concatenate([translations.reshape(n, -1), weighted.reshape(n, -1)], axis=1)


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


def canonical_frames(model, spatial_scores):
    """(rotations, translations) of the canonical frames the spatial scores give, each joint kept
    within the model's "limits"."""
    rotations, translations = frames_from_coefficients(
        model, _back(model["spatial"], spatial_scores)
    )
    if "limits" in model:
        rotations = within_limits(rotations, model["limits"])
    return rotations, translations


def joint_limits(rotations):
    """Each joint's mean rotation (the principal eigenvector of its quaternions' scatter) and the
    largest angle (degrees) any of the (frames, joints, 4) rotations turns from it: the joint
    limits the examples show."""
    rotations = np.asarray(rotations, dtype=np.float64)
    mean = np.stack([np.linalg.eigh(q.T @ q)[1][:, -1] for q in np.moveaxis(rotations, 1, 0)])
    mean = quaternion.canonical(mean)
    degrees = np.degrees(quaternion.angle_between(rotations, mean[None]).max(axis=0))
    return {"mean": mean.tolist(), "degrees": degrees.tolist()}


def within_limits(rotations, limits):
    """The rotations, each turned back towards its joint's mean rotation where it is farther from
    it than the limit (the same axis, the limit's angle)."""
    mean = np.asarray(limits["mean"], dtype=np.float64)[None]
    most = np.radians(np.asarray(limits["degrees"], dtype=np.float64))[None]
    angle = quaternion.angle_between(rotations, mean)
    share = np.minimum(1.0, most / np.maximum(angle, 1e-12))[..., None]
    relative = quaternion.multiply(quaternion.conjugate(mean), rotations)
    return quaternion.canonical(quaternion.multiply(mean, quaternion.power(relative, share)))


def frames_from_coefficients(model, flat):
    """(rotations, translations) of the canonical frames of flattened B-spline coefficients."""
    n = model["n_frames"]
    spatial = model["spatial"]
    k = spatial["n_basis"]
    channels = basis(n, k) @ np.asarray(flat, dtype=np.float64).reshape(k, -1)
    n_t = len(model["translated"])
    translations = channels[:, : 3 * n_t].reshape(n, n_t, 3)
    rotations = channels[:, 3 * n_t :].reshape(n, model["n_joints"], 4)
    rotations /= np.asarray(spatial["weights"], dtype=np.float64)[None, :, None]
    rotations /= np.maximum(np.linalg.norm(rotations, axis=-1, keepdims=True), 1e-12)
    return quaternion.canonical(rotations), translations


def time_function(model, temporal_scores):
    """The motion's frame (from 0) at each canonical frame, from the temporal scores."""
    temporal = model["temporal"]
    log_steps = basis(model["n_frames"] - 1, temporal["n_basis"]) @ _back(temporal, temporal_scores)
    return np.concatenate([[0.0], np.cumsum(np.exp(log_steps))])


def play(rotations, translations, times):
    """Canonical frames played at their own pace: one frame per whole step of times (the motion's
    frame at each canonical frame), each blended from the two canonical frames around it."""
    n = len(rotations)
    out_frames = np.arange(int(np.floor(times[-1] + 1e-9)) + 1, dtype=np.float64)
    at = np.interp(out_frames, times, np.arange(n, dtype=np.float64))
    lo = np.minimum(np.floor(at).astype(int), n - 2) if n > 1 else np.zeros(len(at), dtype=int)
    hi = np.minimum(lo + 1, n - 1)
    w = (at - lo)[:, None, None]
    ahead = consistent_signs(rotations[hi], rotations[lo])
    blended = rotations[lo] * (1 - w) + ahead * w
    blended /= np.maximum(np.linalg.norm(blended, axis=-1, keepdims=True), 1e-12)
    return quaternion.canonical(blended), translations[lo] * (1 - w) + translations[hi] * w


def frames_from_scores(model, spatial_scores, temporal_scores):
    """(rotations, translations, time function) of one motion: canonical frames rebuilt from the
    spatial scores, then played at the times the temporal scores give."""
    times = time_function(model, temporal_scores)
    return (*play(*canonical_frames(model, spatial_scores), times), times)


def _within(rng, n, d, limit):
    """n standard normal draws in d dimensions, each redrawn until its squared length is at most
    limit (None: as drawn)."""
    z = rng.standard_normal((n, d))
    while limit is not None:
        far = np.flatnonzero(np.einsum("ij,ij->i", z, z) > limit)
        if not len(far):
            break
        z[far] = rng.standard_normal((len(far), d))
    return z


def draw_scores(mixture, n, seed):
    """n draws from the mixture (rows of joined scores), reproducible from the seed; each within
    the squared Mahalanobis distance "max_mahalanobis2" of its component's mean where the model
    sets one (a Gaussian's tails reach poses no example has)."""
    rng = np.random.default_rng(seed)
    weights = np.asarray(mixture["weights"], dtype=np.float64)
    means = np.asarray(mixture["means"], dtype=np.float64)
    covariances = np.asarray(mixture["covariances"], dtype=np.float64)
    chosen = rng.choice(len(weights), size=n, p=weights / weights.sum())
    out = np.empty((n, means.shape[1]))
    for k in range(len(weights)):
        rows = np.flatnonzero(chosen == k)
        if len(rows):
            z = _within(rng, len(rows), means.shape[1], mixture.get("max_mahalanobis2"))
            out[rows] = means[k] + z @ np.linalg.cholesky(covariances[k]).T
    return out


def sample(model, n, seed, interrupts=lambda: None):
    """n motions [(rotations, translations, time function)] drawn from the model; interrupts() is
    called before each (the server's lets a cancel in)."""
    split = len(model["spatial"]["components"])
    out = []
    for scores in draw_scores(model["mixture"], n, seed):
        interrupts()
        out.append(frames_from_scores(model, scores[:split], scores[split:]))
    return out
