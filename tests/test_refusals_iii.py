"""What issue 58's campaign found refused late, in tracebacks, with the wrong status or not at all:
each refused in words, before any work, with nothing stored. On a copy of conftest's cmu16_walks
(CMU 16's steps, their two models and the graph of models `walk` over them)."""

from __future__ import annotations

import os

import httpx
import psycopg.types.json
import psycopg
import pytest
from support.browser import serving
from support.commands import run_modb_here as modb

from modb.cli.common import write_motion_file
from modb.database.connection import connect

MODEL = "cmu16_left_step"


@pytest.fixture(scope="module")
def dsn(cmu16_walks):
    with cmu16_walks(f"refusals_iii_{os.getpid()}") as dsn:
        yield dsn


@pytest.fixture(scope="module")
def rest(dsn):
    r = modb(dsn, "token", "create", "refusals-loader", "--role", "loader")
    assert r.returncode == 0, r.stderr
    token = {"Authorization": f"Bearer {r.stdout.strip()}"}
    with serving(dsn) as address, httpx.Client(base_url=f"http://{address}", timeout=60) as client:
        client.headers.update(token)
        yield client


def _count(dsn: str, query: str, *params) -> int:
    with connect(dsn) as conn:
        return conn.execute(query, params).fetchone()[0]


def test_model_commands_check_their_outputs_before_any_work(dsn, tmp_path):
    (tmp_path / "folder.glb").mkdir()
    for out in (tmp_path / "missing" / "x.bvh", tmp_path / "folder.glb"):
        r = modb(dsn, "model", "sample", MODEL, "-n", "2", "--out", out)
        assert r.returncode == 2, r.stderr
        assert r.stderr.startswith("modb model sample: cannot write"), r.stderr
        assert "Traceback" not in r.stderr
    versions = _count(dsn, "SELECT count(*) FROM modb.models WHERE name = %s", MODEL)
    r = modb(dsn, "model", "build", MODEL, "--collection", "cmu16", "--primitive", "left_step",
             "--report-json", tmp_path / "missing" / "r.json")  # fmt: skip
    assert r.returncode == 2 and "modb model build: cannot write" in r.stderr, r.stderr
    assert _count(dsn, "SELECT count(*) FROM modb.models WHERE name = %s", MODEL) == versions


def test_a_failed_job_says_why_in_words(dsn):
    r = modb(dsn, "worker", "--init")  # job tables: the command runs its job in its own process
    assert r.returncode == 0, r.stderr
    r = modb(dsn, "model", "build", "x", "--collection", "cmu16", "--primitive", "jump")
    assert r.returncode != 0 and 'collection "cmu16" has 0 "jump" segments' in r.stderr, r.stderr
    r2 = modb(dsn, "align", "left_step", "--collection", "nosuch")
    assert r2.returncode != 0 and 'no collection "nosuch"' in r2.stderr, r2.stderr
    for said in (r.stderr, r2.stderr):
        assert "Traceback" not in said and "CONTEXT:" not in said and "HINT:" not in said, said
    with connect(dsn) as conn:
        errors = [e for (e,) in conn.execute(
            "SELECT error FROM modb_jobs.progress WHERE error IS NOT NULL").fetchall()]  # fmt: skip
    assert len(errors) >= 2, errors
    for error in errors:
        assert "CONTEXT" not in error and "HINT:" not in error and "PL/pgSQL" not in error, error


def test_quiet_jobs_say_nothing(dsn):
    r = modb(dsn, "align", "right_step", "--collection", "cmu16", "-q")
    assert r.returncode == 0 and r.stderr == "", r.stderr


def test_null_names_are_said_as_null(dsn):
    with connect(dsn) as conn:
        for query, said in (
            ("SELECT * FROM modb.sample_motion(NULL, 1, 0)", "model is NULL"),
            ("SELECT * FROM modb.synthesize_from_models(NULL, ARRAY[[0, 3]]::float8[], 3)",
             "graph is NULL"),
        ):  # fmt: skip
            with pytest.raises(psycopg.Error) as refused, conn.transaction():
                conn.execute(query)
            message = refused.value.diag.message_primary
            assert said in message and "None" not in message, message


