"""Long work as jobs (issue 42) on real capture: a CMU 131 trial and its mirror image (468
snippets), transition graphs built by `modb graph build` as jobs computed in the worker's process.
Checked against the graph the server's own modb.build_transition_graph stores; a worker killed
mid-job (the job finishes once, on another), a cancel (nothing stored), a reader refused, two
workers sharing a batch (no job run twice). Where a job must be caught mid-way (killed, cancelled,
its progress on the web page), this test holds it there with a lock, however fast the machine."""

from __future__ import annotations

import contextlib
import os
import time

import psycopg
import pytest
from support.commands import run_modb
from support.data import mocap
from support.databases import scratch_database
from support.jobs import events, job, stop, until, worker

from modb.database.connection import connect

GRAPH = ["--collection", "cmu", "--profile", "locomotion", "--min-turn", "0"]


@pytest.fixture(scope="module")
def dsn(cluster):
    with scratch_database(cluster, f"jobs_{os.getpid()}") as dsn:
        trial = mocap("cmu", "131", "131_01.amc")
        r = run_modb(dsn, "load", trial, "--collection", "cmu", "--mirror", "-q", process=False)
        assert r.returncode == 0, r.stderr
        r = run_modb(dsn, "worker", "--init", process=False)
        assert r.returncode == 0 and "made" in r.stdout, r.stderr
        with connect(dsn) as conn:  # the oracle: the graph the server builds in one call
            conn.execute("SELECT modb.build_transition_graph('server', 'locomotion', 'cmu', 0)")
        yield dsn


def graph_rows(conn: psycopg.Connection, name: str):
    return conn.execute(
        "SELECT g.data - 'collection', array_agg((t.from_snippet, t.to_snippets, t.cost_to_go) "
        "ORDER BY t.from_snippet) FROM modb.graphs g JOIN modb.graph_transitions t "
        "ON t.graph_id = g.id WHERE g.name = %s GROUP BY g.id",
        [name],
    ).fetchall()


def background(dsn: str, name: str) -> int:
    r = run_modb(dsn, "graph", "build", name, *GRAPH, "--background", process=False)
    assert r.returncode == 0, r.stderr
    return int(r.stdout)


class HeldReading:
    """The terminators locked (ACCESS EXCLUSIVE) in a transaction of the test's: a graph build job
    started meanwhile waits in the reading of its inputs, mid-job (running, its first lines logged),
    until release()."""

    def __init__(self, dsn: str) -> None:
        self.conn = psycopg.connect(dsn)
        self.conn.execute("LOCK TABLE modb.terminators IN ACCESS EXCLUSIVE MODE")

    def wait_for(self, conn: psycopg.Connection, job_id: int) -> None:
        """Until the job runs and waits for the lock."""
        deadline = time.monotonic() + 300
        while not (
            job(conn, job_id)["state"] == "running"
            and conn.execute(
                "SELECT count(*) FROM pg_locks WHERE relation = 'modb.terminators'::regclass "
                "AND NOT granted"
            ).fetchone()[0]
        ):
            assert time.monotonic() < deadline, f"job {job_id} is not waiting: {job(conn, job_id)}"
            time.sleep(0.05)

    def release(self) -> None:
        self.conn.rollback()


@contextlib.contextmanager
def reading_held(dsn: str):
    held = HeldReading(dsn)
    try:
        yield held
    finally:
        held.conn.close()


