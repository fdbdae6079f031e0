"""Each synthesis-step kind timed on the same seeded requests (psycopg, prepared, server defaults):
what BENCHMARKS.md's A/B of two builds of modb.so runs once per build.

    .venv/bin/python bench/selection_kinds.py DSN N [SEED] [KIND,...]
    .venv/bin/python bench/selection_kinds.py DSN N SEED start COLLECTION GRAPH

Previous snippets are drawn uniformly from the database, goals 1-5 m away in any direction.
Kinds: plain (select_next_snippet_world), rest (select_synthesis_step resting: coming to rest),
off (select_snippet_ending walking: setting off), step (select_synthesis_step, not resting: a
standing previous snippet sets off, any other walks), and start (no previous snippet, goals
within 8 m, in COLLECTION with SET modb.graph = GRAPH). Prints p50, p90, p99, max and mean in
ms per kind; the p99 of a few hundred is their few slowest, hence the mean. Each kind is timed as
`modb bench tail` times its kinds (modb.bench.tail.time_run).
"""

import sys

import numpy as np
import psycopg

from modb.bench.tail import KindRun, time_run

ARGS = "%s, '{0,0,0}', 0, %s, 'default', NULL, NULL"
QUERIES = {
    "plain": f"SELECT snippet_id FROM modb.select_next_snippet_world({ARGS})",
    "rest": f"SELECT snippet_id FROM modb.select_synthesis_step({ARGS}, true)",
    "off": f"SELECT snippet_id FROM modb.select_snippet_ending({ARGS}, false)",
    "step": f"SELECT snippet_id FROM modb.select_synthesis_step({ARGS}, false)",
}
START = "SELECT count(*) FROM modb.select_next_snippets(NULL, %s::float8[], 1, 'default', %s)"


def report(kind: str, ms: list[float]) -> None:
    p50, p90, p99 = np.percentile(ms, [50, 90, 99])
    print(
        f"{kind:6s} p50 {p50:7.2f} p90 {p90:7.2f} p99 {p99:7.2f} max {max(ms):7.2f} "
        f"mean {np.mean(ms):7.2f}",
        flush=True,
    )


def main() -> None:
    dsn, n = sys.argv[1], int(sys.argv[2])
    seed = int(sys.argv[3]) if len(sys.argv) > 3 else 1
    kinds = sys.argv[4].split(",") if len(sys.argv) > 4 else list(QUERIES)
    rng = np.random.default_rng(seed)
    none_excluded = [[]] * n
    with psycopg.connect(dsn, autocommit=True) as conn:
        if kinds == ["start"]:
            collection, graph = sys.argv[5], sys.argv[6]
            goals = [(None, [float(v) for v in rng.uniform(-8, 8, 2)]) for _ in range(n)]
            run = KindRun(
                "start", START, lambda _, goal, __: [goal, collection], {"modb.graph": graph}, goals
            )
            report("start", time_run(conn, run, none_excluded))
            return
        ids = np.array([r[0] for r in conn.execute("SELECT id FROM modb.snippets ORDER BY id")])
        requests = []
        for _ in range(n):
            angle, distance = rng.uniform(-np.pi, np.pi), rng.uniform(1, 5)
            goal = [float(distance * np.sin(angle)), 0.0, float(distance * np.cos(angle))]
            requests.append((int(rng.choice(ids)), goal))
        for kind in kinds:
            run = KindRun(kind, QUERIES[kind], lambda prev, goal, _: [prev, goal], {}, requests)
            report(kind, time_run(conn, run, none_excluded))


if __name__ == "__main__":
    main()
