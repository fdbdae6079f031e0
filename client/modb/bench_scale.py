"""`modb bench scale` (make bench): select_next_snippet at several database sizes, beside in the same run
(a) the paper's formulation: one flat query scoring every snippet (no box, so no index: a sequential scan),
    its continuity ratio by modb.continuity_ratio, the C function the tests tie to 0.6.0's arithmetic over
    the terminator columns to the last bit (that arithmetic in SQL is about 4.5x slower: the ratio to (a)
    here is the conservative one) (the same rows as the function),
(b) a vectorised numpy brute force in this process over the same stored terminators (the same rows),
(c) scipy's cKDTree in this process (the box as a Chebyshev ball of the scaled features) plus one
    `SELECT 1` round trip: what an in-memory index in the client costs (the same rows).
The index is rebuilt (REINDEX, timed) before the queries, so every size is measured on a fresh build.
Also: candidates examined per query (modb.candidates_examined), the GiST index's build time and size,
bytes per snippet, and throughput with pgbench and the shipped script at 1, 2 and 8 clients.
"""
from __future__ import annotations

import os
import re
import statistics
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import psycopg

from modb_kernel import transitions

from .bench_resampled import add_resampled_clips, resampled_snippets
from .connection import configure_for_selection, connect, selection_pgoptions

PGBENCH = "/usr/lib/postgresql/15/bin/pgbench"  # postgresql-15's own (Debian keeps it off PATH)
PGBENCH_SCRIPT = Path(__file__).resolve().parents[2] / "bench" / "select_next_snippet.pgbench"
FUNCTION = "SELECT snippet_id, relax_level FROM modb.select_next_snippet(%s, %s, %s)"
LEVELS = (1.0, 2.0, 4.0, 8.0)  # relaxation levels 0-3 scale every threshold; level 4 takes the nearest

# (a): every snippet scored; level and order as select_next_snippets, without its index.
FLAT = """
WITH cfg AS MATERIALIZED (SELECT modb.match_plan(%(profile)s) AS plan),
p AS MATERIALIZED (
    SELECT t AS term, t.features, s.pose_key, s.fps, s.clip_id, s.version, s.mirrored, s.first_frame, s.n_frames
      FROM modb.snippets s JOIN modb.terminators t ON t.id = s.end_terminator WHERE s.id = %(prev)s)
SELECT c.id, l.level
  FROM cfg, p, modb.snippets c JOIN modb.terminators b ON b.id = c.begin_terminator
 CROSS JOIN LATERAL (SELECT modb.continuity_ratio(p.term, b, cfg.plan) AS ratio) r
 CROSS JOIN LATERAL (SELECT CASE WHEN r.ratio <= 1 THEN 0 WHEN r.ratio <= 2 THEN 1 WHEN r.ratio <= 4 THEN 2
                                 WHEN r.ratio <= 8 THEN 3 ELSE 4 END AS level) l
 WHERE c.pose_key = p.pose_key AND c.fps = p.fps
   AND NOT (c.clip_id = p.clip_id AND c.version = p.version AND c.mirrored = p.mirrored
            AND p.first_frame + 1 <= c.first_frame + c.n_frames - 1 AND c.first_frame + 1 <= p.first_frame + p.n_frames - 1)
 ORDER BY l.level,
          CASE WHEN l.level = 4 THEN c.begin_features <-> p.features
               ELSE modb.approach_cost(c.net_translation, c.future_translation, c.future_heading,
                                       modb.aim_point(%(target)s::float8[], (cfg.plan).lookahead_distance),
                                       (cfg.plan).heading_weight)
                    + (cfg.plan).continuity_weight * r.ratio END,
          c.id
 LIMIT 1
"""


