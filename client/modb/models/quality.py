"""How good a motion model is (`modb model build --report-json`), measured on its own examples:

- reconstruction: examples left out one at a time (all of them, or HELD_OUT spread evenly over a
  large set), each projected and back-projected by the spatial PCA of the others; the mean joint
  position error (cm, forward kinematics of the canonical frames) against that of predicting the
  others' mean motion, overall and per joint whose mean-motion error is over 1 cm;
- likelihood: the mixture's mean log-likelihood of held-out scores (FOLDS folds) against that of a
  single Gaussian fitted to the same folds;
- samples (SAMPLES of them): foot sliding, the horizontal speed of a foot near the ground (within a
  tenth of a leg of the training examples' ground, as steps.py finds contacts) against the
  training examples' played at their own time; each joint's largest angle from its training mean
  rotation against the training examples' (joints that turn under a degree are not animated; the
  model's joint limits keep samples within them: how often they pulled one back is reported too);
  novelty, the median distance (root mean square over joints and canonical frames, cm) from a
  sample to its nearest training example against the training examples' own leave-one-out
  nearest-neighbour distance.
The targets are the issue's: reconstruction at most half the mean motion's, likelihood at least the
single Gaussian's, sliding at most 1.5x, no joint beyond its range by more than 10%, novelty within
0.5x to 2x."""

from __future__ import annotations

from typing import Any

import numpy as np
from modb_kernel import kinematics, motion_model, quaternion
from modb_kernel import steps as kernel_steps
from sklearn.decomposition import PCA
from sklearn.mixture import GaussianMixture
from sklearn.model_selection import KFold
from sklearn.neighbors import NearestNeighbors

from . import build as B
from .examples import Inputs, rig_of

HELD_OUT = 40
FOLDS = 5
SAMPLES = 100
MIN_MEAN_ERROR_CM = 1.0
ANIMATED_DEGREES = 1.0
TARGETS = {"reconstruction": 0.5, "sliding": 1.5, "rotation_excess": 0.1, "novelty": (0.5, 2.0)}


def _positions(inputs: Inputs, rotations: np.ndarray, translations: np.ndarray) -> np.ndarray:
    sk = inputs.skeleton
    return kinematics.world_positions(sk.parents, sk.offsets, rotations, translations,
                                      sk.translated)  # fmt: skip


def _coefficient_positions(inputs, model, flat) -> np.ndarray:
    return _positions(inputs, *motion_model.frames_from_coefficients(model, flat))


def reconstruction(inputs: Inputs, model: dict[str, Any], forward: list[B.Example]) -> dict:
    spatial = model["spatial"]
    rows = B.spatial_rows(forward, spatial["weights"], spatial["n_basis"])
    n = len(rows)
    held = np.unique(np.linspace(0, n - 1, min(n, HELD_OUT)).round().astype(int))
    model_err, mean_err = [], []
    for k in held:
        others = np.delete(rows, k, axis=0)
        pca = PCA(n_components=model["settings"]["variance_kept"], svd_solver="full").fit(others)
        rebuilt = pca.inverse_transform(pca.transform(rows[k : k + 1]))[0]
        truth = _positions(inputs, forward[k].rotations, forward[k].translations)
        model_err.append(np.linalg.norm(_coefficient_positions(inputs, model, rebuilt) - truth,
                                        axis=-1).mean(axis=0))  # fmt: skip
        mean_err.append(np.linalg.norm(
            _coefficient_positions(inputs, model, others.mean(axis=0)) - truth, axis=-1
        ).mean(axis=0))  # fmt: skip
    per_joint_model = 100 * np.mean(model_err, axis=0)
    per_joint_mean = 100 * np.mean(mean_err, axis=0)
    names = inputs.skeleton.names
    joints = [
        {"joint": names[j], "error_cm": float(per_joint_model[j]),
         "mean_motion_error_cm": float(per_joint_mean[j]),
         "ratio": float(per_joint_model[j] / per_joint_mean[j])}
        for j in range(len(names)) if per_joint_mean[j] > MIN_MEAN_ERROR_CM
    ]  # fmt: skip
    ratio = float(per_joint_model.mean() / per_joint_mean.mean())
    worst = max((j["ratio"] for j in joints), default=0.0)
    return {
        "held_out": int(len(held)),
        "error_cm": float(per_joint_model.mean()),
        "mean_motion_error_cm": float(per_joint_mean.mean()),
        "ratio": ratio,
        "worst_joint_ratio": worst,
        "joints": joints,
        "pass": ratio <= TARGETS["reconstruction"] and worst <= TARGETS["reconstruction"],
    }


