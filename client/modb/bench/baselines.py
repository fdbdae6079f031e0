"""The baselines `modb bench scale` sets beside select_next_snippet (see modb.bench.scale).

(a) the paper's flat query (FLAT); (b) a numpy brute force, (c) a k-d tree and (d) a vectorised box
scan in this process, over a Snapshot of the stored terminators.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import psycopg
from scipy.spatial import cKDTree

from modb_kernel import transitions

# Relaxation levels 0-3 scale every threshold; level 4 takes the nearest.
LEVELS = (1.0, 2.0, 4.0, 8.0)

# (a): every snippet scored; level and order as select_next_snippets, without its index.
FLAT = """
WITH cfg AS MATERIALIZED (SELECT modb.match_plan(%(profile)s) AS plan),
p AS MATERIALIZED (
    SELECT t AS term, t.features, s.pose_key, s.fps, s.clip_id, s.version, s.mirrored,
           s.first_frame, s.n_frames
      FROM modb.snippets s JOIN modb.terminators t ON t.id = s.end_terminator WHERE s.id = %(prev)s)
SELECT c.id, l.level
  FROM cfg, p, modb.snippets c JOIN modb.terminators b ON b.id = c.begin_terminator
 CROSS JOIN LATERAL (SELECT modb.continuity_ratio(p.term, b, cfg.plan) AS ratio) r
 CROSS JOIN LATERAL (SELECT CASE WHEN r.ratio <= 1 THEN 0 WHEN r.ratio <= 2 THEN 1
                                 WHEN r.ratio <= 4 THEN 2 WHEN r.ratio <= 8 THEN 3 ELSE 4 END
                                 AS level) l
 WHERE c.pose_key = p.pose_key AND c.fps = p.fps
   AND NOT (c.clip_id = p.clip_id AND c.version = p.version AND c.mirrored = p.mirrored
            AND p.first_frame + 1 <= c.first_frame + c.n_frames - 1
            AND c.first_frame + 1 <= p.first_frame + p.n_frames - 1)
 ORDER BY l.level,
          CASE WHEN l.level = 4 THEN c.begin_features <-> p.features
               ELSE modb.approach_cost(c.net_translation, c.future_translation, c.future_heading,
                                       modb.aim_point(%(target)s::float8[],
                                                      (cfg.plan).lookahead_distance),
                                       (cfg.plan).heading_weight)
                    + (cfg.plan).continuity_weight * r.ratio END,
          c.id
 LIMIT 1
