"""What every page asks of motion models, in two databases of the same models under two extension
versions (one kept at 0.25.0, a copy updated to 0.26.0), measured alternately in this process:

- listing every version with its staleness (`modb model list`, GET /api/motion-models) and showing
  one (`modb model show`), with NAMES x VERSIONS versions of a CMU 16 step model stored;
- how long a statement timeout of 1 s takes to stop `modb.synthesize_from_models` (a 600 s walk);
- a backend's resident memory over 20 calls of a 30 s walk on one connection.

    .venv/bin/python bench/model_service.py "host=... dbname=old" "host=... dbname=new" [ROUNDS]

Make the databases with bench/model_service.py --make CLUSTER_DSN (CMU 16 loaded without snippets,
its steps annotated, the step models and their graph `walk`, 20 names x 5 versions of copies).
"""

from __future__ import annotations

import statistics
import sys
import time

import numpy as np
import psycopg

from modb.models.store import brief, listing, load

NAMES, VERSIONS = 20, 5
OLD_ROUNDS = 1
# what the listing read before 0.26.0 (the counts from the documents): the old database's query
OLD_LISTING = """
SELECT s.id, s.name, s.version, s.latest, s.collection, s.primitive, s.skeleton_id,
       s.created_at::text, s.stale, jsonb_array_length(m.data->'inputs') AS examples,
       jsonb_array_length(m.data->'mixture'->'weights') AS components,
       m.meta ? 'tree' AS has_tree
  FROM modb.model_status s JOIN modb.models m USING (id)
 WHERE s.kind = 'motion_primitive' ORDER BY s.name, s.version
"""
WALK = (
    "SELECT n_frames FROM modb.synthesize_from_models('walk', "
    "ARRAY[[0, 6], [6, 8], [0, 0]]::float8[], %s, 1)"
)


def _rss_kb(conn: psycopg.Connection) -> int:
    pid = conn.info.backend_pid
    with open(f"/proc/{pid}/status") as status:
        return next(int(line.split()[1]) for line in status if line.startswith("VmRSS:"))


def _timed(call) -> float:
    start = time.perf_counter()
    call()
    return (time.perf_counter() - start) * 1e3


def _figures(times: list[float]) -> str:
    return f"p50 {statistics.median(times):.0f} ms, p99 {np.percentile(times, 99):.0f} ms"


def main(old_dsn: str, new_dsn: str, rounds: int) -> None:
    conns = {label: psycopg.connect(dsn, autocommit=True)
             for label, dsn in (("old", old_dsn), ("new", new_dsn))}  # fmt: skip
    versions = {label: c.execute("SELECT extversion FROM pg_extension WHERE extname = 'modb'")
                .fetchone()[0] for label, c in conns.items()}  # fmt: skip
    listed: dict[str, list[float]] = {"old": [], "new": []}
    shown: dict[str, list[float]] = {"old": [], "new": []}
    for k in range(rounds):
        order = ("old", "new") if k % 2 == 0 else ("new", "old")
        for label in order:
            if label == "old" and k >= OLD_ROUNDS:  # (minutes each before 0.26.0)
                continue
            conn = conns[label]
            if label == "old":
                listed[label].append(_timed(lambda: conn.execute(OLD_LISTING).fetchall()))
            else:
                listed[label].append(_timed(lambda: listing(conn)))
            # before 0.26.0 `show` read the whole version (data and tree) and summed it up here
            show = (lambda: load(conn, "many 7")) if label == "old" else (
                lambda: brief(conn, "many 7"))  # fmt: skip
            shown[label].append(_timed(show))
    rows = len(listing(conns["new"]))
    for label in ("old", "new"):
        print(f"{versions[label]}: list {rows} versions {_figures(listed[label])}; "
              f"show one {_figures(shown[label])}")  # fmt: skip
    print(f"median list {versions['old']} / {versions['new']}: "
          f"{statistics.median(listed['old']) / statistics.median(listed['new']):.0f}x")
    for label in ("old", "new"):
        conn = conns[label]
        conn.execute("SET statement_timeout = '1s'")
        stops = []
        for _ in range(3):
            start = time.perf_counter()
            try:
                conn.execute(WALK, [600]).fetchall()
            except psycopg.errors.QueryCanceled:
                pass
            stops.append(time.perf_counter() - start)
        conn.execute("RESET statement_timeout")
        print(f"{versions[label]}: a 1 s statement timeout stopped a 600 s walk after "
              f"{', '.join(f'{s:.1f}' for s in stops)} s")  # fmt: skip
    for label, dsn in (("old", old_dsn), ("new", new_dsn)):
        with psycopg.connect(dsn, autocommit=True) as conn:
            conn.execute(WALK, [30]).fetchall()
            first = _rss_kb(conn)
            for _ in range(19):
                conn.execute(WALK, [30]).fetchall()
            last = _rss_kb(conn)
        growth = (last - first) / 19 / 1024
        print(f"{versions[label]}: backend RSS after the 1st walk {first / 1024:.0f} MB, after "
              f"the 20th {last / 1024:.0f} MB ({growth:+.2f} MB a call)")  # fmt: skip


def make(cluster_dsn: str) -> None:
    """The two databases (modb_service_old at 0.25.0, modb_service_new updated to today's)."""
    from psycopg.conninfo import make_conninfo

    from modb.cli.main import main as modb

    with psycopg.connect(cluster_dsn, autocommit=True) as admin:
        for name in ("modb_service_old", "modb_service_new"):
            admin.execute(f"DROP DATABASE IF EXISTS {name}")
        admin.execute("CREATE DATABASE modb_service_old")
    old = make_conninfo(cluster_dsn, dbname="modb_service_old")
    with psycopg.connect(old, autocommit=True) as conn:
        conn.execute("CREATE EXTENSION modb VERSION '0.25.0' CASCADE")
    for args in (["load", "../shared/mocap/cmu/16", "--collection", "cmu16", "--no-snippets",
                  "-q"],
                 ["annotate", "--steps", "cmu16", "-q"],
                 ["model", "build", "left", "--collection", "cmu16", "--primitive", "left_step",
                  "-q"],
                 ["model", "build", "right", "--collection", "cmu16", "--primitive", "right_step",
                  "-q"],
                 ["model", "graph", "walk", "--collection", "cmu16"]):  # fmt: skip
        if modb(["--dsn", old, *args]) != 0:
            sys.exit(f"modb {' '.join(args)} failed")
    with psycopg.connect(old, autocommit=True) as conn:
        conn.execute(
            "INSERT INTO modb.models (name, kind, skeleton_id, collection_id, data, meta) "
            "SELECT 'many ' || n, m.kind, m.skeleton_id, m.collection_id, m.data, m.meta "
            "FROM modb.models m, generate_series(1, %s) n, generate_series(1, %s) v "
            "WHERE m.name = 'left' ORDER BY n, v",
            [NAMES, VERSIONS],
        )
    with psycopg.connect(cluster_dsn, autocommit=True) as admin:
        admin.execute("CREATE DATABASE modb_service_new TEMPLATE modb_service_old")
    new = make_conninfo(cluster_dsn, dbname="modb_service_new")
    with psycopg.connect(new, autocommit=True) as conn:
        conn.execute("ALTER EXTENSION modb UPDATE")
    print(old, new, sep="\n")


if __name__ == "__main__":
    if sys.argv[1] == "--make":
        make(sys.argv[2])
    else:
        main(sys.argv[1], sys.argv[2], int(sys.argv[3]) if len(sys.argv) > 3 else 20)
