"""Building a motion primitive's model from its processed data (modb.processed_data): functional
PCA of the aligned examples and of their time functions, and a Gaussian mixture on the joined
scores with its number of components chosen by BIC (scikit-learn's PCA and GaussianMixture). The
model's layout: modb_kernel.motion_model."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.stats import chi2
from sklearn.decomposition import PCA
from sklearn.mixture import GaussianMixture

from modb_kernel import kinematics, quaternion
from modb_kernel import terminators as T

from modb_kernel import motion_model as M

VARIANCE_KEPT = 0.95
BASIS_PER_FRAME = 0.3
TEMPORAL_BASIS = 6
TEMPORAL_COMPONENTS = 3
MAX_MIXTURE = 8
SAMPLED_MASS = 0.9  # samples come from the part of each component that holds this much of it


@dataclass
class Example:
    rotations: np.ndarray  # (n_frames, joints, 4), aligned to the reference's frames
    translations: np.ndarray  # (n_frames, translated, 3)
    time_function: np.ndarray  # (n_frames,) the example's frame at each canonical frame
    reference: bool


@dataclass
class Rig:
    parents: list[int]
    offsets: np.ndarray
    translated: list[int]
    left_hip: int
    right_hip: int
    pelvis: int


def facing_forward(e: Example, rig: Rig, fps: float) -> Example:
    """The example turned about the vertical so that its first frame faces +Z, and moved so that its
    pelvis starts above the origin. The pelvis carries the travel: its world position and rotation
    become its own (the joints above it, such as Bandai's static joint_Root, made the identity at
    the origin), so that the travel is one channel set whatever the rig puts above the pelvis."""
    positions, orientations = kinematics.world_transforms(
        rig.parents, rig.offsets, e.rotations, e.translations, rig.translated
    )
    heading = T.headings(positions[:1], rig.left_hip, rig.right_hip, fps)[0]
    turn = quaternion.about_axis("Y", np.array(-heading))
    ground = positions[0, rig.pelvis] * np.array([1.0, 0.0, 1.0])
    rotations, translations = e.rotations.copy(), e.translations.copy()
    above, j = [], rig.parents[rig.pelvis]
    while j >= 0:
        above.append(j)
        j = rig.parents[j]
    if rig.pelvis not in rig.translated or any(a not in rig.translated for a in above):
        # the travel cannot be moved onto the pelvis: only turned, about the root
        rotations[:, 0] = quaternion.canonical(quaternion.multiply(turn[None], rotations[:, 0]))
        return Example(rotations, translations, e.time_function, e.reference)
    for a in above:
        rotations[:, a] = [1.0, 0.0, 0.0, 0.0]
        translations[:, rig.translated.index(a)] = 0.0
    rotations[:, rig.pelvis] = quaternion.canonical(
        quaternion.multiply(turn[None], orientations[:, rig.pelvis])
    )
    translations[:, rig.translated.index(rig.pelvis)] = quaternion.rotate(
        turn[None], positions[:, rig.pelvis] - ground
    )
    return Example(rotations, translations, e.time_function, e.reference)


def continuous(rotations: np.ndarray) -> np.ndarray:
    """Each joint's track flipped frame by frame onto the hemisphere of the frame before it."""
    out = np.array(rotations, dtype=np.float64)
    for f in range(1, len(out)):
        out[f] = M.consistent_signs(out[f], out[f - 1])
    return out


def spatial_rows(examples: list[Example], weights: np.ndarray, n_basis: int) -> np.ndarray:
    (reference,) = [e for e in examples if e.reference]
    track = continuous(reference.rotations)
    rows = []
    for e in examples:
        rotations = np.stack(
            [M.consistent_signs(e.rotations[f], track[f]) for f in range(len(track))]
        )
        channels = M.spatial_channels(rotations, e.translations, weights)
        rows.append(M.coefficients(channels, n_basis).ravel())
    return np.asarray(rows)


def temporal_rows(examples: list[Example], n_basis: int) -> np.ndarray:
    return np.asarray(
        [M.coefficients(M.time_steps(e.time_function), n_basis).ravel() for e in examples]
    )