"""


def _chunks(conn: psycopg.Connection, query: str, size: int = 20000):
    """Rows of `query` in chunks (a server-side cursor): a million snippets never sit in lists."""
    with conn.transaction(), conn.cursor(name="snapshot", binary=True) as cur:
        cur.execute(query)
        while rows := cur.fetchmany(size):
            yield rows


@dataclass
class Snapshot:
    """Every snippet as stored, in arrays: what (b) and (c) search."""

    ids: np.ndarray
    term: transitions.Terminators  # every stored terminator
    begin: np.ndarray  # each snippet's begin terminator (a row of term)
    end: np.ndarray
    group: np.ndarray  # pose key and rate
    clip: np.ndarray  # clip, version, mirrored as one key
    first: np.ndarray
    n_frames: np.ndarray
    net: np.ndarray  # (n, 3)
    future: np.ndarray  # (n, 3)
    future_heading: np.ndarray
    plan: dict
    trees: dict  # group -> (members, cKDTree of begin features / box half-widths)

    @classmethod
    def load(cls, conn: psycopg.Connection, profile: str) -> Snapshot:
        parts: list[list[np.ndarray]] = [[] for _ in range(6)]
        for rows in _chunks(
            conn,
            "SELECT id, positions, rotations, velocities, angular_velocities, "
            "(SELECT array_agg(cube_ll_coord(features, i) ORDER BY i) FROM generate_series(1, "
            "cube_dim(features)) i) "
            "FROM modb.terminators ORDER BY id",
        ):
            for c, part in enumerate(parts):
                part.append(
                    np.array([r[c] for r in rows], dtype=np.float64 if c == 5 else np.float32)
                )
        term_ids, *columns = (np.concatenate(part) for part in parts)
        term = transitions.Terminators(*columns)
        parts = [[] for _ in range(10)]
        for rows in _chunks(
            conn,
            "SELECT id, begin_terminator, end_terminator, pose_key || '@' || fps, "
            "clip_id || '/' || version || '/' || mirrored, first_frame, n_frames, "
            "net_translation, future_translation, future_heading FROM modb.snippets ORDER BY id",
        ):
            for c, part in enumerate(parts):
                part.append(np.array([r[c] for r in rows], dtype=np.float64 if c >= 7 else None))
        if not parts[0]:
            raise RuntimeError("no snippets stored: `modb load` builds them")
        ids, begin, end, group, clip, first, n_frames, net, future, future_heading = (
            np.concatenate(p) for p in parts
        )
        begin, end = np.searchsorted(term_ids, begin), np.searchsorted(term_ids, end)
        plan = conn.execute("SELECT to_jsonb(p) FROM modb.match_plan(%s) p", [profile]).fetchone()[
            0
        ]
        half = np.asarray(plan["box_half_width"], dtype=np.float64) + transitions.BOX_MARGIN
        trees = {}
        for g in np.unique(group):
            members = np.flatnonzero(group == g)
            trees[g] = (members, cKDTree(term.features[begin[members]] / half))
        return cls(
            ids=ids,
            term=term,
            begin=begin,
            end=end,
            group=group,
            clip=clip,
            first=first,
            n_frames=n_frames,
            net=net,
            future=future,
            future_heading=future_heading,
            plan=plan,
            trees=trees,
        )

    def _objective(self, rows: np.ndarray, target: list[float], ratio: np.ndarray) -> np.ndarray:
        """approach_cost + continuity_weight x ratio as in select_next_snippets ({x, z} targets)."""
        p = self.plan
        t = np.asarray(target, dtype=np.float64)
        reach = np.hypot(t[0], t[-1])
        look = p["lookahead_distance"]
        if look is not None and look < reach:
            t = t * look / reach
        direction = np.arctan2(t[0], t[-1])
        turn = self.future_heading[rows] - direction
        heading = p["heading_weight"] * np.abs(np.arctan2(np.sin(turn), np.cos(turn)))
        cost = [
            np.sqrt((at[rows, 0] - t[0]) ** 2 + (at[rows, 2] - t[1]) ** 2) + heading
            for at in (self.net, self.future)
        ]
        return np.minimum(*cost) + (p["continuity_weight"] or 0) * ratio

    def _best(
        self, prev: int, candidates: np.ndarray, target: list[float]
    ) -> tuple[int, int] | None:
        """The function's pick among snippet rows: lowest level, then objective, then id."""
        overlap = (
            (self.clip[candidates] == self.clip[prev])
            & (self.first[prev] + 1 <= self.first[candidates] + self.n_frames[candidates] - 1)
            & (self.first[candidates] + 1 <= self.first[prev] + self.n_frames[prev] - 1)
        )
        candidates = candidates[~overlap]
        if not len(candidates):
            return None
        ratio = transitions.ratios(
            self.term,
            np.full(len(candidates), self.end[prev]),
            self.begin[candidates],
            self._thresholds(),
        )
        level = np.searchsorted(LEVELS, ratio, side="left")  # ratio <= 1: 0, <= 2: 1, ... > 8: 4
        lowest = level.min()
        if lowest == 4:
            distance = np.linalg.norm(
                self.term.features[self.begin[candidates]] - self.term.features[self.end[prev]],
                axis=1,
            )
            order = np.lexsort((self.ids[candidates], distance))
        else:
            at = level == lowest
            candidates, ratio = candidates[at], ratio[at]
            order = np.lexsort((self.ids[candidates], self._objective(candidates, target, ratio)))
        return int(self.ids[candidates[order[0]]]), int(lowest)

    def _thresholds(self) -> dict:
        p = self.plan
        return {
            k: np.asarray(p[k], dtype=np.float64)
            for k in (
                "position_threshold",
                "angle_threshold",
                "velocity_threshold",
                "angular_velocity_threshold",
            )
        } | {"joints": p["joints"], "norm": p["norm"], "velocity_terms": p["velocity_terms"]}

    def brute_force(self, prev_id: int, target: list[float]) -> tuple[int, int] | None:
        """(b): every snippet of the same pose and rate scored."""
        prev = int(np.searchsorted(self.ids, prev_id))
        return self._best(prev, np.flatnonzero(self.group == self.group[prev]), target)

    def box_scan(self, prev_id: int) -> int:
        """(d): the level-0 box tested against every snippet of the same pose and rate,
        vectorised: the least an in-process scan does (no continuity check, no objective)."""
        prev = int(np.searchsorted(self.ids, prev_id))
        members, _ = self.trees[self.group[prev]]
        half = np.asarray(self.plan["box_half_width"], dtype=np.float64) + transitions.BOX_MARGIN
        point = self.term.features[self.end[prev]]
        inside = np.all(np.abs(self.term.features[self.begin[members]] - point) <= half, axis=1)
        return int(inside.sum())

    def kd_tree(self, prev_id: int, target: list[float]) -> tuple[int, int] | None:
        """(c): candidates from the tree's ball of each level (the box), scored like (b)."""
        prev = int(np.searchsorted(self.ids, prev_id))
        members, tree = self.trees[self.group[prev]]
        half = np.asarray(self.plan["box_half_width"], dtype=np.float64)
        point = self.term.features[self.end[prev]]
        # The tree's scale includes the box margin: a superset of the box.
        for level, scale in enumerate(LEVELS):
            ball = tree.query_ball_point(point / (half + transitions.BOX_MARGIN), r=scale, p=np.inf)
            best = (
                self._best(prev, members[np.asarray(ball, dtype=np.int64)], target)
                if ball
                else None
            )
            if best is not None and best[1] == level:
                return best
        return self._best(prev, members, target)