def test_a_graph_build_job_builds_what_the_server_builds(dsn):
    queued = background(dsn, "left alone")  # a command running its own job runs no other
    r = run_modb(dsn, "graph", "build", "here", *GRAPH, process=False)
    assert r.returncode == 0, r.stderr
    assert "no worker is running" in r.stderr and "running it in this process" in r.stderr
    assert "here: 270 of 468 snippets kept" in r.stdout
    with connect(dsn) as conn:
        assert job(conn, queued)["state"] == "queued"
        assert run_modb(dsn, "jobs", "cancel", str(queued), process=False).returncode == 0
        (state,) = [
            j
            for (j,) in conn.execute("SELECT to_jsonb(j) FROM modb.jobs j WHERE id <> %s", [queued])
        ]
        assert (state["kind"], state["state"], state["submitter"]) == (
            "modb.build_graph",
            "done",
            conn.info.user,
        )
        assert state["done"] == state["total"] == 468 and state["unit"] == "snippets"
        assert state["started_at"] and state["finished_at"] >= state["started_at"]
        graph_id = conn.execute("SELECT id FROM modb.graphs WHERE name = 'here'").fetchone()[0]
        assert state["result"] == {"graph_id": graph_id, "graph": "here"}
        assert any("kept 270 of 468" in line for line in state["log"])
        assert graph_rows(conn, "here") == graph_rows(conn, "server") != []


def test_a_worker_killed_mid_job_is_replaced_and_the_job_finishes_once(dsn):
    first = worker(dsn)
    try:
        with connect(dsn) as conn, reading_held(dsn) as held:
            job_id = background(dsn, "killed")
            held.wait_for(conn, job_id)  # mid-job
            first.kill()  # SIGKILL: no goodbye, its heartbeats just stop
            first.wait(timeout=30)
            assert job(conn, job_id)["state"] == "running"
            held.release()
            second = worker(dsn)
            try:
                state = until(conn, job_id, lambda j: j["state"] == "done", 300, "done")
            finally:
                stop(second)
            assert state["attempts"] == 2  # the engine counts the retry and the run that ended
            assert (events(conn, job_id, "started"), events(conn, job_id, "succeeded")) == (2, 1)
            assert graph_rows(conn, "killed") == graph_rows(conn, "server")
            assert conn.execute(
                "SELECT count(*) FROM modb.graph_names WHERE name = 'killed'"
            ).fetchone() == (1,)
    finally:
        stop(first)


def test_a_cancelled_job_stops_and_stores_nothing(dsn):
    w = worker(dsn)
    try:
        with connect(dsn) as conn, reading_held(dsn) as held:
            job_id = background(dsn, "cancelled")
            held.wait_for(conn, job_id)  # mid-job
            r = run_modb(dsn, "jobs", "cancel", str(job_id), process=False)
            assert r.returncode == 0 and "stops at its next step" in r.stdout, r.stderr
            # the worker hears of the cancel at once (its polling: within 1 s); the job, at the
            # next step after its reading
            time.sleep(2)
            held.release()
            state = until(conn, job_id, lambda j: j["state"] != "running", 120, "stopped")
            assert state["state"] == "cancelled"
            assert any("nothing is half-made" in line for line in state["log"])
            assert not conn.execute(
                "SELECT count(*) FROM modb.graph_names WHERE name = 'cancelled'"
            ).fetchone()[0]
            # a new job, which finishes
            r = run_modb(dsn, "jobs", "retry", str(job_id), process=False)
            assert r.returncode == 0 and "queued again as job" in r.stdout, r.stderr
            again = int(r.stdout.rsplit(" ", 1)[1])
            until(conn, again, lambda j: j["state"] == "done", 300, "done")
            assert graph_rows(conn, "cancelled") == graph_rows(conn, "server")
    finally:
        stop(w)


def test_a_reader_lists_jobs_but_cannot_submit_and_a_loader_can(dsn):
    with connect(dsn) as conn:
        for name, role in (("jobs_reader", "modb_reader"), ("jobs_loader", "modb_loader")):
            conn.execute(f"DROP ROLE IF EXISTS {name}")
            conn.execute(f"CREATE ROLE {name} LOGIN IN ROLE {role}")
    reader = psycopg.conninfo.make_conninfo(dsn, user="jobs_reader")
    loader = psycopg.conninfo.make_conninfo(dsn, user="jobs_loader")
    listed = run_modb(reader, "jobs", "list", process=False)
    assert listed.returncode == 0 and "modb.build_graph" in listed.stdout, listed.stderr
    refused = run_modb(reader, "graph", "build", "no", *GRAPH, "--background")
    assert refused.returncode == 2 and "needs the modb_loader role" in refused.stderr
    assert run_modb(reader, "jobs", "cancel", "1").returncode == 2
    job_id = background(loader, "by the loader")
    with connect(dsn) as conn:
        assert job(conn, job_id)["submitter"] == "jobs_loader"
        assert job(conn, job_id)["state"] == "queued"
    r = run_modb(loader, "jobs", "cancel", str(job_id), process=False)
    assert r.returncode == 0 and "cancelled" in r.stdout, r.stderr


