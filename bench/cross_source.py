"""Whether two sources in one pool chain into each other (BENCHMARKS.md "Mixed pools"): for every
10th snippet of each, the relaxation level at which the other source first gives a continuation
(`modb.select_next_snippet` kept to the other collection, no graph, a goal 2 m ahead); then seeded
60 s courses synthesized over the pool on the user's path (`modb synth --collection POOL`: the
default profile and graph, the graph built first when there is none): each source's share of the
snippets against its share of the pool, the seams between the sources and their levels, and the
quality aims. First, each source's posture and pace read from joint positions
(modb.posture: the same on any rig, kept by retargeting), and the measures whose ranges do not
overlap: what keeps the sources apart whatever the profile.

    .venv/bin/python bench/cross_source.py "host=/var/lib/modb/run dbname=mix16 user=postgres" \
        mixa mixa/cmu16 mixa/bandai 60 1,2,3
"""

import sys
from collections import Counter

from modb.bench.synth import seeded_course
from modb.clips import collection_clips, read_motion
from modb.cli.synth import prepare_default_graph
from modb.database.connection import connect
from modb.posture import apart, posture
from modb.synthesis.avatar import Settings
from modb.synthesis.synth import report, synthesize

LEVELS = """
SELECT n.relax_level, count(*)
  FROM modb.snippets s
  CROSS JOIN LATERAL modb.select_next_snippet(s.id, ARRAY[0, 2.0], %(profile)s, %(other)s, NULL) n
 WHERE s.collection_id = ANY (modb.collection_subtree(%(one)s))
   AND NOT s.mirrored AND s.first_frame %% 10 = 0
 GROUP BY 1 ORDER BY 1
"""
SOURCE_OF_CLIPS = """
SELECT cl.id, %(name)s FROM modb.clips cl
 WHERE cl.collection_id = ANY (modb.collection_subtree(%(name)s))
"""


def continuations(conn, one: str, other: str, profile: str) -> dict[int, int]:
    with conn.transaction():
        conn.execute("SET LOCAL modb.graph = 'none'")
        return dict(
            conn.execute(LEVELS, {"one": one, "other": other, "profile": profile}).fetchall()
        )


def compare_postures(conn, one: str, other: str) -> None:
    measures = {
        name: posture(read_motion(conn, c) for c in collection_clips(conn, name))
        for name in (one, other)
    }
    print(f"| measure: median (p10-p90) | {one} | {other} |\n|---|---|---|")
    for a, b in zip(measures[one], measures[other], strict=True):
        print(f"| {a.name} | {a.text()} | {b.text()} |")
    print(f"ranges apart: {', '.join(apart(measures[one], measures[other])) or 'none'}")


def main(
    dsn: str, pool: str, one: str, other: str, seconds: float, seeds: list[int], profile: str
) -> None:
    with connect(dsn) as conn:
        compare_postures(conn, one, other)
        for a, b in ((one, other), (other, one)):
            levels = continuations(conn, a, b, profile)
            print(f"{a} -> {b}: snippets by the level of their first continuation in {b}: {levels}")
        source = {}
        for name in (one, other):
            source.update(conn.execute(SOURCE_OF_CLIPS, {"name": name}).fetchall())
        pool_counts = Counter(
            source.get(clip_id, "other")
            for (clip_id,) in conn.execute(
                "SELECT clip_id FROM modb.snippets WHERE NOT mirrored "
                "AND collection_id = ANY (modb.collection_subtree(%s))",
                [pool],
            )
        )
        total = sum(pool_counts.values())
        print(
            f"pool {pool}: "
            + ", ".join(
                f"{n} {pool_counts[n] / total:.1%} of {total:,} snippets" for n in (one, other)
            )
        )
        settings = Settings(profile=profile, collection=pool)
        prepare_default_graph(conn, settings, None, quiet=True)
        print(
            "| seed | snippets | " + " | ".join(f"from {n}" for n in (one, other))
            + " | seams between them (their levels) | aims met | pose jump max (sources p99.9) |"
        )  # fmt: skip
        print("|---|---|---|---|---|---|---|")
        for seed in seeds:
            goals = seeded_course(seed, n_goals=int(seconds // 5) + 1)
            result = synthesize(conn, goals, seconds, settings)
            names = [source.get(c.clip_id, "other") for c in result.chain]
            counts = Counter(names)
            crossings = [
                c.relax_level
                for x, y, c in zip(names, names[1:], result.chain[1:], strict=False)
                if x != y
            ]
            r = report(conn, result)
            failed = [name for name, ok in r.aims.items() if ok is False]
            print(
                f"| {seed} | {len(names)} | "
                + " | ".join(f"{counts[n] / len(names):.0%}" for n in (one, other))
                + f" | {len(crossings)} {crossings} | "
                f"{sum(1 for v in r.aims.values() if v)} of {len(r.aims)}"
                + (f" (missed: {', '.join(failed)})" if failed else "")
                + f" | {100 * r.pose_jump_max:.1f} cm ({100 * r.natural_pose_jump_p999:.1f}) |"
            )


if __name__ == "__main__":
    main(
        sys.argv[1],
        sys.argv[2],
        sys.argv[3],
        sys.argv[4],
        float(sys.argv[5]),
        [int(s) for s in sys.argv[6].split(",")],
        sys.argv[7] if len(sys.argv) > 7 else "default",
    )
