"""Who may do what to jobs (issue 58, 3 and 6): the privileges docs/roles.md lists, checked against
the database for each role; what a loader tried in plain SQL (forging a submitter, marking a job
done, deleting another's job, writing its progress, deferring past the cap, two jobs waiting on
each other) refused; and a worker that lost a job not reporting over the attempt that took it
over. On a fresh database with the job tables (`modb worker --init`), no capture needed."""

from __future__ import annotations

import re
from pathlib import Path

import psycopg
import pytest
from psycopg.types.json import Jsonb
from support.commands import run_modb_here as modb

from modb.jobs.submit import MAX_QUEUED, NotALoader, TooManyQueued, cancel, retry, submit

ROLES_DOC = Path(__file__).resolve().parents[1] / "docs" / "roles.md"
ENGINE = ("procrastinate_jobs", "procrastinate_workers", "procrastinate_events",
          "procrastinate_periodic_defers")  # fmt: skip
FUNCTIONS = ("modb_jobs.submit(text, text, text, jsonb, bigint[], text)",
             "modb_jobs.cancel(bigint)", "modb_jobs.retry(bigint, text)")  # fmt: skip
PRIVILEGES = ("SELECT", "INSERT", "UPDATE", "DELETE")


@pytest.fixture
def logins(fresh_db, db):
    r = modb(fresh_db, "worker", "--init")
    assert r.returncode == 0, r.stderr
    made = {}
    for role in ("reader", "loader", "worker"):
        name = f"jobs_{role}_login"
        db.execute(f"DROP ROLE IF EXISTS {name}")
        db.execute(f"CREATE ROLE {name} LOGIN IN ROLE modb_{role}")
        made[role] = psycopg.conninfo.make_conninfo(fresh_db, user=name)
    yield made
    db.execute("DROP OWNED BY jobs_reader_login, jobs_loader_login, jobs_worker_login")
    for role in made:
        db.execute(f"DROP ROLE jobs_{role}_login")


def _documented() -> dict[str, list[str]]:
    """docs/roles.md's table of job privileges: role -> its cells."""
    text = ROLES_DOC.read_text()
    table = text[text.index("<!-- job privileges -->") :].split("\n\n")[0].splitlines()[3:]
    return {re.sub(r"[`\s]", "", row.split("|")[1]): [c.strip() for c in row.split("|")[2:-1]]
            for row in table}  # fmt: skip


def _granted(db, role: str, tables: tuple[str, ...]) -> str:
    """The privileges the role holds on every one of the tables, as the table writes them."""
    held = [p for p in PRIVILEGES
            if all(db.execute("SELECT has_table_privilege(%s, %s, %s)", [role, t, p]).fetchone()[0]
                   for t in tables)]  # fmt: skip
    assert not [p for p in PRIVILEGES if p not in held and any(
        db.execute("SELECT has_table_privilege(%s, %s, %s)", [role, t, p]).fetchone()[0]
        for t in tables)], f"{role} holds a privilege on some of {tables} only"  # fmt: skip
    return ", ".join(held) or "none"


def test_each_role_holds_the_job_privileges_the_docs_list(logins, db):
    documented = _documented()
    assert set(documented) == {"modb_reader", "modb_loader", "modb_worker"}
    for role, cells in documented.items():
        executes = {db.execute("SELECT has_function_privilege(%s, %s, 'EXECUTE')", [role, f])
                    .fetchone()[0] for f in FUNCTIONS}  # fmt: skip
        assert len(executes) == 1, role
        held = [
            _granted(db, role, ENGINE),
            _granted(db, role, ("modb_jobs.progress",)),
            _granted(db, role, ("modb_jobs.waits",)),
            _granted(db, role, ("modb.jobs",)),
            "EXECUTE" if executes.pop() else "none",
        ]
        assert held == cells, (role, held, cells)


