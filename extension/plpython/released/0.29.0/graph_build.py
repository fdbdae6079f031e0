"""A transition graph computed from the rows modb.build_transition_graph reads (its snippets and
their terminators): the level-0 edges, the component a chain can steer in (transitions.py) and its
cost-to-go (cost_to_go.py). Plain numpy, so that a job worker on another machine computes what the
server's PL/Python would, and the database only stores it."""

from dataclasses import dataclass

import numpy as np

from . import cost_to_go as C
from . import transitions as T

# A hair looser than level 0, so the stored transitions hold every pair the SQL test passes (numpy
# and SQL round differently); selection applies the exact test again.
TRANSITION_SLACK = 1e-9
THRESHOLDS = (
    "position_threshold",
    "angle_threshold",
    "velocity_threshold",
    "angular_velocity_threshold",
)


class GraphBuildError(ValueError):
    """No graph can be made of these snippets: (message, hint)."""

    def __init__(self, message, hint):
        super().__init__(message)
        self.hint = hint


@dataclass
class Built:
    data: dict  # modb.graphs.data
    kept: list  # snippet ids the graph keeps, in id order
    from_ids: list  # its transitions among the kept, one pair per edge
    to_ids: list
    costs: np.ndarray  # (len(kept), angles * rings) cost-to-go, row k for kept[k]
    width: int  # angles * rings


def build(
    name,
    snippets,
    terminators,
    plan,
    plan_shown,
    transition_key,
    profile,
    collection,
    min_turn_degrees,
    notice=lambda text: None,
    advance=None,
):
    """snippets: rows (dicts) ordered by id with id, begin_terminator, end_terminator, grp,
    future_heading, clip, first_frame, n_frames, net_x, net_z, net_heading, duration (as
    modb.transition_graph_inputs gives them); terminators: rows with id, positions, rotations,
    velocities, angular_velocities, features; plan: a modb.match_plan row. notice(text): what the
    build is at; advance(done, total): the snippets whose edges are found so far (else a notice)."""
    n = len(snippets)

    def column(key):
        return [r[key] for r in snippets]

    row_of = {r["id"]: i for i, r in enumerate(terminators)}
    term = T.Terminators(
        *(
            [r[c] for r in terminators]
            for c in ("positions", "rotations", "velocities", "angular_velocities", "features")
        )
    )

    def keys(values):
        return np.unique(values, return_inverse=True)[1]

    begin = np.array([row_of[t] for t in column("begin_terminator")])
    end = np.array([row_of[t] for t in column("end_terminator")])
    group, clip = keys(column("grp")), keys(column("clip"))
    first_frame, n_frames = np.array(column("first_frame")), np.array(column("n_frames"))
    thresholds = {
        k: np.array(plan[k], dtype=np.float64) * (1 + TRANSITION_SLACK) for k in THRESHOLDS
    }
    spec = dict(
        thresholds,
        joints=list(plan["joints"]),
        norm=plan["norm"],
        velocity_terms=plan["velocity_terms"],
        box_half_width=plan["box_half_width"],
    )
    src, dst, ratio = T.edges(
        term,
        begin,
        end,
        group,
        clip,
        first_frame,
        n_frames,
        spec,
        progress=lambda done: (
            advance(done, n)
            if advance
            else notice(f'transition graph "{name}": {done}/{n} snippets')
        ),
    )
    turn = np.array(
        [np.nan if t is None else t for t in column("future_heading")], dtype=np.float64
    )
    keep = T.steerable(n, src, dst, group, np.nan_to_num(turn), np.radians(min_turn_degrees))
    ids = np.array(column("id"), dtype=np.int64)
    out_degree = np.bincount(src, minlength=n)
    inside = keep[src] & keep[dst]
    kept = np.flatnonzero(keep)
    if not len(kept):
        raise GraphBuildError(
            f'transition graph "{name}": no set of these {n} snippets can keep walking and turn '
            f"{min_turn_degrees:g} degrees each way",
            "load more varied motion (turns, both ways), or pass a smaller min_turn_degrees",
        )
    position = np.full(n, -1)
    position[kept] = np.arange(len(kept))
    net_x, net_z, heading, duration = (
        np.array(column(c), dtype=np.float64)[kept]
        for c in ("net_x", "net_z", "net_heading", "duration")
    )
    # Priced beyond its grid at the kept snippets' median speed.
    grid = C.Grid(speed=max(float(np.median(np.hypot(net_x, net_z) / duration)), C.MIN_SPEED))
    notice(
        f'transition graph "{name}": cost-to-go of {len(kept)} snippets on '
        f"{grid.angles} x {grid.rings} goal positions"
    )
    seconds_per_ratio = (
        plan["continuity_weight"] or 0
    ) / grid.speed  # the selection's price of a rough seam
    costs, iterations, change = C.cost_to_go(
        grid,
        net_x,
        net_z,
        heading,
        duration,
        position[src[inside]],
        position[dst[inside]],
        ratio[inside] * seconds_per_ratio,
        progress=lambda i, c: (
            i % 10
            or notice(
                f'transition graph "{name}": cost-to-go iteration {i}, largest change {c:.3f} s'
            )
        ),
    )
    data = {
        "profile": profile,
        "collection": collection,
        "min_turn_degrees": min_turn_degrees,
        "plan": plan_shown,
        "snippets": n,
        "edges": int(len(src)),
        "kept": int(keep.sum()),
        "dead_ends": int((out_degree == 0).sum()),
        "edges_within_kept": int(inside.sum()),
        "transition_key": transition_key,
        "cost_to_go": dict(
            grid.as_json(),
            seconds_per_ratio=seconds_per_ratio,
            iterations=iterations,
            last_change=change,
        ),
    }
    notice(
        f'transition graph "{name}": kept {data["kept"]} of {n} snippets '
        f"({data['edges']} transitions, {data['dead_ends']} snippets with none); "
        f"cost-to-go after {iterations} iterations "
        f"(last change {change:.3f} s)"
    )
    return Built(
        data,
        ids[kept].tolist(),
        ids[src[inside]].tolist(),
        ids[dst[inside]].tolist(),
        costs,
        grid.angles * grid.rings,
    )