def test_two_workers_share_a_batch_and_no_job_runs_twice(dsn):
    with connect(dsn) as conn:
        jobs = [background(dsn, f"batch {i}") for i in range(4)]
        workers = [worker(dsn), worker(dsn)]
        try:
            for job_id in jobs:
                until(conn, job_id, lambda j: j["state"] == "done", 300, "done")
        finally:
            stop(*workers)
        once = [(events(conn, j, "started"), job(conn, j)["attempts"]) for j in jobs]
        assert once == [(1, 1)] * 4  # started once; the engine counts the run that ended
        oracle = graph_rows(conn, "server")
        assert all(graph_rows(conn, f"batch {i}") == oracle for i in range(4))


def test_finished_jobs_are_deleted_after_their_age(dsn):
    with connect(dsn) as conn:
        finished = conn.execute(
            "SELECT count(*) FROM modb.jobs WHERE state IN ('done', 'failed', 'cancelled')"
        ).fetchone()[0]
        assert (
            finished >= 5 and conn.execute("SELECT count(*) FROM modb_jobs.progress").fetchone()[0]
        )
        # under an hour: every finished job is old enough (its first housekeeping within 1.3 s)
        w = worker(dsn, "--keep-days", "0.01")
        try:
            deadline = time.monotonic() + 60
            while conn.execute("SELECT count(*) FROM modb.jobs").fetchone()[0]:
                assert time.monotonic() < deadline, "finished jobs still there after 60 s"
                time.sleep(0.05)
        finally:
            stop(w)
        assert conn.execute("SELECT count(*) FROM modb_jobs.progress").fetchone() == (0,)


def test_rest_submits_with_a_loader_token_and_a_reader_token_only_reads(dsn):
    import httpx
    from support.browser import serving

    from modb.database.cluster import ensure_writer_role

    with psycopg.connect(dsn, autocommit=True) as conn:
        ensure_writer_role(conn)
    tokens = {}
    for name, role in (("rest-loader", "loader"), ("rest-reader", "reader")):
        r = run_modb(dsn, "token", "create", name, "--role", role, process=False)
        assert r.returncode == 0, r.stderr
        tokens[role] = {"Authorization": f"Bearer {r.stdout.strip()}"}
    arguments = {
        "name": "rest",
        "collection": "cmu",
        "profile": "locomotion",
        "min_turn_degrees": 0,
    }
    body = {"kind": "build_graph", "arguments": arguments}
    with serving(dsn) as address, httpx.Client(base_url=f"http://{address}", timeout=60) as client:
        assert client.post("/api/jobs", json=body, headers=tokens["reader"]).status_code == 403
        bad = client.post("/api/jobs", json={**body, "kind": "nap"}, headers=tokens["loader"])
        assert bad.status_code == 400 and "build_graph" in bad.json()["error"]
        r = client.post("/api/jobs", json=body, headers=tokens["loader"])
        assert r.status_code == 202, r.text
        job_id = r.json()["id"]
        assert r.headers["location"] == f"/api/jobs/{job_id}"
        assert (r.json()["state"], r.json()["submitter"]) == ("queued", "rest-loader")
        w = worker(dsn)
        try:
            deadline = time.monotonic() + 300
            while (state := client.get(f"/api/jobs/{job_id}").json())["state"] != "done":
                assert time.monotonic() < deadline, state
                time.sleep(0.05)
        finally:
            stop(w)
        graph_id = state["result"]["graph_id"]
        assert client.get(f"/api/graphs/{graph_id}").json()["name"] == "rest"
        assert job_id in [j["id"] for j in client.get("/api/jobs").json()]
        ended = client.post(f"/api/jobs/{job_id}/cancel", headers=tokens["loader"])
        assert ended.status_code == 409, ended.text
    with connect(dsn) as conn:
        audited = conn.execute(
            "SELECT token_name, action FROM modb.audit_log WHERE object = %s", [f"job {job_id}"]
        ).fetchall()
        assert audited == [("rest-loader", "submit job")]
        assert graph_rows(conn, "rest") == graph_rows(conn, "server")


