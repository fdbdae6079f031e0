"""Packing every snippet block again while readers select, on the primary and on a hot standby (the
step an update's WARNING asks for, issue 40's procedure): the packing's time and WAL, and each
reader's calls, errors and latency while it ran.

    .venv/bin/python bench/pack_beside_readers.py PRIMARY_DSN STANDBY_DSN

Each reader calls select_next_snippet every 50 ms from seeded previous snippets and goals, from a
few seconds before the packing until a few seconds after it (the standby's reader waits for the
replayed blocks as its snapshots reach them).
"""

import sys
import threading
import time

import numpy as np
import psycopg

QUERY = "SELECT snippet_id FROM modb.select_next_snippet(%s, %s)"
INTERVAL_SECONDS = 0.05
MARGIN_SECONDS = 5.0


def reader(dsn: str, ids: list[int], seed: int, stop: threading.Event, out: dict) -> None:
    rng = np.random.default_rng(seed)
    times, errors = [], []
    with psycopg.connect(dsn, autocommit=True) as conn:
        while not stop.is_set():
            prev = int(rng.choice(ids))
            angle, distance = rng.uniform(-np.pi, np.pi), rng.uniform(1, 5)
            target = [float(distance * np.sin(angle)), float(distance * np.cos(angle))]
            t = time.perf_counter()
            try:
                conn.execute(QUERY, [prev, target]).fetchone()
                times.append((time.perf_counter() - t) * 1000)
            except psycopg.Error as e:
                errors.append(str(e).splitlines()[0])
            time.sleep(INTERVAL_SECONDS)
    out.update(times=np.array(times), errors=errors)


def main() -> None:
    primary, standby = sys.argv[1], sys.argv[2]
    with psycopg.connect(primary, autocommit=True) as conn:
        ids = [r[0] for r in conn.execute("SELECT id FROM modb.snippets TABLESAMPLE SYSTEM (2)")]
    stop = threading.Event()
    results = {"primary": {}, "standby": {}}
    threads = [
        threading.Thread(target=reader, args=(dsn, ids, seed, stop, results[name]))
        for seed, (name, dsn) in enumerate((("primary", primary), ("standby", standby)))
    ]
    for t in threads:
        t.start()
    time.sleep(MARGIN_SECONDS)
    with psycopg.connect(primary, autocommit=True) as conn:
        conn.add_notice_handler(lambda d: None)
        (before,) = conn.execute("SELECT pg_current_wal_lsn()").fetchone()
        t = time.perf_counter()
        packed = conn.execute("SELECT count(*) FROM modb.pack_snippet_blocks(0)").fetchone()[0]
        seconds = time.perf_counter() - t
        (wal,) = conn.execute(
            "SELECT pg_size_pretty(pg_wal_lsn_diff(pg_current_wal_lsn(), %s))", [before]
        ).fetchone()
    time.sleep(MARGIN_SECONDS)
    stop.set()
    for t in threads:
        t.join()
    print(f"packing: {seconds:.1f} s, {wal} of WAL ({packed} poses and rates)")
    for name, r in results.items():
        ms = r["times"]
        print(
            f"{name}: {len(ms)} calls, {len(r['errors'])} errors, p50 {np.median(ms):.1f} ms, "
            f"p99 {np.percentile(ms, 99):.1f} ms, max {ms.max():.1f} ms"
            + (f"; first error: {r['errors'][0]}" if r["errors"] else "")
        )


if __name__ == "__main__":
    main()
