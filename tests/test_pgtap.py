"""The SQL test suite (pgTAP, tests/sql/*.sql), run by pg_prove against a fresh database."""

import shutil
import subprocess
from pathlib import Path

import psycopg
import pytest

SQL_TESTS = sorted((Path(__file__).parent / "sql").glob("*.sql"))


@pytest.mark.skipif(
    shutil.which("pg_prove") is None, reason="pg_prove not installed: run `make setup`"
)
def test_pgtap_suite(fresh_db):
    info = psycopg.conninfo.conninfo_to_dict(fresh_db)
    result = subprocess.run(
        [
            "pg_prove",
            "--host",
            info["host"],
            "--port",
            str(info["port"]),
            "--username",
            info["user"],
            "--dbname",
            info["dbname"],
            "--verbose",
            *map(str, SQL_TESTS),
        ],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert "All tests successful" in result.stdout