def test_the_web_page_lists_jobs_with_live_progress_and_what_they_made(dsn, chromium_driver):
    from selenium.webdriver.common.by import By
    from support.browser import module_page, serving, severe_console_entries
    from support.data import REPO

    # The job is held running, its progress shown, until the page has shown it so (however fast
    # this machine builds the graph): its name taken, uncommitted, it waits at its store.
    held = psycopg.connect(dsn)
    held.execute("INSERT INTO modb.graph_names (name, kind) VALUES ('seen', 'transitions')")
    with serving(dsn) as address, module_page(chromium_driver, "1280,800") as browser:
        job_id = background(dsn, "seen")
        browser.get(f"http://{address}/")
        w = worker(dsn)
        try:
            seen, deadline = set(), time.monotonic() + 300
            while "done" not in seen:
                assert time.monotonic() < deadline, f"the page showed {seen}"
                shown = browser.execute_script(  # one read: the panel is redrawn as it polls
                    "const li = document.querySelector(`#jobs li[data-job='${arguments[0]}']`);"
                    "return li && [li.className, !!li.querySelector('progress')];",
                    job_id,
                )
                if shown:
                    seen.add(shown[0])
                    if shown == ["running", True]:
                        seen.add("progress")
                        held.rollback()  # the job may finish now
                time.sleep(0.1)
        finally:
            held.close()
            stop(w)
        assert {"running", "progress", "done"} <= seen, seen
        row = browser.find_element(By.CSS_SELECTOR, f'#jobs li[data-job="{job_id}"]')
        with connect(dsn) as conn:
            graph_id = conn.execute("SELECT id FROM modb.graphs WHERE name = 'seen'").fetchone()[0]
        link = row.find_element(By.TAG_NAME, "a")
        assert link.get_attribute("href").endswith(f"/api/graphs/{graph_id}")
        assert link.text == "graph seen"
        artifacts = REPO / "tests" / "artifacts"
        artifacts.mkdir(exist_ok=True)
        browser.execute_script("document.getElementById('jobs-panel').scrollIntoView()")
        browser.save_screenshot(str(artifacts / "jobs-panel.png"))
        assert severe_console_entries(browser) == []


def test_one_submitter_may_have_only_so_many_jobs_waiting(dsn):
    from modb.jobs.submit import MAX_QUEUED, cancel, submit

    with connect(dsn) as conn:
        conn.execute("DROP ROLE IF EXISTS jobs_flood")
        conn.execute("CREATE ROLE jobs_flood LOGIN IN ROLE modb_loader")
        waiting = [
            submit(conn, "build_graph", "jobs_flood", name=f"flood {i}", collection="cmu")
            for i in range(MAX_QUEUED)
        ]
        flood = psycopg.conninfo.make_conninfo(dsn, user="jobs_flood")
        refused = run_modb(flood, "graph", "build", "one more", *GRAPH, "--background")
        assert refused.returncode == 2 and f"{MAX_QUEUED} jobs waiting already" in refused.stderr
        assert background(dsn, "another's") > 0
        cancel(conn, waiting[0])  # one fewer waiting: one more may come
        r = run_modb(flood, "graph", "build", "one more", *GRAPH, "--background", process=False)
        assert r.returncode == 0, r.stderr
        for job_id in conn.execute("SELECT id FROM modb.jobs WHERE state = 'queued'"):
            cancel(conn, job_id[0])
