"""A database for actions (issue 63), built once per run: Bandai dataset 2's walks and turns,
dataset 1's bows for standing (retargeted onto the walks' skeleton), a few of dataset 2's hand
raises and waves annotated by `modb annotate --action`, and the family graph GRAPH with their
action nodes."""

from __future__ import annotations

from .commands import run_modb_here as modb
from .data import mocap

GRAPH = "walk"
COLLECTION = "actions"
BUILT = "shared_bandai_actions"
RAISES = 12  # clips of each hand: with the other side's mirrored, 24 examples a model
WAVES = 8
ACTIONS = {"raise_right_hand": ("raise-up-right-hand", RAISES),
           "raise_left_hand": ("raise-up-left-hand", RAISES),
           "wave_right_hand": ("wave-right-hand", WAVES),
           "wave_left_hand": ("wave-left-hand", WAVES)}  # fmt: skip


def build(dsn: str) -> None:
    data = mocap("bandai-2-dev", "data")
    walks = [str(p) for kind in ("walk_active", "walk-turn-left_active", "walk-turn-right_active")
             for p in sorted(data.glob(f"dataset-2_{kind}_0*.bvh"))[:8]]  # fmt: skip
    bows = [str(p) for p in sorted(mocap("bandai-1", "data").glob("dataset-1_bow_*.bvh"))]
    steps = [
        ("load", *walks, "--collection", COLLECTION, "--no-snippets", "-q"),
        ("load", *bows, "--collection", "bows", "--no-snippets", "-q"),
        # the bows (their own skeleton) onto the walks': standing before and after
        ("retarget", "bows", "--to", f"{COLLECTION}/dataset-2_walk_active_001", "--collection",
         f"{COLLECTION}/standing", "-q"),
        ("annotate", "--steps", COLLECTION, "-q"),
    ]  # fmt: skip
    for action, (files, n) in ACTIONS.items():
        where = f"{COLLECTION}/{action}"
        paths = [str(p) for p in sorted(data.glob(f"dataset-2_{files}_active_0*.bvh"))[:n]]
        steps += [("load", *paths, "--collection", where, "--no-snippets", "-q"),
                  ("annotate", "--action", action, where, "-q")]  # fmt: skip
    steps.append(("model", "graph", GRAPH, "--collection", COLLECTION, "-q"))
    for args in steps:
        r = modb(dsn, *args)
        assert r.returncode == 0, (args[:2], r.stderr)


def action_files(action: str) -> list:
    """The capture files of an action that the build did not load (held out), and those it did."""
    files, n = ACTIONS[action]
    paths = sorted(mocap("bandai-2-dev", "data").glob(f"dataset-2_{files}_active_*.bvh"))
    return paths[n:], paths[:n]
