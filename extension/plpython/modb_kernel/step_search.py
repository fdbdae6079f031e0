"""The scores of a motion model that best meet a step's constraints (after the DFKI pipeline): a
beam search down the model's k-means tree, then a numerical refinement of the constraint error plus
the mixture's Mahalanobis distance (least squares, scipy). Plain numpy and scipy: it runs in the
server (modb.synthesize_from_models) as in the client.

A step's constraints are where its swing foot lands and which way the body faces at its end, both
relative to the step's start: the frame where the stance foot stands, facing +Z (every sample of a
model starts so, motion_model). Only the first and the last canonical frames decide them, and a
clamped cubic B-spline's first and last values are its first and last coefficients, so a
candidate's constraint error costs two frames of forward kinematics, not the whole motion.
"""

import numpy as np

from . import kinematics, motion_model

HEADING_WEIGHT_M = 0.5  # metres of constraint error per radian of heading error
PRIOR_WEIGHT_M = 0.02  # metres of constraint error per unit of Mahalanobis distance
BEAM = 4  # nodes kept per level of the tree
CHOICES = 8  # the best leaf samples the search draws one from
TURN_PERCENTILES = (5, 95)  # the turns a model's steps make: from the one to the other
QUICKEST_SHARE = 25  # percent: the quickest steps of a model, passed by the search
RANDOM_BASELINE = 300  # random samples the search is measured against
MASS_WALL = 1.0  # metres per unit of Mahalanobis distance past the mixture's max_mahalanobis2


def hip_heading(positions, left_hip, right_hip):
    """Heading (radians, about +Y, 0 facing +Z) from the hip-to-hip axis: forward is the axis turned
    a quarter to the right, as terminators.headings has it, without its smoothing."""
    axis = positions[..., left_hip, :] - positions[..., right_hip, :]
    return np.arctan2(-axis[..., 2], axis[..., 0])


def wrap(angle):
    return (np.asarray(angle) + np.pi) % (2 * np.pi) - np.pi


def rotate_y(vectors, angle):
    """Ground vectors (..., 2) as (x, z), turned by angle about +Y."""
    c, s = np.cos(angle), np.sin(angle)
    x, z = vectors[..., 0], vectors[..., 1]
    return np.stack([c * x + s * z, -s * x + c * z], axis=-1)


class Rig:
    """What a step needs of its skeleton: FK data and the joints that define heading and feet."""

    def __init__(self, skeleton_row):
        hierarchy, joint_map = skeleton_row["hierarchy"], skeleton_row["joint_map"]
        joints = hierarchy["joints"]
        self.names = [j["name"] for j in joints]
        self.joint_map = dict(joint_map)
        self.parents = [j["parent"] for j in joints]
        self.offsets = np.array([j["offset"] for j in joints], dtype=np.float64)
        self.offsets.flags.writeable = False  # shared by the syntheses of its prepared models
        self.translated = list(hierarchy.get("translated", []))
        index = {k: self.names.index(v) for k, v in joint_map.items() if v in self.names}
        needed = ["pelvis", "left_hip", "right_hip", "left_ankle", "right_ankle"]
        missing = [k for k in needed if k not in index]
        if missing:
            raise ValueError(f"its joint map lacks {', '.join(missing)}")
        self.pelvis, self.left_hip, self.right_hip = (index[k] for k in ("pelvis", "left_hip",
                                                                          "right_hip"))  # fmt: skip
        self.ankle = {"left": index["left_ankle"], "right": index["right_ankle"]}

        # the constraints read these joints only: forward kinematics of them and their ancestors
        chain = set()
        for j in (self.pelvis, self.left_hip, self.right_hip, *self.ankle.values()):
            while j >= 0 and j not in chain:
                chain.add(j)
                j = self.parents[j]
        self.chain = sorted(chain)
        at = {j: k for k, j in enumerate(self.chain)}
        self.chain_parents = [at.get(self.parents[j], -1) for j in self.chain]
        self.chain_translated = [k for k, j in enumerate(self.chain) if j in self.translated]
        self.chain_translation_columns = [self.translated.index(j) for j in self.chain
                                          if j in self.translated]  # fmt: skip
        self.at = at

    def positions(self, rotations, translations):
        return kinematics.world_positions(self.parents, self.offsets, rotations, translations,
                                          self.translated)  # fmt: skip

    def chain_positions(self, rotations, translations):
        """World positions of the chain's joints only (index them through self.at)."""
        return kinematics.world_positions(
            self.chain_parents, self.offsets[self.chain], rotations[..., self.chain, :],
            translations[..., self.chain_translation_columns, :], self.chain_translated,
        )  # fmt: skip


