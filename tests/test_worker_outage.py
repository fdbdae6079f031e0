"""A worker outlives its database going away (issue 58, 4): stopped for longer than its pool waits,
then started again, the worker says so once, waits, and takes the next job; it never exits with a
traceback. On a cluster of its own (a throwaway one, as test_replicas makes), no capture needed."""

from __future__ import annotations

import shutil
import time

import psycopg
from support.commands import run_modb
from support.jobs import stop, until, worker
from support.shared import NOT_DURABLE, throwaway_folder


from modb.database.cluster import Cluster
from modb.jobs.submit import submit

DOWN_S = 35  # longer than procrastinate's pool waits for a connection (30 s)


def test_a_worker_waits_out_an_outage_and_goes_on(tmp_path):
    home = throwaway_folder("modb-outage-")
    cluster = Cluster(home)
    try:
        cluster.init()
        with open(cluster.datadir / "postgresql.auto.conf", "a") as conf:
            conf.write(NOT_DURABLE)
        cluster.start()
        dsn = cluster.dsn()
        r = run_modb(dsn, "worker", "--init", process=False)
        assert r.returncode == 0, r.stderr
        w = worker(dsn)
        try:
            with psycopg.connect(dsn, autocommit=True) as conn:
                first = submit(conn, "align", primitive="left_step", collection="nowhere")
                until(conn, first, lambda j: j["state"] == "failed", 60, "the first job ends")
            cluster.stop()
            time.sleep(DOWN_S)
            assert w.poll() is None, f"the worker exited while the database was down: {w.stderr}"
            cluster.start()
            with psycopg.connect(dsn, autocommit=True) as conn:
                second = submit(conn, "align", primitive="left_step", collection="nowhere")
                state = until(conn, second, lambda j: j["state"] in ("failed", "done"), 120,
                              "a job after the outage")  # fmt: skip
            assert 'no collection "nowhere"' in state["error"], state
            assert w.poll() is None
        finally:
            stop(w)
        said = w.stderr.read()
        # (the failing jobs' own tracebacks are the worker's log; the outage's are not)
        assert "PoolTimeout" not in said and "ConnectorException" not in said, said
        assert said.count("the database is unreachable") == 1, said
        assert "the database answers again" in said, said
    finally:
        cluster.stop()
        shutil.rmtree(home, ignore_errors=True)
