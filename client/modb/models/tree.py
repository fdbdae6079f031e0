"""The acceleration tree of a motion model (after the DFKI pipeline): about 10,000 samples of the
mixture split by k-means (scikit-learn's KMeans) into a few children, recursively, until a node
holds a few; each node keeps the mean of its samples, each leaf its samples' scores. A search for
the scores that best meet a constraint descends it (synthesis from models); it lives in the
model's meta, so it can be rebuilt without a new version."""

from __future__ import annotations

from typing import Any

import numpy as np
from modb_kernel import motion_model
from sklearn.cluster import KMeans

SAMPLES = 10_000
CHILDREN = 4
LEAF = 16  # a node with at most this many samples is a leaf
DIGITS = 5  # stored precision of the scores: the tree is large


def _round(a: np.ndarray) -> list[Any]:
    return np.round(a, DIGITS).tolist()


def _node(scores: np.ndarray, children: int, leaf: int, seed: int) -> dict[str, Any]:
    mean = scores.mean(axis=0)
    if len(scores) <= max(leaf, children):
        return {"mean": _round(mean), "samples": _round(scores)}
    labels = KMeans(children, n_init=1, max_iter=100, random_state=seed).fit_predict(scores)
    groups = [scores[labels == k] for k in range(children) if np.any(labels == k)]
    if len(groups) < 2:  # every sample alike: nothing left to split
        return {"mean": _round(mean), "samples": _round(scores)}
    return {"mean": _round(mean), "children": [_node(g, children, leaf, seed) for g in groups]}


def build_tree(model: dict[str, Any], samples: int = SAMPLES, children: int = CHILDREN,
               leaf: int = LEAF, seed: int = 0) -> dict[str, Any]:  # fmt: skip
    """The tree of `samples` draws from the model's mixture (reproducible from the seed)."""
    scores = motion_model.draw_scores(model["mixture"], samples, seed)
    return {
        "samples": samples,
        "children": children,
        "leaf": leaf,
        "seed": seed,
        "root": _node(scores, children, leaf, seed),
    }


def shape(tree: dict[str, Any]) -> dict[str, int]:
    """Nodes, leaves, depth and samples held by the leaves, for listings."""
    nodes = leaves = depth = held = 0
    stack = [(tree["root"], 1)]
    while stack:
        node, level = stack.pop()
        nodes += 1
        depth = max(depth, level)
        if "samples" in node:
            leaves += 1
            held += len(node["samples"])
        else:
            stack.extend((c, level + 1) for c in node["children"])
    return {"nodes": nodes, "leaves": leaves, "depth": depth, "samples": held}