def scores_of(model: dict[str, Any], forward: list[B.Example]) -> np.ndarray:
    """The joined (spatial, temporal) scores of the examples under the model's PCAs."""
    spatial, temporal = model["spatial"], model["temporal"]

    def project(part, rows):
        return (rows - np.asarray(part["mean"])) @ np.asarray(part["components"]).T

    return np.hstack([
        project(spatial, B.spatial_rows(forward, spatial["weights"], spatial["n_basis"])),
        project(temporal, B.temporal_rows(forward, temporal["n_basis"])),
    ])  # fmt: skip


def likelihood(model: dict[str, Any], scores: np.ndarray, seed: int) -> dict:
    k = len(model["mixture"]["weights"])
    kind = model["mixture"]["covariance_type"]
    folds = KFold(min(FOLDS, len(scores)), shuffle=True, random_state=seed)
    mixture, single = [], []
    for train, test in folds.split(scores):
        for out, count, covariance in ((mixture, k, kind), (single, 1, "full")):
            fit = GaussianMixture(count, covariance_type=covariance, reg_covar=1e-6, n_init=2,
                                  random_state=seed).fit(scores[train])  # fmt: skip
            out.extend(fit.score_samples(scores[test]))
    m, s = float(np.mean(mixture)), float(np.mean(single))
    return {"folds": folds.get_n_splits(), "components": k, "covariance": kind, "mixture": m,
            "single_gaussian": s, "pass": m >= s - 1e-9 * abs(s)}  # fmt: skip


def _foot_index(inputs: Inputs) -> dict[str, int]:
    return kernel_steps.joint_indices(inputs.skeleton.names, inputs.skeleton.joint_map)


def _low_and_speed(positions: np.ndarray, index: dict[str, int], side: str, fps: float):
    """Per frame: the foot's height (its lower of ankle and toe) and its horizontal speed (the
    slower of the two, m/s)."""
    feet = [index[f"{side}_ankle"], index[f"{side}_toe"]]
    low = positions[:, feet, 1].min(axis=1)
    flat = positions[:, feet] * np.array([1.0, 0.0, 1.0])
    speed = np.min([np.linalg.norm(np.gradient(flat[:, k], axis=0), axis=-1) * fps
                    for k in range(len(feet))], axis=0)  # fmt: skip
    return low, speed


def foot_sliding(inputs: Inputs, played: list[np.ndarray], samples: list[np.ndarray]) -> dict:
    index = _foot_index(inputs)
    sk = inputs.skeleton
    leg = kernel_steps.leg_length(sk.parents, sk.offsets, index)
    lows = np.concatenate([_low_and_speed(p, index, s, inputs.fps)[0] for p in played
                           for s in kernel_steps.SIDES])  # fmt: skip
    ground = float(np.percentile(lows, 5))

    def sliding(motions):
        speeds = []
        for p in motions:
            for side in kernel_steps.SIDES:
                low, speed = _low_and_speed(p, index, side, inputs.fps)
                speeds.append(speed[low < ground + kernel_steps.HEIGHT_LEGS * leg])
        return float(np.mean(np.concatenate(speeds)))

    training, sampled = sliding(played), sliding(samples)
    ratio = sampled / max(training, 1e-9)
    return {"samples_m_per_s": sampled, "training_m_per_s": training, "ratio": ratio,
            "pass": ratio <= TARGETS["sliding"]}  # fmt: skip