def swing_side(primitive):
    """The foot a primitive swings ("left_step": left), or None when its name does not say."""
    name = primitive.lower()
    sides = [s for s in ("left", "right") if s in name]
    return sides[0] if len(sides) == 1 else None


def stance_side(swing):
    """The foot a step stands on: the other than the one it swings (None for None)."""
    return None if swing is None else ("right" if swing == "left" else "left")


class StepModel:
    """A motion model prepared for the search: its decoding of first and last frames, its mixture
    in whitened form, its tree (its means and samples as arrays), and the spread of its samples'
    steps. Read-only once made (its arrays are not writeable): syntheses running at once, in
    threads, share one (prepared_models keeps it for the process)."""

    prior_weight = PRIOR_WEIGHT_M  # metres of constraint error per unit of Mahalanobis distance
    within_mass = False  # refine() keeps the scores within the mixture's max_mahalanobis2

    def __init__(self, model, tree, rig):
        held = self._prepare(model, tree, rig)
        landing, turn, travel = self.features(held)
        # the model's ordinary step: its median landing and turn, and how far its turns reach
        self.usual_landing = np.median(landing, axis=0)
        self.usual_turn = float(np.median(turn))
        # the turns its steps make, both ways (a turning model's are two-sided: open and crossing
        # steps): the planner asks no turn beyond them
        self.turn_range = tuple(float(v) for v in np.percentile(turn, TURN_PERCENTILES))
        self.usual_travel = np.median(travel, axis=0)
        self.seconds = (model["n_frames"] - 1) / model["fps"]
        self._freeze()

    def _freeze(self):
        for value in (*vars(self).values(), *self.whiteners):
            if isinstance(value, np.ndarray):
                value.flags.writeable = False

    def _prepare(self, model, tree, rig):
        """What every model's search needs (its tree, decoding of ends, mixture); returns the
        samples its tree holds (or draws of its mixture)."""
        self.model, self.rig = model, rig
        self.tree = {**tree, "root": _packed(tree["root"])} if tree else tree
        spatial = model["spatial"]
        self.split = len(spatial["components"])
        mean = np.asarray(spatial["mean"], dtype=np.float64)
        components = np.asarray(spatial["components"], dtype=np.float64).reshape(self.split, -1)
        k = spatial["n_basis"]
        width = mean.size // k
        ends = np.r_[0:width, (k - 1) * width : k * width]  # first and last coefficient rows
        self.end_mean, self.end_components = mean[ends], components[:, ends]
        self.weights = np.asarray(spatial["weights"], dtype=np.float64)
        self.swing = swing_side(model["primitive"])
        mixture = model["mixture"]
        self.mixture_means = np.asarray(mixture["means"], dtype=np.float64)
        self.whiteners = [np.linalg.inv(np.linalg.cholesky(np.asarray(c, dtype=np.float64)))
                          for c in mixture["covariances"]]  # fmt: skip
        self.dimensions = self.mixture_means.shape[1]
        held = _leaf_samples(tree["root"]) if tree else motion_model.draw_scores(mixture, 2000, 0)
        # the quickest quarter of the model's motions swing their limbs fastest: drawn with far-out
        # shapes, a frame jumped more than any capture (Bandai's steps at 30 fps; its raises: up
        # to 1.35x the examples' p99.9 jump); the search passes them (errors_past_quickest)
        self.least_frames = float(np.percentile(self.durations(held), QUICKEST_SHARE))
        return held

    def durations(self, scores):
        """Frames each row of scores lasts (motion_model.time_function's end, for many rows)."""
        temporal = self.model["temporal"]
        basis = motion_model.basis(self.model["n_frames"] - 1, temporal["n_basis"])
        coefficients = np.asarray(temporal["mean"]) + np.atleast_2d(scores)[:, self.split :] @ (
            np.asarray(temporal["components"], dtype=np.float64))  # fmt: skip
        return np.exp(coefficients @ basis.T).sum(axis=1)

    def end_frames(self, scores):
        """(rotations (m, 2, J, 4), translations (m, 2, T, 3)) of the first and last canonical
        frames of m rows of joined scores."""
        scores = np.atleast_2d(scores)
        flat = self.end_mean + scores[:, : self.split] @ self.end_components
        m, n_t = len(scores), len(self.model["translated"])
        channels = flat.reshape(m, 2, -1)
        translations = channels[..., : 3 * n_t].reshape(m, 2, n_t, 3)
        rotations = channels[..., 3 * n_t :].reshape(m, 2, -1, 4) / self.weights[:, None]
        rotations /= np.maximum(np.linalg.norm(rotations, axis=-1, keepdims=True), 1e-12)
        if "limits" in self.model:
            rotations = motion_model.within_limits(rotations, self.model["limits"])
        return rotations, translations

    def features(self, scores):
        """Per row of scores: the swing foot's landing (x, z) from where the stance foot stands, in
        the frame of the step's first heading; the turn (radians) from its first heading to its
        last; the pelvis's travel (x, z) in that frame. Without a swing side, the landing is the
        pelvis's travel."""
        rotations, translations = self.end_frames(scores)
        m = len(rotations)
        rig, at = self.rig, self.rig.at
        positions = rig.chain_positions(
            rotations.reshape(2 * m, *rotations.shape[2:]),
            translations.reshape(2 * m, *translations.shape[2:]),
        )
        positions = positions.reshape(m, 2, -1, 3)
        headings = hip_heading(positions, at[rig.left_hip], at[rig.right_hip])
        first = headings[:, 0]
        pelvis = positions[:, :, at[rig.pelvis]][..., [0, 2]]
        travel = rotate_y(pelvis[:, 1] - pelvis[:, 0], -first)
        if self.swing is None:
            landing = travel
        else:
            stance = stance_side(self.swing)
            feet = positions[..., [0, 2]]
            moved = feet[:, 1, at[rig.ankle[self.swing]]] - feet[:, 0, at[rig.ankle[stance]]]
            landing = rotate_y(moved, -first)
        return landing, wrap(headings[:, 1] - first), travel

    def errors(self, scores, target):
        """Constraint error (metres; the heading's at HEADING_WEIGHT_M per radian) of each row."""
        landing, turn, _ = self.features(scores)
        miss = np.linalg.norm(landing - target[:2], axis=-1)
        return np.hypot(miss, HEADING_WEIGHT_M * wrap(turn - target[2]))

    def mahalanobis(self, scores):
        """Per row: the least Mahalanobis distance to a component of the mixture, and which."""
        d = np.stack([np.linalg.norm((np.atleast_2d(scores) - mu) @ w.T, axis=-1)
                      for mu, w in zip(self.mixture_means, self.whiteners)])  # fmt: skip
        return d.min(axis=0), d.argmin(axis=0)

    def search(self, target, rng):
        """(scores, candidates examined) from the tree: a beam of BEAM nodes down its levels, then
        one of the leaves' CHOICES samples of least error drawn with rng (so a seed varies the
        walk, and a straight walk does not repeat one pair of steps)."""
        held, examined = self.beam(target)
        e = self.errors_past_quickest(held, target)
        return held[rng.choice(np.argsort(e)[:CHOICES])], len(held) + examined

    def errors_past_quickest(self, scores, target):
        """self.errors of the rows of scores, infinite for those quicker than least_frames (unless
        every one is)."""
        e = self.errors(scores, target)
        quick = self.durations(scores) < self.least_frames
        if not quick.all():
            e[quick] = np.inf
        return e

    def beam(self, target):
        """(the samples of the leaves a beam of BEAM nodes reaches down the tree by self.errors,
        the inner nodes it examined)."""
        level = [self.tree["root"]]
        leaves, examined = [], 0
        while level:
            inner = [c for node in level for c in node.get("children", [])]
            leaves += [node for node in level if "samples" in node]
            if not inner:
                break
            examined += len(inner)
            means = np.array([c["mean"] for c in inner])
            level = [inner[i] for i in np.argsort(self.errors(means, target))[:BEAM]]
        return np.concatenate([np.asarray(leaf["samples"], dtype=np.float64)
                               for leaf in leaves]), examined  # fmt: skip

    def refine(self, start, target):
        """The scores near start that least-squares minimise the constraint error plus
        PRIOR_WEIGHT_M times the Mahalanobis distance to start's component (scipy). Only the
        spatial scores move: the timing stays the sampled one, which the constraints do not see
        (moved by the prior alone, it went to its component's mean: steps a fifth shorter than
        the examples' median on CMU 16)."""
        from scipy.optimize import least_squares

        _, component = self.mahalanobis(start)
        mu, whiten = self.mixture_means[component[0]], self.whiteners[component[0]]
        timing = start[self.split :]
        limit = self.model["mixture"].get("max_mahalanobis2") if self.within_mass else None

        def residuals(spatial):
            """Rows of residuals, one per row of spatial scores."""
            spatial = np.atleast_2d(spatial)
            x = np.hstack([spatial, np.broadcast_to(timing, (len(spatial), len(timing)))])
            z = (x - mu) @ whiten.T
            rows = [self.constraint_residuals(x, target), self.prior_weight * z]
            if limit:  # a steep wall at the edge of the mass the model draws from
                rows.append(MASS_WALL * np.maximum(0.0, np.linalg.norm(z, axis=1, keepdims=True)
                                                   - np.sqrt(limit)))  # fmt: skip
            return np.concatenate(rows, axis=1)

        def jacobian(x):
            """Forward differences, every column from one batch of features."""
            step = 1e-4 * np.maximum(1.0, np.abs(x))
            rows = residuals(np.vstack([x, x + np.diag(step)]))
            return ((rows[1:] - rows[0]) / step[:, None]).T

        found = least_squares(lambda x: residuals(x)[0], start[: self.split], jac=jacobian,
                              method="trf" if limit else "lm", max_nfev=100 if limit else 50).x
        return np.concatenate([found, timing])

    def constraint_residuals(self, scores, target):
        """Per row of scores, the constraint's residuals in metres (refine squares them): the
        landing's miss and the heading's at HEADING_WEIGHT_M per radian."""
        landing, turn, _ = self.features(scores)
        heading = HEADING_WEIGHT_M * wrap(turn - target[2])[:, None]
        return np.concatenate([landing - target[:2], heading], axis=1)

    def calm_draw(self, rng, spread):
        """One draw of the mixture (its seed from rng) taken `spread` of the way from its
        component's mean (0: the mean; 1: as drawn): an idle piece, a repeated action."""
        drawn = motion_model.draw_scores(self.model["mixture"], 1, int(rng.integers(2**31)))
        mean = self.mixture_means[self.mahalanobis(drawn)[1][0]]
        return mean + spread * (drawn[0] - mean)

    def best_random(self, target, rng, n=RANDOM_BASELINE):
        """The least constraint error among n draws of the mixture (the baseline the search must
        beat)."""
        draws = motion_model.draw_scores(self.model["mixture"], n, int(rng.integers(2**31)))
        return float(self.errors(draws, target).min())


def _packed(node):
    """The tree's node with its mean and samples as read-only float64 arrays (a search reads them
    as arrays: converted once, not at every step), its children packed alike."""
    out = dict(node)
    for key in ("mean", "samples"):
        if key in node:
            out[key] = np.asarray(node[key], dtype=np.float64)
            out[key].flags.writeable = False
    if "children" in node:
        out["children"] = [_packed(child) for child in node["children"]]
    return out


def _leaf_samples(root):
    out, stack = [], [root]
    while stack:
        node = stack.pop()
        if "samples" in node:
            out.append(np.asarray(node["samples"], dtype=np.float64))
        else:
            stack.extend(node["children"])
    return np.concatenate(out)