def _chunks(conn: psycopg.Connection, query: str, size: int = 20000):
    """The rows of `query` in chunks (a server-side cursor), so a million snippets never sit in Python lists."""
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
        from scipy.spatial import cKDTree

        parts: list[list[np.ndarray]] = [[] for _ in range(6)]
        for rows in _chunks(conn, "SELECT id, positions, rotations, velocities, angular_velocities, "
                                  "(SELECT array_agg(cube_ll_coord(features, i) ORDER BY i) FROM generate_series(1, cube_dim(features)) i) "
                                  "FROM modb.terminators ORDER BY id"):
            for c, part in enumerate(parts):
                part.append(np.array([r[c] for r in rows], dtype=np.float64 if c == 5 else np.float32))
        term_ids, *columns = (np.concatenate(part) for part in parts)
        term = transitions.Terminators(*columns)
        parts = [[] for _ in range(10)]
        for rows in _chunks(conn, "SELECT id, begin_terminator, end_terminator, pose_key || '@' || fps, "
                                  "clip_id || '/' || version || '/' || mirrored, first_frame, n_frames, "
                                  "net_translation, future_translation, future_heading FROM modb.snippets ORDER BY id"):
            for c, part in enumerate(parts):
                part.append(np.array([r[c] for r in rows], dtype=np.float64 if c >= 7 else None))
        if not parts[0]:
            raise RuntimeError("no snippets stored: `modb load` builds them")
        ids, begin, end, group, clip, first, n_frames, net, future, future_heading = (np.concatenate(p) for p in parts)
        begin, end = np.searchsorted(term_ids, begin), np.searchsorted(term_ids, end)
        plan = conn.execute("SELECT to_jsonb(p) FROM modb.match_plan(%s) p", [profile]).fetchone()[0]
        half = np.asarray(plan["box_half_width"], dtype=np.float64) + transitions.BOX_MARGIN
        trees = {}
        for g in np.unique(group):
            members = np.flatnonzero(group == g)
            trees[g] = (members, cKDTree(term.features[begin[members]] / half))
        return cls(ids=ids, term=term, begin=begin, end=end, group=group, clip=clip, first=first, n_frames=n_frames,
                   net=net, future=future, future_heading=future_heading, plan=plan, trees=trees)

    def _objective(self, rows: np.ndarray, target: list[float], ratio: np.ndarray) -> np.ndarray:
        """approach_cost + continuity_weight x ratio, as select_next_snippets computes it ({x, z} targets)."""
        p = self.plan
        t = np.asarray(target, dtype=np.float64)
        reach = np.hypot(t[0], t[-1])
        look = p["lookahead_distance"]
        if look is not None and look < reach:
            t = t * look / reach
        direction = np.arctan2(t[0], t[-1])
        turn = self.future_heading[rows] - direction
        heading = p["heading_weight"] * np.abs(np.arctan2(np.sin(turn), np.cos(turn)))
        cost = [np.sqrt((at[rows, 0] - t[0]) ** 2 + (at[rows, 2] - t[1]) ** 2) + heading for at in (self.net, self.future)]
        return np.minimum(*cost) + (p["continuity_weight"] or 0) * ratio

    def _best(self, prev: int, candidates: np.ndarray, target: list[float]) -> tuple[int, int] | None:
        """The function's choice among candidates (snippet rows): lowest level, then objective, then id."""
        overlap = ((self.clip[candidates] == self.clip[prev])
                   & (self.first[prev] + 1 <= self.first[candidates] + self.n_frames[candidates] - 1)
                   & (self.first[candidates] + 1 <= self.first[prev] + self.n_frames[prev] - 1))
        candidates = candidates[~overlap]
        if not len(candidates):
            return None
        ratio = transitions.ratios(self.term, np.full(len(candidates), self.end[prev]), self.begin[candidates],
                                  self._thresholds())
        level = np.searchsorted(LEVELS, ratio, side="left")  # ratio <= 1: 0, <= 2: 1, ... > 8: 4
        lowest = level.min()
        if lowest == 4:
            distance = np.linalg.norm(self.term.features[self.begin[candidates]] - self.term.features[self.end[prev]], axis=1)
            order = np.lexsort((self.ids[candidates], distance))
        else:
            at = level == lowest
            candidates, ratio = candidates[at], ratio[at]
            order = np.lexsort((self.ids[candidates], self._objective(candidates, target, ratio)))
        return int(self.ids[candidates[order[0]]]), int(lowest)

    def _thresholds(self) -> dict:
        p = self.plan
        return {k: np.asarray(p[k], dtype=np.float64) for k in
                ("position_threshold", "angle_threshold", "velocity_threshold", "angular_velocity_threshold")} | {
                "joints": p["joints"], "norm": p["norm"], "velocity_terms": p["velocity_terms"]}

    def brute_force(self, prev_id: int, target: list[float]) -> tuple[int, int] | None:
        """(b): every snippet of the same pose and rate scored."""
        prev = int(np.searchsorted(self.ids, prev_id))
        return self._best(prev, np.flatnonzero(self.group == self.group[prev]), target)

    def kd_tree(self, prev_id: int, target: list[float]) -> tuple[int, int] | None:
        """(c): candidates from the tree's ball of each level (the box), scored like (b)."""
        prev = int(np.searchsorted(self.ids, prev_id))
        members, tree = self.trees[self.group[prev]]
        half = np.asarray(self.plan["box_half_width"], dtype=np.float64)
        point = self.term.features[self.end[prev]]
        for level, scale in enumerate(LEVELS):  # the tree's scale includes the box margin: a superset of the box
            ball = tree.query_ball_point(point / (half + transitions.BOX_MARGIN), r=scale, p=np.inf)
            best = self._best(prev, members[np.asarray(ball, dtype=np.int64)], target) if ball else None
            if best is not None and best[1] == level:
                return best
        return self._best(prev, members, target)


