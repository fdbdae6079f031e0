"""select_next_snippet before and after 10% more data arrives through the loader's own path, and
then after every snippet block is packed again: does a database that only grew by loads answer as
fast as a repacked one? (Blocks are appended in the loaders' transactions, and a load under a fifth
of a pose leaves them unpacked: nothing to REINDEX or VACUUM by hand.) It works on a copy
(`CREATE DATABASE ... TEMPLATE`), so the source stays as it is. Each phase runs the same seeded
queries from psycopg with the server's default settings and reports p50, p99 and the median
per-query ratio to the first phase, and the memory of a session's block directory
(pg_backend_memory_contexts).

    .venv/bin/python bench/after_a_load.py "host=/var/lib/modb/run dbname=modb_100000" 300
"""

import statistics
import sys
import time

import numpy as np
import psycopg

from modb.bench.resampled import add_resampled_clips
from modb.database.connection import connect

QUERY = "SELECT snippet_id, relax_level FROM modb.select_next_snippet(%s, %s)"
DIRECTORY = (
    "SELECT sum(total_bytes) FROM pg_backend_memory_contexts WHERE name = 'modb block directory'"
)


def phase(dsn: str, requests: list) -> tuple[list[float], list, int]:
    with psycopg.connect(dsn, autocommit=True) as conn:
        conn.execute(QUERY, requests[0]).fetchone()  # the directory, read once
        times, chosen = [], []
        for prev, target in requests:
            t = time.perf_counter()
            chosen.append(conn.execute(QUERY, [prev, target]).fetchone())
            times.append((time.perf_counter() - t) * 1000)
        (directory,) = conn.execute(DIRECTORY).fetchone()
    return times, chosen, int(directory or 0)


def main(source: str, queries: int) -> None:
    copy = psycopg.conninfo.conninfo_to_dict(source)
    name = f"{copy.get('dbname', 'modb')}_after_a_load"
    admin_dsn = psycopg.conninfo.make_conninfo(source, dbname="postgres")
    with psycopg.connect(admin_dsn, autocommit=True) as admin:
        admin.execute(f'DROP DATABASE IF EXISTS "{name}"')
        admin.execute(f'CREATE DATABASE "{name}" TEMPLATE "{copy.get("dbname", "modb")}"')
    dsn = psycopg.conninfo.make_conninfo(source, dbname=name)
    with psycopg.connect(dsn, autocommit=True) as conn:
        ids = [r[0] for r in conn.execute("SELECT id FROM modb.snippets ORDER BY id")]
        rng = np.random.default_rng(7)
        requests = [
            (int(rng.choice(ids)), [float(v) for v in rng.uniform(-5, 5, size=2)])
            for _ in range(queries)
        ]
        before = len(ids)
    results = {"as loaded": phase(dsn, requests)}
    with connect(dsn) as conn:  # modb's: arrays as numpy, as the loader reads them
        t = time.perf_counter()
        after = add_resampled_clips(conn, int(before * 1.1), seed=3)
        load_s = time.perf_counter() - t
    results["10% more, loaded"] = phase(dsn, requests)
    with psycopg.connect(dsn, autocommit=True) as conn:
        conn.execute("SELECT * FROM modb.pack_snippet_blocks(0)")  # every pose packed again
    results["blocks repacked"] = phase(dsn, requests)
    with psycopg.connect(admin_dsn, autocommit=True) as admin:
        admin.execute(f'DROP DATABASE "{name}" WITH (FORCE)')
    base = results["as loaded"][0]
    print(
        f"{before:,} snippets, then {after:,} after {load_s:.0f} s of loading; {queries} queries\n"
    )
    print("| phase | p50 ms | p99 ms | median ratio to the first | directory |")
    print("|---|---|---|---|---|")
    for label, (times, _, directory) in results.items():
        ratio = statistics.median(a / b for a, b in zip(times, base))
        print(
            f"| {label} | {statistics.median(times):.3f} | {np.percentile(times, 99):.3f} | "
            f"{ratio:.2f}x | {directory / 2**20:.2f} MiB |"
        )
    loaded, repacked = results["10% more, loaded"][1], results["blocks repacked"][1]
    same = sum(a == b for a, b in zip(loaded, repacked))
    print(f"\nSame choice after the load and after the repacking: {same}/{queries}.")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 300)
