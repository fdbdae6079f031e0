"""The job engine's tables in a modb database: Procrastinate's own schema (applied once, by its own
code), modb_jobs.progress (what a running job has done, its log and result) and the view modb.jobs
over both. Not part of the extension (the engine's migrations are its own); pg_dump keeps them."""

from __future__ import annotations

from importlib import resources

import psycopg
from procrastinate.schema import SchemaManager

# modb_jobs.progress and the view modb.jobs, with their grants (a script that can run again)
JOB_TABLES = resources.files(__package__).joinpath("job_tables.sql").read_text(encoding="utf-8")


NO_TABLES = "this database has no job tables: `modb worker --init` (as a superuser) makes them"


OLD_TABLES = (
    "this database's job tables are older than this modb (jobs submitted through functions since "
    "0.26.0): `modb worker --init` (as a superuser) brings them up to date"
)


def installed(conn: psycopg.Connection) -> bool:
    return conn.execute("SELECT to_regclass('modb.jobs') IS NOT NULL").fetchone()[0]


def current(conn: psycopg.Connection) -> bool:
    """Whether the job tables are this modb's (the job functions came with 0.26.0)."""
    return conn.execute(
        "SELECT to_regprocedure('modb_jobs.submit(text, text, text, jsonb, bigint[], text)') "
        "IS NOT NULL"
    ).fetchone()[0]


def install(conn: psycopg.Connection) -> bool:
    """The engine's schema and modb's job tables, when missing or older than this modb (a role
    that may create them: the database's owner). Returns whether anything was made."""
    with conn.transaction():
        conn.execute("SELECT pg_advisory_xact_lock(hashtext('modb jobs schema'))")
        engine = conn.execute("SELECT to_regclass('procrastinate_jobs') IS NOT NULL").fetchone()[0]
        if engine and installed(conn) and current(conn):
            return False
        if not engine:
            conn.execute(SchemaManager.get_schema())  # no parameters: sent as written
        conn.execute(JOB_TABLES)
    return True
