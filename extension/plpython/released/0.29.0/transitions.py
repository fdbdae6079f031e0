"""The transition graph of a snippet set: which snippet can follow which at relaxation level 0, and
the part of it a chain can keep moving and steering in: the largest strongly connected component (as
in motion graphs) that holds turns both ways.

Outside it a chain runs into a dead end: a snippet from which the data cannot be left smoothly, or a
component it cannot leave that never turns (in Bandai dataset 2, the runs: from a run's end only
runs pass the thresholds, and no run turns more than 14 degrees in 1.5 s). Restricting the choice to
the steerable component keeps every chain where it can face its next goal.

The edge test is select_next_snippets' level 0, computed for all pairs at once: the same search box
around the end's features, the same per-joint ratio (position by the norm, rotation angle,
velocities) with the same float4 arithmetic, and the same rule against replaying the previous
snippet's frames. Needs scipy (the server: Debian's python3-scipy) for the box search and the
components.
"""

import numpy as np

from . import quaternion

BOX_MARGIN = 1e-4  # match_box's margin: terminators store float4, features float8
# The box search's k-d tree spans only the features that spread most (in box half-widths); numpy
# checks the rest. A tree over all 49 features prunes little in that many dimensions: on Bandai's
# locomotion, 12 found the same candidates 4x faster.
TREE_FEATURES = 12


class Terminators:
    """Per terminator row i: positions, velocities, angular velocities (n, 19, 3), rotations (n, 19,
    4) as stored (float4), and features (n, 25)."""

    def __init__(self, positions, rotations, velocities, angular_velocities, features):
        n = len(features)
        self.positions = np.asarray(positions, dtype=np.float32).reshape(n, -1, 3)
        self.rotations = np.asarray(rotations, dtype=np.float32).reshape(n, -1, 4)
        self.velocities = np.asarray(velocities, dtype=np.float32).reshape(n, -1, 3)
        self.angular_velocities = np.asarray(angular_velocities, dtype=np.float32).reshape(n, -1, 3)
        self.features = np.asarray(features, dtype=np.float64).reshape(n, -1)


def _norm(a, b, norm):
    d = (a - b).astype(np.float64)  # the SQL subtracts float4 values, then widens
    return np.abs(d).sum(axis=-1) if norm == "l1" else np.sqrt((d * d).sum(axis=-1))


def _joint_terms(term, src, dst, plan, j):
    """Joint j's continuity terms for pairs (end terminator src[k], begin terminator dst[k]):
    (difference, threshold) for the rotation angle, the position (the plan's norm) and, with
    velocity terms, the velocity and angular velocity."""
    yield (
        quaternion.angle_between(term.rotations[src, j], term.rotations[dst, j]),
        plan["angle_threshold"][j],
    )
    yield (
        _norm(term.positions[src, j], term.positions[dst, j], plan["norm"]),
        plan["position_threshold"][j],
    )
    if plan["velocity_terms"]:
        yield (
            _norm(term.velocities[src, j], term.velocities[dst, j], "l2"),
            plan["velocity_threshold"][j],
        )
        yield (
            _norm(term.angular_velocities[src, j], term.angular_velocities[dst, j], "l2"),
            plan["angular_velocity_threshold"][j],
        )


def _within(term, src, dst, plan):
    """Of the pairs (end terminator src[k], begin terminator dst[k]), those whose continuity ratio
    is at most 1 (a mask), and the ratio of those. Joint by joint, the tightest first, so a pair
    that fails is dropped early."""
    keep = np.ones(len(src), dtype=bool)
    ratio = np.zeros(len(src))
    for j in sorted(plan["joints"], key=lambda j: plan["angle_threshold"][j]):
        at = np.flatnonzero(keep)
        ok = np.ones(len(at), dtype=bool)
        worst = ratio[at]
        for difference, threshold in _joint_terms(term, src[at], dst[at], plan, j):
            ok &= difference <= threshold
            worst = np.maximum(worst, difference / threshold)
        ratio[at] = worst
        keep[at[~ok]] = False
    return keep, ratio[keep]


