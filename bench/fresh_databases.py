"""What a test's fresh database costs: a copy of the run's template database
(tests/support/shared.py) against CREATE DATABASE + CREATE EXTENSION modb, alternated in one run on
one throwaway cluster of the tests' own; medians and p99 of `rounds` each, and their ratio.

    .venv/bin/python bench/fresh_databases.py [rounds]
"""

import os
import sys
import time
from pathlib import Path

import numpy as np
import psycopg

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
os.environ.pop("MODB_TEST_RUN", None)
from support import shared  # noqa: E402


def timed(f) -> float:
    t0 = time.perf_counter()
    f()
    return time.perf_counter() - t0


def plain(cluster, name: str) -> None:
    with psycopg.connect(cluster.dsn("postgres"), autocommit=True) as admin:
        admin.execute(f'CREATE DATABASE "{name}"')
    with psycopg.connect(cluster.dsn(name), autocommit=True) as conn:
        conn.execute("CREATE EXTENSION modb CASCADE")


def main(rounds: int = 20) -> None:
    folder = shared.start_run()
    try:
        cluster = shared.cluster()
        copy, fresh = [], []
        for i in range(rounds):
            copy.append(timed(lambda: shared.create_database(cluster, f"copy{i}")))
            fresh.append(timed(lambda: plain(cluster, f"fresh{i}")))
            shared.drop_database(cluster, f"copy{i}")
            shared.drop_database(cluster, f"fresh{i}")
        for what, ts in (
            ("CREATE DATABASE + CREATE EXTENSION (baseline)", fresh),
            ("copy of the template", copy),
        ):
            ms = np.array(ts) * 1000
            print(
                f"{what}: p50 {np.median(ms):.0f} ms, p99 {np.percentile(ms, 99):.0f} ms, "
                f"{np.median(fresh) / np.median(ts):.2f}x"
            )
    finally:
        shared.end_run(folder)


if __name__ == "__main__":
    main(*map(int, sys.argv[1:]))