def rotation_range(inputs: Inputs, training: list[np.ndarray], samples: list[np.ndarray],
                   unlimited: list[np.ndarray]) -> dict:  # fmt: skip
    """Each joint's farthest turn from its mean rotation in the samples against the training's;
    and how often the model's joint limits pulled a sample's joint back (unlimited: the samples
    before that)."""
    limits = motion_model.joint_limits(np.concatenate(training))
    mean, reach = np.asarray(limits["mean"]), np.asarray(limits["degrees"])
    frames = np.concatenate(samples)
    sampled = np.degrees(quaternion.angle_between(frames, mean[None]).max(axis=0))
    beyond = np.degrees(quaternion.angle_between(np.concatenate(unlimited), mean[None])) > reach
    animated = np.flatnonzero(reach >= ANIMATED_DEGREES)
    excess = sampled[animated] / reach[animated] - 1.0
    worst = int(animated[np.argmax(excess)])
    return {"animated_joints": int(len(animated)), "worst_joint": inputs.skeleton.names[worst],
            "worst_excess": float(excess.max()),
            "training_degrees": float(reach[worst]), "samples_degrees": float(sampled[worst]),
            "limited_share": float(beyond.mean()),
            "pass": float(excess.max()) <= TARGETS["rotation_excess"]}  # fmt: skip


def novelty(training: list[np.ndarray], samples: list[np.ndarray]) -> dict:
    """Distances between canonical motions (same frame count): RMS joint distance, cm."""
    points = training[0].shape[0] * training[0].shape[1]

    def flat(motions):
        return np.stack([m.reshape(-1) for m in motions]) / np.sqrt(points) * 100

    train = flat(training)
    nn = NearestNeighbors(n_neighbors=2).fit(train)
    own = float(np.median(nn.kneighbors(train)[0][:, 1]))
    new = float(np.median(nn.kneighbors(flat(samples), n_neighbors=1)[0][:, 0]))
    ratio = new / max(own, 1e-9)
    low, high = TARGETS["novelty"]
    return {"samples_nn_cm": new, "training_nn_cm": own, "ratio": ratio,
            "pass": low <= ratio <= high}  # fmt: skip


def report(inputs: Inputs, model: dict[str, Any], seed: int = 0) -> dict[str, Any]:
    rig = rig_of(inputs.skeleton)
    forward = [B.facing_forward(e, rig, inputs.fps) for e in inputs.examples]
    split = len(model["spatial"]["components"])
    draws = motion_model.draw_scores(model["mixture"], SAMPLES, seed)
    canonical = [_positions(inputs, e.rotations, e.translations) for e in forward]
    sample_canonical = [
        _positions(inputs, *motion_model.canonical_frames(model, d[:split])) for d in draws
    ]
    played = [_positions(inputs, *motion_model.play(e.rotations, e.translations, e.time_function))
              for e in forward]  # fmt: skip
    sampled = [_positions(inputs, *motion_model.frames_from_scores(model, d[:split], d[split:])[:2])
               for d in draws]  # fmt: skip
    sample_rotations = [
        quaternion.canonical(motion_model.canonical_frames(model, d[:split])[0]) for d in draws
    ]
    unlimited = [
        motion_model.frames_from_coefficients(
            model, np.asarray(model["spatial"]["mean"]) + d[:split] @ np.asarray(
                model["spatial"]["components"])
        )[0]
        for d in draws
    ]  # fmt: skip
    parts = {
        "reconstruction": reconstruction(inputs, model, forward),
        "likelihood": likelihood(model, scores_of(model, forward), seed),
        "foot_sliding": foot_sliding(inputs, played, sampled),
        "rotation_range": rotation_range(
            inputs,
            [quaternion.canonical(e.rotations) for e in forward],
            sample_rotations,
            unlimited,
        ),
        "novelty": novelty(canonical, sample_canonical),
    }
    return {
        "primitive": inputs.primitive,
        "examples": len(inputs.examples),
        "mirrored_examples": sum(bool(r["mirrored"]) for r in inputs.rows),
        "spatial_components": split,
        "temporal_components": len(model["temporal"]["components"]),
        "mixture_components": len(model["mixture"]["weights"]),
        "mixture_covariance": model["mixture"]["covariance_type"],
        "mixture_bic": model["mixture"]["bic"],
        "samples": {"n": SAMPLES, "seed": seed},
        **parts,
        "pass": all(p["pass"] for p in parts.values()),
    }