def ratios(term, src, dst, plan):
    """The continuity ratio of pairs (end terminator src[k], begin terminator dst[k]): the largest
    over the plan's joints and terms of difference / threshold (select_next_snippets'
    continuity_ratio)."""
    ratio = np.zeros(len(src))
    for j in plan["joints"]:
        for difference, threshold in _joint_terms(term, src, dst, plan, j):
            ratio = np.maximum(ratio, difference / threshold)
    return ratio


def edges(term, begin, end, group, clip, first_frame, n_frames, plan, chunk=2000, progress=None):
    """Level-0 transitions (from snippet index, to snippet index, continuity ratio) among snippets
    given by their begin and end terminator rows in `term`, their pose/rate group, clip (and
    version, mirror: one key) and window. progress(done) is called after each chunk of sources."""
    # scipy here, not at the top: a server session that only selects never pays its import (about
    # 250 ms), only one that builds a graph.
    from scipy.spatial import cKDTree

    half = np.asarray(plan["box_half_width"], dtype=np.float64) + BOX_MARGIN
    out_src, out_dst, out_ratio = [], [], []
    done = 0
    for g in np.unique(group):
        members = np.flatnonzero(group == g)
        starts = term.features[begin[members]] / half
        dims = np.argsort(-starts.std(axis=0))[:TREE_FEATURES]
        tree = cKDTree(starts[:, dims])
        for lo in range(0, len(members), chunk):
            sources = members[lo : lo + chunk]
            done += len(sources)
            ends = term.features[end[sources]] / half
            near = cKDTree(ends[:, dims]).sparse_distance_matrix(
                tree, 1.0, p=np.inf, output_type="ndarray"
            )
            i, j = near["i"], near["j"]
            inside = (np.abs(ends[i] - starts[j]) <= 1.0).all(axis=1)
            if not inside.any():
                continue  # (progress is reported with the next chunk that has candidates)
            s, d = sources[i[inside]], members[j[inside]]
            # No replay of the previous snippet's frames (its last frame, the seam, aside).
            overlap = (
                (clip[s] == clip[d])
                & (first_frame[s] + 1 <= first_frame[d] + n_frames[d] - 1)
                & (first_frame[d] + 1 <= first_frame[s] + n_frames[s] - 1)
            )
            s, d = s[~overlap], d[~overlap]
            keep, ratio = _within(term, end[s], begin[d], plan)
            out_src.append(s[keep])
            out_dst.append(d[keep])
            out_ratio.append(ratio)
            if progress:
                progress(done)
    if not out_src:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0)
    return np.concatenate(out_src), np.concatenate(out_dst), np.concatenate(out_ratio)


def steerable(n, src, dst, group, turn, min_turn):
    """Per snippet: True when it lies in the largest strongly connected component of its pose/rate
    group among those (of more than one snippet) whose snippets include turns of at least min_turn
    radians each way (`turn`: the heading change where each one leads). A chain in it can always
    move on, and can face any goal. (The largest only, as in motion graphs: on Bandai dataset 2,
    adding the active walks' component to the slow walks' made right-angle courses worse:
    docs/synthesis.md "Transition graphs".)"""
    # scipy only when a graph is built (see edges()).
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    graph = coo_matrix((np.ones(len(src), dtype=np.int8), (src, dst)), shape=(n, n)).tocsr()
    _, label = connected_components(graph, directed=True, connection="strong")
    turn = np.asarray(turn, dtype=np.float64)
    size = np.bincount(label, minlength=label.max() + 1)
    left = np.zeros(len(size), dtype=bool)
    right = np.zeros(len(size), dtype=bool)
    np.logical_or.at(left, label, turn >= min_turn)
    np.logical_or.at(right, label, turn <= -min_turn)
    eligible = (size > 1) & left & right
    keep = np.zeros(n, dtype=bool)
    for g in np.unique(group):
        members = np.flatnonzero(group == g)
        candidates = np.unique(label[members][eligible[label[members]]])
        if len(candidates):
            keep[members[label[members] == candidates[size[candidates].argmax()]]] = True
    return keep