def test_a_loader_submits_as_itself_and_cannot_tamper_in_sql(logins, db):
    with psycopg.connect(logins["loader"], autocommit=True) as loader:
        mine = submit(loader, "align", primitive="left_step", collection="c",
                      submitter="alice")  # a forged submitter is overwritten  # fmt: skip
        (who,) = loader.execute("SELECT submitter FROM modb.jobs WHERE id = %s", [mine]).fetchone()
        assert who == "jobs_loader_login"
        other = db.execute(
            "SELECT modb_jobs.submit('align', 'clips', NULL, '{}', '{}', NULL)"
        ).fetchone()[0]  # the owner's job
        for query, params in (
            ("UPDATE procrastinate_jobs SET args = args || '{\"submitter\": \"alice\"}' "
             "WHERE id = %s", [other]),
            ("UPDATE procrastinate_jobs SET status = 'succeeded' WHERE id = %s", [mine]),
            ("DELETE FROM procrastinate_jobs WHERE id = %s", [other]),
            ("INSERT INTO modb_jobs.progress (job_id, result) VALUES (%s, '{}')", [mine]),
            ("UPDATE modb_jobs.progress SET error = 'forged' WHERE job_id = %s", [other]),
            ("INSERT INTO modb_jobs.waits VALUES (%s, %s)", [mine, other]),
            ("SELECT procrastinate_defer_jobs_v1(ARRAY[ROW('clips', 'modb.align', 0, NULL, NULL, "
             "%s, NULL)::procrastinate_job_to_defer_v1])", [Jsonb({"submitter": "alice"})]),
        ):  # fmt: skip
            with pytest.raises(psycopg.errors.InsufficientPrivilege):
                loader.execute(query, params)
        # through the functions: cancel, and retry as a new job of its own
        assert cancel(loader, other) is True
        again = retry(loader, {"id": other})
        assert again != other
        assert loader.execute("SELECT submitter FROM modb.jobs WHERE id = %s",
                              [again]).fetchone() == ("jobs_loader_login",)  # fmt: skip
        # the cap holds for the functions too
        with pytest.raises(TooManyQueued, match=f"at most {MAX_QUEUED}"):
            for _ in range(MAX_QUEUED + 1):
                submit(loader, "align", primitive="left_step", collection="c")
    with psycopg.connect(logins["reader"], autocommit=True) as reader:
        assert reader.execute("SELECT count(*) FROM modb.jobs").fetchone()[0] > 0
        with pytest.raises((psycopg.errors.InsufficientPrivilege, NotALoader)):
            submit(reader, "align", primitive="left_step", collection="c")
        with pytest.raises(psycopg.errors.InsufficientPrivilege):
            reader.execute("SELECT * FROM modb_jobs.progress")


def test_jobs_never_wait_on_each_other_in_a_circle(logins, db):
    a, b, c = (db.execute("SELECT modb_jobs.submit('align', 'clips', NULL, '{}', '{}', NULL)")
               .fetchone()[0] for _ in range(3))  # fmt: skip
    db.execute("INSERT INTO modb_jobs.waits VALUES (%s, %s), (%s, %s)", [a, b, b, c])
    with pytest.raises(psycopg.errors.CheckViolation, match="neither would ever run"):
        db.execute("INSERT INTO modb_jobs.waits VALUES (%s, %s)", [c, a])


def test_a_worker_that_lost_a_job_does_not_report_over_the_newer_attempt(logins, db):
    job = db.execute(
        "SELECT modb_jobs.submit('align', 'clips', NULL, '{}', '{}', NULL)"
    ).fetchone()[0]
    db.execute("UPDATE procrastinate_jobs SET status = 'doing' WHERE id = %s", [job])

    def as_runner(name: str) -> psycopg.Connection:
        conninfo = psycopg.conninfo.make_conninfo(
            logins["worker"], options=f"-c role=modb_worker -c modb_jobs.runner={name}"
        )
        return psycopg.connect(conninfo, autocommit=True)

    with as_runner("new:2") as new, as_runner("old:1") as old:
        # the newer attempt started (connection.as_worker's JobProgress does this)
        new.execute("INSERT INTO modb_jobs.progress (job_id, runner) VALUES (%s, "
                    "current_setting('modb_jobs.runner'))", [job])  # fmt: skip
        from modb.jobs.progress import UPSERT

        old.execute(UPSERT, {"job": job, "done": None, "total": None, "unit": None, "log": None,
                             "result": None, "error": "the old attempt failed"})  # fmt: skip
        with pytest.raises(psycopg.errors.RaiseException, match="not found"):
            old.execute("SELECT procrastinate_finish_job_v1(%s, 'failed', false)", [job])
        assert db.execute("SELECT status::text FROM procrastinate_jobs WHERE id = %s",
                          [job]).fetchone() == ("doing",)  # fmt: skip
        assert db.execute("SELECT error FROM modb_jobs.progress WHERE job_id = %s",
                          [job]).fetchone() == (None,)  # fmt: skip
        new.execute("SELECT procrastinate_finish_job_v1(%s, 'succeeded', false)", [job])
    assert db.execute("SELECT state FROM modb.jobs WHERE id = %s", [job]).fetchone() == ("done",)


def test_job_tables_of_an_older_modb_are_brought_up_to_date(logins, db, fresh_db):
    """0.25.0's job tables let a loader write the engine's and the progress tables, and had no job
    functions: `modb worker --init` (and `modb db start`) finds them old and takes that back."""
    db.execute("GRANT SELECT, INSERT, UPDATE, DELETE ON modb_jobs.progress, modb_jobs.waits, "
               "procrastinate_jobs, procrastinate_events TO modb_loader")  # fmt: skip
    db.execute("DROP FUNCTION modb_jobs.submit(text, text, text, jsonb, bigint[], text)")
    r = modb(fresh_db, "worker", "--init")
    assert r.returncode == 0 and "job tables made" in r.stdout, r.stdout + r.stderr
    assert _granted(db, "modb_loader", ("modb_jobs.progress", "modb_jobs.waits")) == "SELECT"
    assert _granted(db, "modb_loader", ENGINE) == "SELECT"