def _with_dbname(dsn: str, name: str) -> str:
    return psycopg.conninfo.make_conninfo(dsn, dbname=name)


def sized_database(dsn: str, size: int, seed: int, progress=print) -> str:
    """A copy of the database at `dsn` (made once, kept for the next run) with `size` snippets, about; its
    conninfo. Smaller: whole clips drawn in a seeded order, compacted as after a load of that size. Larger:
    speed-resampled copies of its clips added (bench_resampled; an interrupted run resumes)."""
    source = psycopg.conninfo.conninfo_to_dict(dsn).get("dbname") or "modb"
    name = f"{source}_{size}"
    with psycopg.connect(_with_dbname(dsn, "postgres"), autocommit=True) as admin:
        made = admin.execute("SELECT 1 FROM pg_database WHERE datname = %s", [name]).fetchone() is None
        if made:
            admin.execute(f'CREATE DATABASE "{name}" TEMPLATE "{source}"')  # needs no other session on the source
    with connect(_with_dbname(dsn, name)) as conn:
        clips = conn.execute("SELECT clip_id, count(*) FROM modb.snippets GROUP BY clip_id ORDER BY clip_id").fetchall()
        if size > sum(n for _, n in clips) and (made or resampled_snippets(conn)):  # made now, or an interrupted run's
            progress(f"  adding speed-resampled copies of the clips up to {size:,} snippets (once)")
            add_resampled_clips(conn, size, seed, progress)
            conn.execute("VACUUM ANALYZE modb.snippets, modb.terminators")
        elif made:
            order = np.random.default_rng(seed).permutation(len(clips))
            kept, total = set(), 0
            for k in order:
                if total + clips[k][1] <= size:
                    kept.add(clips[k][0])
                    total += clips[k][1]
            conn.execute("DELETE FROM modb.clips WHERE NOT id = ANY (%s)", [sorted(kept)])
            conn.execute("VACUUM (FULL, ANALYZE) modb.snippets")
            conn.execute("VACUUM (FULL, ANALYZE) modb.terminators")
    return _with_dbname(dsn, name)


def pgbench(dsn: str, clients: int, seconds: int) -> float:
    """Selections per second: the shipped script (a random prev and target per call), prepared, generic
    plans, no JIT."""
    with psycopg.connect(dsn) as conn:
        low, high = conn.execute("SELECT min(id), max(id) FROM modb.snippets").fetchone()
    env = {**os.environ, "PGOPTIONS": selection_pgoptions()}
    out = subprocess.run([PGBENCH, "-n", "-M", "prepared", "-T", str(seconds), "-c", str(clients),
                          "-j", str(min(clients, 2)), "-f", str(PGBENCH_SCRIPT), "-D", f"low={low}", "-D", f"high={high}",
                          dsn],  # pgbench takes a conninfo string where a database name goes
                         capture_output=True, text=True, env=env)
    if out.returncode != 0:
        raise RuntimeError(f"pgbench failed: {out.stderr.strip()}")
    out = out.stdout
    return float(re.search(r"tps = ([0-9.]+) \(without initial connection time\)", out).group(1))


def bench_database(dsn: str, queries: int, baseline_queries: int, seed: int, profile: str,
                   pgbench_seconds: int, progress=print) -> dict:
    """Every figure of one database (see the module's docstring)."""
    with psycopg.connect(dsn, autocommit=True) as conn:
        configure_for_selection(conn)
        progress("  reading the snippets into memory (for numpy and the k-d tree)")
        t = time.perf_counter()
        snap = Snapshot.load(conn, profile)
        load_s = time.perf_counter() - t
        t = time.perf_counter()
        conn.execute("REINDEX INDEX modb.snippets_begin_features_idx")
        index_s = time.perf_counter() - t
        rng = np.random.default_rng(seed)
        requests = [(int(rng.choice(snap.ids)), [float(v) for v in rng.uniform(-5, 5, size=2)]) for _ in range(queries)]
        conn.execute(FUNCTION, [requests[0][0], requests[0][1], profile], prepare=True).fetchone()  # plans once
        out = {k: [] for k in ("function_ms", "flat_ms", "numpy_ms", "kdtree_ms", "candidates", "levels")}
        same_flat = same_numpy = same_kdtree = 0
        progress(f"  {queries} seeded queries ({baseline_queries} also by the flat query)")
        for k, (prev, target) in enumerate(requests):
            t = time.perf_counter()
            chosen = conn.execute(FUNCTION, [prev, target, profile], prepare=True).fetchone()
            out["function_ms"].append((time.perf_counter() - t) * 1000)
            out["levels"].append(chosen[1])
            out["candidates"].append(conn.execute("SELECT modb.candidates_examined(%s, %s, %s)",
                                                  [prev, chosen[1], profile], prepare=True).fetchone()[0])
            t = time.perf_counter()
            mine = snap.brute_force(prev, target)
            out["numpy_ms"].append((time.perf_counter() - t) * 1000)
            same_numpy += mine == tuple(chosen)
            t = time.perf_counter()
            tree_choice = snap.kd_tree(prev, target)
            conn.execute("SELECT 1", prepare=True).fetchone()
            out["kdtree_ms"].append((time.perf_counter() - t) * 1000)
            same_kdtree += tree_choice == tuple(chosen)
            if k < baseline_queries:
                t = time.perf_counter()
                flat = conn.execute(FLAT, {"prev": prev, "target": target, "profile": profile}, prepare=True).fetchone()
                out["flat_ms"].append((time.perf_counter() - t) * 1000)
                same_flat += tuple(flat) == tuple(chosen)
        resampled = resampled_snippets(conn)
        index_bytes, table_bytes = conn.execute(
            "SELECT pg_relation_size('modb.snippets_begin_features_idx'), sum(pg_total_relation_size(c)) "
            "FROM unnest(ARRAY['modb.snippets', 'modb.terminators', 'modb.snippet_sources']::regclass[]) AS c").fetchone()
    progress("  pgbench")
    tps = {c: pgbench(dsn, c, pgbench_seconds) for c in (1, 2, 8)}
    return {**out, "snippets": len(snap.ids), "resampled": resampled, "same_flat": same_flat, "same_numpy": same_numpy, "same_kdtree": same_kdtree,
            "baseline_queries": baseline_queries, "queries": queries, "index_s": index_s, "index_bytes": index_bytes,
            "bytes_per_snippet": table_bytes / len(snap.ids), "snapshot_s": load_s, "tps": tps}


