"""Whether two sources on one skeleton chain into each other (issue 26, item 5; BENCHMARKS.md "Mixed
pools"): for every 10th snippet of each, the relaxation level at which the other source first gives
a continuation (`modb.select_next_snippet` kept to the other collection, no graph, a goal 2 m
ahead); then seeded courses synthesized on the default path over their common pool: each source's
share of the snippets, the seams between sources and the quality aims.

    .venv/bin/python bench/cross_source.py "host=/var/lib/modb/run dbname=mix4 user=postgres" \
        cmu bandai 60 1,2,3
"""

import sys
from collections import Counter

from modb.bench.synth import seeded_course
from modb.database.connection import connect
from modb.synthesis.avatar import Settings
from modb.synthesis.synth import report, synthesize

LEVELS = """
SELECT n.relax_level, count(*)
  FROM modb.snippets s
  JOIN modb.collections c ON c.id = s.collection_id
  CROSS JOIN LATERAL modb.select_next_snippet(s.id, ARRAY[0, 2.0], NULL, %(other)s, NULL) n
 WHERE c.name = %(one)s AND NOT s.mirrored AND s.first_frame %% 10 = 0
 GROUP BY 1 ORDER BY 1
"""


def main(dsn: str, one: str, other: str, seconds: float, seeds: list[int]) -> None:
    with connect(dsn) as conn:
        for a, b in ((one, other), (other, one)):
            with conn.transaction():
                conn.execute("SET LOCAL modb.graph = 'none'")
                levels = dict(conn.execute(LEVELS, {"one": a, "other": b}).fetchall())
            print(f"{a} -> {b}: snippets by the level of their first continuation in {b}: {levels}")
        source = dict(
            conn.execute(
                "SELECT cl.id, c.name FROM modb.clips cl JOIN modb.collections c "
                "ON c.id = cl.collection_id WHERE c.name = ANY (%s)",
                [[one, other]],
            ).fetchall()
        )
        print("| seed | snippets | " + " | ".join(f"from {n}" for n in (one, other)) + " | seams "
              "between them (their levels) | aims met |")  # fmt: skip
        print("|---|---|---|---|---|---|")
        for seed in seeds:
            goals = seeded_course(seed, n_goals=int(seconds // 5) + 1)
            result = synthesize(conn, goals, seconds, Settings())
            names = [source.get(c.clip_id, "other") for c in result.chain]
            counts = Counter(names)
            crossings = [
                c.relax_level
                for x, y, c in zip(names, names[1:], result.chain[1:], strict=False)
                if x != y
            ]
            aims = report(conn, result).aims
            print(
                f"| {seed} | {len(names)} | "
                + " | ".join(f"{counts[n] / len(names):.0%}" for n in (one, other))
                + f" | {len(crossings)} {crossings} | "
                f"{sum(1 for v in aims.values() if v)} of {len(aims)} |"
            )


if __name__ == "__main__":
    main(
        sys.argv[1],
        sys.argv[2],
        sys.argv[3],
        float(sys.argv[4]),
        [int(s) for s in sys.argv[5].split(",")],
    )