def test_synth_on_models_refuses_what_it_cannot_do(dsn, tmp_path):
    out = tmp_path / "w.bvh"
    base = ("synth", "--models", "walk", "--to", "0,3", "--seconds", "3", "--out", out)
    r = modb(dsn, *base, "--arrival-radius", "20")
    assert r.returncode == 2 and "takes at most 10 m" in r.stderr, r.stderr
    assert not out.exists()
    r = modb(dsn, "synth", "--help")
    assert "with --models at most 10" in " ".join(r.stdout.split())


def test_synth_no_foot_lock_walks_as_the_seams_leave_it(dsn, tmp_path):
    """Issue 59: feet held by default in both families; --no-foot-lock shows the seams alone, the
    same walk as modb.synthesize_from_models with modb.foot_hold off."""
    from modb.synthesis.from_models import synthesize

    walks = {}
    for flag in ("--foot-lock", "--no-foot-lock"):
        out = tmp_path / f"w{flag}.bvh"
        r = modb(dsn, "synth", "--models", "walk", "--to", "0,3", "--seconds", "3", "--in-place",
                 "--out", out, flag)  # fmt: skip
        assert r.returncode == 0, r.stderr
        walks[flag] = out.read_text()
    assert walks["--foot-lock"] != walks["--no-foot-lock"]
    with connect(dsn) as conn:
        conn.execute("SET modb.foot_hold = off")
        unheld = synthesize(conn, "walk", [(0.0, 3.0)], 3.0).motion
    assert write_motion_file("test", unheld, str(tmp_path / "sql.bvh"))
    assert (tmp_path / "sql.bvh").read_text() == walks["--no-foot-lock"]


def test_a_graph_build_says_which_versions_it_took(dsn):
    r = modb(dsn, "model", "graph", "versions", "--collection", "cmu16")
    assert r.returncode == 0, r.stderr
    with connect(dsn) as conn:
        latest = dict(conn.execute(
            "SELECT primitive, name || ' v' || version || ' (id ' || id || ')' "
            "FROM modb.model_status WHERE latest AND collection = 'cmu16'").fetchall())  # fmt: skip
    for primitive in ("left_step", "right_step"):
        assert f"{primitive} = {latest[primitive]}" in r.stdout, (r.stdout, latest)


def test_a_model_a_graph_names_is_not_deleted(dsn, rest):
    (ident,) = [i for (i,) in psycopg.connect(dsn).execute(
        "SELECT id FROM modb.models WHERE name = 'cmu16_right_step' AND version = 1")]  # fmt: skip
    r = modb(dsn, "model", "delete", "cmu16_right_step", "--version", "1")
    assert r.returncode == 2 and '"walk"' in r.stderr and "is not deleted" in r.stderr, r.stderr
    assert "modb model graph NAME --collection C --model cmu16_right_step" in r.stderr
    answer = rest.delete(f"/api/models/{ident}")
    assert answer.status_code == 409 and '"walk"' in answer.json()["error"], answer.text
    assert _count(dsn, "SELECT count(*) FROM modb.models WHERE id = %s", ident) == 1
    # once no graph names it, it goes
    with connect(dsn) as conn:
        conn.execute("INSERT INTO modb.models (name, kind, skeleton_id, data, meta) "
                     "SELECT 'spare', kind, skeleton_id, data, meta FROM modb.models "
                     "WHERE id = %s", [ident])  # fmt: skip
    r = modb(dsn, "model", "delete", "spare")
    assert r.returncode == 0 and "deleted 1 version of model spare" in r.stdout, r.stderr


