"""Where select_next_snippet's time goes, stage by stage: modb.explain_selection on seeded requests
(a random previous snippet, a target within 5 m, the default profile) in one session, after a first
pass that reads the block directory and resolves the profile; per call, the levels' stages summed.
`modb bench tail` prints the same table for each database it measures.

    .venv/bin/python bench/selection_stages.py \\
        "host=/var/lib/modb/run dbname=modb_1000000 user=postgres" 200
"""

import sys

import numpy as np
import psycopg

from modb.bench.tail import requests_for, stages


def main(dsn: str, n: int) -> None:
    with psycopg.connect(dsn, autocommit=True) as conn:
        requests = requests_for(conn, n, 7)
    stages(dsn, requests[:1])
    figures = stages(dsn, requests)
    print(f"{n} requests (p50 / p90 / p99)\n")
    print("| stage | p50 / p90 / p99 |\n|---|---|")
    for name, values in figures.items():
        p = np.percentile(values, [50, 90, 99])
        print(f"| {name} | {p[0]:,.2f} / {p[1]:,.2f} / {p[2]:,.2f} |")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 200)