def report(name: str, r: dict) -> str:
    def row(label: str, ms: list[float]) -> str:
        return f"| {label} | {statistics.median(ms):.2f} | {np.percentile(ms, 99):.2f} |"

    n = r["baseline_queries"]
    flat_ratio = statistics.median(a / b for a, b in zip(r["flat_ms"], r["function_ms"][:n])) if n else float("nan")
    kd_ratio = statistics.median(a / b for a, b in zip(r["function_ms"], r["kdtree_ms"]))
    np_ratio = statistics.median(a / b for a, b in zip(r["function_ms"], r["numpy_ms"]))
    c = r["candidates"]
    levels = {lvl: r["levels"].count(lvl) for lvl in sorted(set(r["levels"]))}
    return "\n".join([
        f"### {name}: {r['snippets']:,} snippets",
        "",
        *([f"{r['resampled']:,} of them are speed-resampled copies of the real clips (bench_resampled.py).", ""]
          if r["resampled"] else []),
        "| | p50 ms | p99 ms |",
        "|---|---|---|",
        row("select_next_snippet (prepared, generic plan)", r["function_ms"]),
        row(f"(a) flat query, sequential scan ({n} of the queries)", r["flat_ms"]) if n else "| (a) | - | - |",
        row("(b) numpy brute force, in process", r["numpy_ms"]),
        row("(c) cKDTree in process + SELECT 1", r["kdtree_ms"]),
        "",
        f"- Per query, median: (a) / function {flat_ratio:.1f}x; function / (b) {np_ratio:.2f}x; "
        f"function / (c) {kd_ratio:.2f}x.",
        f"- Same snippet and level as the function: (a) {r['same_flat']}/{n}, (b) {r['same_numpy']}/{r['queries']}, "
        f"(c) {r['same_kdtree']}/{r['queries']}.",
        f"- Candidates examined: p50 {np.percentile(c, 50):.0f}, p90 {np.percentile(c, 90):.0f}, "
        f"p99 {np.percentile(c, 99):.0f}, max {max(c)}; relaxation levels {levels}.",
        f"- GiST index: {r['index_bytes'] / 2**20:.1f} MiB, rebuilt in {r['index_s']:.1f} s; "
        f"{r['bytes_per_snippet']:,.0f} bytes per snippet (snippets, terminators, sources and their indexes).",
        "- pgbench (shipped script, prepared): " + ", ".join(f"{k} client{'s' if k > 1 else ''} {v:,.0f}/s"
                                                            for k, v in r["tps"].items()) + ".",
    ])


def bench_scale(dsn: str, sizes: list[int | None], queries: int, baseline_queries: int, seed: int, profile: str,
                pgbench_seconds: int, progress=print) -> list[tuple[str, dict]]:
    """Every size (None: the database at `dsn` itself, all it holds), smallest first."""
    out = []
    for size in sizes:
        where = dsn if size is None else sized_database(dsn, size, seed, progress)
        name = "all the data" if size is None else f"about {size:,}"
        progress(f"{name}:")
        out.append((name, bench_database(where, queries, baseline_queries, seed, profile, pgbench_seconds, progress)))
    return out