def test_a_write_that_takes_no_body_refuses_one(dsn, rest):
    (clip,) = psycopg.connect(dsn).execute("SELECT min(clip_id) FROM modb.current_clips").fetchone()
    answer = rest.post(f"/api/clips/{clip}/steps", json={"x": 1})
    assert answer.status_code == 400 and "takes none" in answer.json()["error"], answer.text
    for empty in ({}, None):
        answer = rest.post(f"/api/clips/{clip}/steps", json=empty)
        assert answer.status_code == 200, answer.text


def test_an_upload_names_its_collection_as_a_collection_is_named(dsn, rest):
    from support.data import mocap

    amc = mocap("cmu", "16", "16_08.amc")
    asf = mocap("cmu", "16", "16.asf")
    files = [("file", (p.name, p.read_bytes())) for p in (asf, amc)]
    made = rest.post("/api/collections", json={"path": "/abs"})
    uploaded = rest.post("/api/uploads", data={"collection": "/abs"}, files=files)
    assert made.status_code == uploaded.status_code == 400, (made.text, uploaded.text)
    assert "collection" in uploaded.json()["error"]
    assert _count(dsn, "SELECT count(*) FROM modb.collections WHERE name = 'abs'") == 0


def test_a_refusal_keeps_its_status_when_the_connection_is_dropped(dsn, rest):
    stretch = {"op": "time_stretch", "factor": 20}
    answer = rest.put("/api/edit-scripts/bx", json={"commands": [stretch] * 3})
    assert answer.status_code in (200, 201), answer.text
    (clip,) = psycopg.connect(dsn).execute("SELECT min(clip_id) FROM modb.current_clips").fetchone()
    versions = _count(dsn, "SELECT count(*) FROM modb.clip_versions")
    answer = rest.post("/api/edit-scripts/bx/apply", json={"clips": [clip]})
    assert answer.status_code == 413, answer.text
    assert "the result would have" in answer.json()["error"] and "Retry-After" not in answer.headers
    assert _count(dsn, "SELECT count(*) FROM modb.clip_versions") == versions


# --- work with bounds (issue 58, 7 and 8) ---------------------------------------------------------


def _ring(model_id: int, n: int) -> dict:
    """A graph of n nodes of one model, each leading to the next (every node reached)."""
    nodes = {f"n{k}": {"model_id": model_id, "type": "standard"} for k in range(n)}
    transitions = [{"from": f"n{k}", "to": f"n{(k + 1) % n}"} for k in range(n)]
    return {"nodes": nodes, "transitions": transitions}


def test_graphs_of_models_are_capped_and_their_check_names_the_first_fault(dsn, rest):
    from psycopg.types.json import Jsonb

    with connect(dsn) as conn:
        model_id, skeleton = conn.execute(
            "SELECT id, skeleton_id FROM modb.models WHERE name = %s AND version = 1", [MODEL]
        ).fetchone()
        check = "SELECT modb.model_graph_problem(%s, %s)"
        assert conn.execute(check, [Jsonb(_ring(model_id, 1000)), skeleton]).fetchone() == (None,)
        (too_big,) = conn.execute(check, [Jsonb(_ring(model_id, 1001)), skeleton]).fetchone()
        assert "at most 1000 nodes and 20000 transitions (this one has 1001" in too_big, too_big
        # the faults the check finds, each named, the first by name or order
        broken = _ring(model_id, 50)
        broken["nodes"]["n7"]["model_id"] = 10**9
        broken["transitions"][3] = {"from": "n3", "to": "nowhere"}
        (said,) = conn.execute(check, [Jsonb(broken), skeleton]).fetchone()
        assert said == 'node "n7": there is no motion model with id 1000000000 (modb model list ' \
            "names them)", said  # fmt: skip
        broken["nodes"]["n7"]["model_id"] = model_id
        (said,) = conn.execute(check, [Jsonb(broken), skeleton]).fetchone()
        assert said.startswith("transition 4 ") and "between nodes of the graph" in said, said
        broken["transitions"][3] = {"from": "n3", "to": "n3"}
        (said,) = conn.execute(check, [Jsonb(broken), skeleton]).fetchone()
        assert said == 'node "n4" is reached by no transition: add one to it, or mark it a start ' \
            "node", said  # fmt: skip
    # what the campaign sent: 100,000 nodes over REST, refused by the cap, nothing stored
    body = {"name": "huge", "kind": "models", "skeleton_id": skeleton,
            "data": _ring(model_id, 100_000)}  # fmt: skip
    answer = rest.post("/api/graphs", json=body)
    assert answer.status_code == 400 and "at most 1000 nodes" in answer.json()["error"], answer.text
    assert _count(dsn, "SELECT count(*) FROM modb.graphs WHERE name = 'huge'") == 0


