"""Time alignment of a motion primitive's examples (after the DFKI pipeline): each example's frames
warped onto a reference example's by dynamic time warping, section by section between keyframes so
that contacts land on the reference's. Plain numpy (server and client).

The cost of matching two frames is the mean distance between their joints' forward-kinematics
positions (the mapped standard joints), each example first turned about the vertical so that its
first frame faces +Z and moved on the ground so that its first frame's pelvis is at the origin (the
2-D alignment). A warp's path runs from the section's first frames to its last ones, each move one
frame on, in one or both; its cost is the sum of the matched frames' costs. The time function gives,
for each of the reference's frames, the example's (fractional) frame matched to it: the mean of the
frames the path pairs with it (at a section's ends, its keyframe), so it never runs backwards, and
the keyframes map onto each other."""

import numpy as np

from . import kinematics
from . import terminators as T
from .joints import STANDARD_JOINTS


class AlignError(ValueError):
    pass


def canonical_positions(parents, offsets, rotations, translations, translated, std, fps):
    """(frames, standard joints, 3) positions, turned and moved so the first frame faces +Z with
    its pelvis above the origin. std: the standard joints' indices
    (terminators.standard_indices)."""
    positions = kinematics.world_positions(parents, offsets, rotations, translations, translated)
    positions = positions[:, std]
    left, right = STANDARD_JOINTS.index("left_hip"), STANDARD_JOINTS.index("right_hip")
    heading = T.headings(positions[:1], left, right, fps)[0]
    c, s = np.cos(-heading), np.sin(-heading)
    origin = positions[0, STANDARD_JOINTS.index("pelvis")] * np.array([1.0, 0.0, 1.0])
    moved = positions - origin
    x = c * moved[..., 0] + s * moved[..., 2]
    z = -s * moved[..., 0] + c * moved[..., 2]
    return np.stack([x, moved[..., 1], z], axis=-1)


def frame_costs(a, b):
    """(len(a), len(b)) mean joint distance between every frame of a and every frame of b."""
    return np.linalg.norm(a[:, None] - b[None, :], axis=-1).mean(axis=-1)


def warp(costs):
    """The cheapest monotone path through the cost matrix from (0, 0) to (n-1, m-1): its total
    cost and its pairs [(i, j), ...] in order."""
    n, m = costs.shape
    total = np.full((n + 1, m + 1), np.inf)
    total[0, 0] = 0.0
    for i in range(1, n + 1):
        row, above = total[i], total[i - 1]
        for j in range(1, m + 1):
            row[j] = costs[i - 1, j - 1] + min(above[j - 1], above[j], row[j - 1])
    i, j, path = n, m, [(n - 1, m - 1)]
    while (i, j) != (1, 1):
        moves = (
            (total[i - 1, j - 1], i - 1, j - 1),
            (total[i - 1, j], i - 1, j),
            (total[i, j - 1], i, j - 1),
        )
        _, i, j = min(moves, key=lambda move: move[0])
        path.append((i - 1, j - 1))
    return float(total[n, m]), path[::-1]


def time_function(path, m):
    """For each of the m reference frames, the mean example frame the path pairs with it."""
    sums, counts = np.zeros(m), np.zeros(m)
    for i, j in path:
        sums[j] += i
        counts[j] += 1
    return sums / counts


def sections_of(keyframes, start, end):
    """The frame numbers (from the segment's start) that bound its sections: start, its keyframes
    inside, end."""
    inner = sorted({k - start for k in keyframes if start < k < end})
    return [0, *inner, end - start]


def align(example, reference, example_sections, reference_sections):
    """The example's time function onto the reference (one value per reference frame) and the cost
    of each section's warp. example, reference: canonical positions; *_sections: section bounds
    (sections_of), as many in both."""
    if len(example_sections) != len(reference_sections):
        raise AlignError(
            f"{len(example_sections) - 1} sections against the reference's "
            f"{len(reference_sections) - 1}: give the examples the same keyframes"
        )
    times, costs = [], []
    bounds = list(
        zip(example_sections, example_sections[1:], reference_sections, reference_sections[1:])
    )
    for k, (a0, a1, b0, b1) in enumerate(bounds):
        cost, path = warp(frame_costs(example[a0 : a1 + 1], reference[b0 : b1 + 1]))
        t = a0 + time_function(path, b1 - b0 + 1)
        t[0], t[-1] = a0, a1  # keyframe onto keyframe, whatever else the ends were paired with
        times.append(t if k == 0 else t[1:])  # a section's first frame is the last one's end
        costs.append(cost)
    return np.concatenate(times), costs


def reference_index(lengths):
    """The example whose length is closest to the mean (the first of a tie)."""
    lengths = np.asarray(lengths, dtype=np.float64)
    return int(np.argmin(np.abs(lengths - lengths.mean())))
