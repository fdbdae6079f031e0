"""Cost-to-go over a transition graph: for every kept snippet, the least time (seconds) a chain of
graph snippets needs from that snippet's end until the pelvis is within the arrival radius of a
goal, for goals on a polar grid around that end (in its heading frame: x left, z forward).

Why: a choice scored by where the candidate itself leads is greedy. It walks away from a goal behind
the avatar when every successor of a straight walk goes straight, and circles a near goal. The
cost-to-go counts the turns the data can make after the candidate, however many snippets they take
(as in near-optimal controllers over motion graphs), so select_next_snippet's stored-transition
level ranks by "seconds to the goal through this candidate" in one indexed lookup per candidate.

Computed by value iteration (Bellman): V(s, g) = min over successors t of s of duration(t) + seam(s,
t) + V(t, g seen from t's end), V = 0 within the arrival radius. seam(s, t) is the transition's
continuity ratio times the profile's continuity_weight / speed: the price the selection puts on a
rough seam, so a plan through many rough cuts costs what the chain will pay for them. Off-grid goals
are read by bilinear interpolation in (angle, log radius); beyond the outer ring by the outer ring's
value plus the extra distance at the graph's median speed. The SQL reader is modb.cost_to_go, the
same arithmetic.
"""

from dataclasses import asdict, dataclass

import numpy as np

# Seconds: stop once no value changes more than this in an iteration (then within ~0.1 s of
# convergence).
TOLERANCE = 0.01
MAX_ITERATIONS = 300
MIN_SPEED = 0.1  # m/s: the price of distance beyond the grid when the snippets hardly move
@dataclass(frozen=True)
class Grid:
    """Goal positions: `angles` directions (0 = straight ahead, counter-clockwise toward +x = left)
    times `rings` radii from inner_radius (reached) to outer_radius, log-spaced. speed (m/s) prices
    the distance beyond the outer ring. Values are stored angle-major: index angle * rings +
    ring."""

    speed: float
    angles: int = 24
    rings: int = 11
    inner_radius: float = 0.5
    outer_radius: float = 12.0

    def radii(self) -> np.ndarray:
        return self.inner_radius * (self.outer_radius / self.inner_radius) ** (
            np.arange(self.rings) / (self.rings - 1)
        )

    def points(self) -> tuple[np.ndarray, np.ndarray]:
        """(x, z) of every grid point, in storage order."""
        theta = np.arange(self.angles) * 2 * np.pi / self.angles
        r = self.radii()
        return (np.sin(theta)[:, None] * r).ravel(), (np.cos(theta)[:, None] * r).ravel()

    def as_json(self) -> dict:
        return asdict(self)


def interpolation(grid: Grid, x: np.ndarray, z: np.ndarray):
    """For goals at (x, z): the 4 grid indices and weights of the bilinear read, and the seconds
    added beyond the outer ring. Goals within the inner radius get weights 0: reached."""
    r = np.hypot(x, z)
    ring = (
        np.log(np.maximum(r, 1e-9) / grid.inner_radius)
        / np.log(grid.outer_radius / grid.inner_radius)
        * (grid.rings - 1)
    )
    ring = np.clip(ring, 0, grid.rings - 1 - 1e-9)
    j0 = np.floor(ring).astype(np.int64)
    wj = ring - j0
    angle = np.mod(np.arctan2(x, z), 2 * np.pi) / (2 * np.pi / grid.angles)
    a0 = np.floor(angle).astype(np.int64) % grid.angles
    a1 = (a0 + 1) % grid.angles
    wa = angle - np.floor(angle)
    index = np.stack(
        [
            a0 * grid.rings + j0,
            a0 * grid.rings + j0 + 1,
            a1 * grid.rings + j0,
            a1 * grid.rings + j0 + 1,
        ],
        -1,
    )
    weight = np.stack([(1 - wa) * (1 - wj), (1 - wa) * wj, wa * (1 - wj), wa * wj], -1)
    beyond = np.maximum(r - grid.outer_radius, 0) / grid.speed
    reached = r <= grid.inner_radius
    weight[reached] = 0
    beyond[reached] = 0
    return index, weight.astype(np.float32), beyond.astype(np.float32)