def _pca(rows: np.ndarray, keep: float | int) -> tuple[PCA, dict[str, Any]]:
    pca = PCA(n_components=keep, svd_solver="full").fit(rows)
    return pca, {
        "mean": pca.mean_.tolist(),
        "components": pca.components_.tolist(),
        "explained": pca.explained_variance_ratio_.tolist(),
    }


def choose_mixture(scores: np.ndarray, seed: int) -> tuple[GaussianMixture, list[dict[str, Any]]]:
    """The mixture of 1..MAX_MIXTURE components, with full or diagonal covariances, whose BIC is
    least; with the BIC of each one tried. Full covariances only where each component would have
    twice as many examples as dimensions (with fewer they collapse onto a few examples); diagonal
    ones suit PCA scores, uncorrelated overall, and let clusters (straight and turning steps) be
    components of their own."""
    n, d = scores.shape
    tried = []
    for kind in ("full", "diag"):
        most = n // (2 * (d + 1)) if kind == "full" else n // 4
        for k in range(1, max(1, min(MAX_MIXTURE, most)) + 1):
            fit = GaussianMixture(k, covariance_type=kind, reg_covar=1e-6, n_init=2,
                                  random_state=seed).fit(scores)  # fmt: skip
            tried.append((fit.bic(scores), kind, k, fit))
    best = min(tried, key=lambda t: t[0])
    return best[3], [{"covariance": kind, "components": k, "bic": bic} for bic, kind, k, _ in tried]


def _full_covariances(mixture: GaussianMixture) -> np.ndarray:
    c = mixture.covariances_
    return np.stack([np.diag(v) for v in c]) if mixture.covariance_type == "diag" else c


def build(examples: list[Example], rig: Rig, fps: float, keyframes: list[int], seed: int = 0,
          variance: float = VARIANCE_KEPT) -> dict[str, Any]:  # fmt: skip
    """The model document (modb_kernel.motion_model) of these examples, each first turned to face
    +Z with its pelvis above the origin."""
    examples = [facing_forward(e, rig, fps) for e in examples]
    translated = rig.translated
    n_frames = len(examples[0].time_function)
    n_joints = examples[0].rotations.shape[1]
    weights = M.lever_arms(rig.parents, rig.offsets)
    n_basis = max(M.DEGREE + 1, int(round(BASIS_PER_FRAME * n_frames)))
    spatial_pca, spatial = _pca(spatial_rows(examples, weights, n_basis), variance)
    temporal_pca, temporal = _pca(
        temporal_rows(examples, TEMPORAL_BASIS), min(TEMPORAL_COMPONENTS, len(examples) - 1)
    )
    scores = np.hstack([
        spatial_pca.transform(spatial_rows(examples, weights, n_basis)),
        temporal_pca.transform(temporal_rows(examples, TEMPORAL_BASIS)),
    ])  # fmt: skip
    mixture, bic = choose_mixture(scores, seed)
    return {
        "fps": fps,
        "n_frames": n_frames,
        "n_joints": n_joints,
        "translated": list(translated),
        "keyframes": list(keyframes),
        "limits": M.joint_limits(np.concatenate([e.rotations for e in examples])),
        "spatial": {
            **spatial,
            "n_basis": n_basis,
            "weights": weights.tolist(),
            "knots": M.knots(n_frames, n_basis).tolist(),
        },
        "temporal": {
            **temporal,
            "n_basis": TEMPORAL_BASIS,
            "knots": M.knots(n_frames - 1, TEMPORAL_BASIS).tolist(),
        },
        "mixture": {
            "weights": mixture.weights_.tolist(),
            "means": mixture.means_.tolist(),
            "covariances": _full_covariances(mixture).tolist(),
            "covariance_type": mixture.covariance_type,
            "max_mahalanobis2": float(chi2.ppf(SAMPLED_MASS, scores.shape[1])),
            "bic": bic,
        },
        "settings": {"variance_kept": variance, "seed": seed, "examples": len(examples)},
    }
