"""Where select_next_snippet's time goes, stage by stage: modb.explain_selection on seeded requests
(a random previous snippet, a target within 5 m, the default profile) in one session, twice (the
second pass has the block directory and the profile cached), the levels' stages summed per call.

    .venv/bin/python bench/selection_stages.py \
        "host=/var/lib/modb/run dbname=modb_1000000 user=postgres" 200
"""

import re
import sys

import numpy as np
import psycopg

LEVEL = re.compile(
    r"(\d+) blocks met it, (\d+) candidates from their codes \(([\d.]+) ms\), (\d+) read .*"
    r"\(([\d.]+) ms\)$"
)


def main(dsn: str, n: int) -> None:
    rng = np.random.default_rng(7)
    with psycopg.connect(dsn, autocommit=True) as conn:
        ids = [r[0] for r in conn.execute("SELECT id FROM modb.snippets")]
        requests = [
            (int(rng.choice(ids)), [float(v) for v in rng.uniform(-5, 5, 2)]) for _ in range(n)
        ]
        for _ in range(2):
            figures: dict[str, list[float]] = {
                k: []
                for k in (
                    "blocks met",
                    "candidates",
                    "rows read",
                    "block search ms",
                    "reading and checking ms",
                    "whole call ms",
                )
            }
            for prev, target in requests:
                lines = [
                    r[0]
                    for r in conn.execute(
                        "SELECT * FROM modb.explain_selection(%s, %s)", [prev, target]
                    )
                ]
                sums = np.zeros(5)
                for line in lines:
                    m = LEVEL.search(line)
                    if m:
                        sums += [float(g) for g in m.groups()]
                figures["blocks met"].append(sums[0])
                figures["candidates"].append(sums[1])
                figures["block search ms"].append(sums[2])
                figures["rows read"].append(sums[3])
                figures["reading and checking ms"].append(sums[4])
                figures["whole call ms"].append(
                    float(re.search(r"rows in ([\d.]+) ms", lines[0])[1])
                )
    print(f"{n} requests, second pass (p50 / p90 / p99)\n")
    print("| stage | p50 / p90 / p99 |\n|---|---|")
    for name, values in figures.items():
        p = np.percentile(values, [50, 90, 99])
        print(f"| {name} | {p[0]:,.2f} / {p[1]:,.2f} / {p[2]:,.2f} |")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 200)