def seen_from_end(net_x, net_z, heading, x, z):
    """Points (x, z) of a snippet's start frame seen from its end (modb.world_to_local): per snippet
    rows."""
    dx = x[None, :] - np.asarray(net_x)[:, None]
    dz = z[None, :] - np.asarray(net_z)[:, None]
    c, s = np.cos(heading)[:, None], np.sin(heading)[:, None]
    return dx * c - dz * s, dx * s + dz * c


def cost_to_go(grid: Grid, net_x, net_z, heading, duration, src, dst, seam, progress=None):
    """Values (n snippets, grid size) float32 in seconds, the iterations run and the last change.
    src, dst: transitions among the n snippets (indices), seam: what each costs (seconds) besides
    the duration of dst; a snippet without successors gets infinity."""
    n = len(duration)
    size = grid.angles * grid.rings
    gx, gz = grid.points()
    index, weight, beyond = interpolation(
        grid, *seen_from_end(net_x, net_z, np.asarray(heading), gx, gz)
    )
    index += (np.arange(n) * size)[:, None, None]  # into the flattened values
    # The bilinear read as four gathers of contiguous corner arrays, summed in the order the
    # (n, size, 4) product's sum took them: the same floats, 3x faster than summing a length-4 axis.
    corners = [(index[..., k].ravel(), weight[..., k].ravel()) for k in range(4)]
    duration = np.asarray(duration, dtype=np.float32)[:, None]
    src, dst = np.asarray(src, dtype=np.int64), np.asarray(dst, dtype=np.int64)
    seam = np.asarray(seam, dtype=np.float32)
    # Transitions rank-major (every source's first successor, then every second, ...): the minimum
    # over successors is then one elementwise minimum per rank, not a reduceat over gathered runs.
    order = np.argsort(src, kind="stable")
    src, dst, seam = src[order], dst[order], seam[order][:, None]
    degree = np.bincount(src, minlength=n)
    rank = np.arange(len(src)) - np.repeat(np.cumsum(degree) - degree, degree)
    by_rank = np.argsort(rank, kind="stable")
    src, dst, seam, rank = src[by_rank], dst[by_rank], seam[by_rank], rank[by_rank]
    rank_bounds = np.searchsorted(rank, np.arange((rank.max() + 2) if len(rank) else 1))
    through = np.empty((n, size), dtype=np.float32)
    corner = np.empty(n * size, dtype=np.float32)
    candidates = np.empty((int(np.count_nonzero(degree)), size), dtype=np.float32)
    ring0 = np.tile(np.arange(grid.rings), grid.angles) == 0
    # Start from the straight-line time at the median speed: near the answer, so fewer iterations.
    values = np.tile(
        np.maximum(np.hypot(gx, gz) - grid.inner_radius, 0) / grid.speed, (n, 1)
    ).astype(np.float32)
    values[:, ring0] = 0
    change = np.inf
    for iteration in range(1, MAX_ITERATIONS + 1):
        # Via each snippet as the next: duration + the bilinear read of its values + beyond.
        flat, out = values.ravel(), through.ravel()
        for k, (at, w) in enumerate(corners):
            np.take(flat, at, out=corner)
            np.multiply(corner, w, out=corner)
            if k == 0:
                out[:] = corner
            else:
                np.add(out, corner, out=out)
        np.add(duration, through, out=through)
        np.add(through, beyond, out=through)
        new = np.full_like(values, np.inf)
        for lo, hi in zip(rank_bounds[:-1], rank_bounds[1:]):
            rows, sources = candidates[: hi - lo], src[lo:hi]
            np.take(through, dst[lo:hi], axis=0, out=rows)
            np.add(rows, seam[lo:hi], out=rows)
            np.minimum(new[sources], rows, out=rows)
            new[sources] = rows
        new[:, ring0] = 0
        finite = np.isfinite(new)
        change = float(np.abs(np.where(finite, new - values, 0)).max()) if n else 0.0
        values = new
        if progress:
            progress(iteration, change)
        if change < TOLERANCE:
            break
    return values, iteration, change