def test_a_walk_on_models_lets_an_interrupt_in_between_its_steps(dsn):
    from modb_kernel import model_synthesis as MS

    from modb.jobs.kernel_database import WorkerDatabase

    class Interrupted(Exception):
        pass

    calls = []

    def interrupts() -> None:
        calls.append(1)
        if len(calls) > 5:
            raise Interrupted

    with connect(dsn) as conn:
        graph, models, rig = MS.load(WorkerDatabase(conn), "walk")
    synthesis = MS.Synthesis(graph, models, rig, [(0.0, 30.0)], 60.0, 0, interrupts=interrupts)
    with pytest.raises(Interrupted):
        synthesis.run()
    assert len(synthesis.steps) <= 5  # stopped at the sixth piece of work, not at the walk's end


def test_a_cancel_reaches_the_kernels_python_between_statements(dsn):
    """The server's Server.check_interrupts, called in a loop that never runs a statement of its
    own: a statement timeout must end it (else the loop runs its 3,000 rounds and ends quietly)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "extension"))
    import build_sql

    from modb.version import __version__

    body = build_sql._expand(
        "#@modb_kernel database\nimport time\nserver = kernel.database.Server(plpy)\n"
        "for _ in range(3000):\n    time.sleep(0.01)\n    server.check_interrupts()\n",
        __version__,
    )
    with connect(dsn) as conn:
        conn.execute("SET statement_timeout = '300ms'")
        with pytest.raises(psycopg.errors.QueryCanceled):
            conn.execute(f"DO LANGUAGE plpython3u $py$\n{body}\n$py$")


def test_a_retried_build_finds_the_version_it_stored(dsn):
    """Issue 58, 2: a build's job killed after it stored its version, then run again, stores no
    second version: the retry finds its own (marked with the job) and reports it."""
    from modb.models.pipeline import build_model

    job = 987_654
    with connect(dsn) as conn:
        (stored,) = conn.execute(
            "INSERT INTO modb.models (name, kind, skeleton_id, collection_id, data, meta) "
            "SELECT name, kind, skeleton_id, collection_id, data, meta || %s FROM modb.models "
            "WHERE name = %s AND version = 1 RETURNING version",
            [psycopg.types.json.Jsonb({"built_by_job": job}), MODEL],
        ).fetchone()
        before = _count(dsn, "SELECT count(*) FROM modb.models WHERE name = %s", MODEL)
        said: list[str] = []
        made = build_model(conn, MODEL, "cmu16", "left_step", say=said.append, job_id=job)
    assert made["version"] == stored and any("kept, not built again" in s for s in said), said
    assert _count(dsn, "SELECT count(*) FROM modb.models WHERE name = %s", MODEL) == before


def test_costs_are_said_and_estimates_say_what_they_rest_on(dsn):
    r = modb(dsn, "model", "build", "--help")
    assert "twice as long as the build itself" in " ".join(r.stdout.split())
    from modb.synthesis import graphs

    assert "square of the snippets" in graphs.GROWTH and not hasattr(graphs, "build_seconds")
