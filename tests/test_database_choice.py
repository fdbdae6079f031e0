"""Which database modb uses, and the embedded cluster's lifecycle through `modb db`."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path


from modb.database import dsn


def test_precedence(monkeypatch):
    for v in ("MODB_DSN", *dsn.LIBPQ_VARIABLES):
        monkeypatch.delenv(v, raising=False)
    monkeypatch.setenv("MODB_DSN", "dbname=from_env")
    monkeypatch.setenv("PGHOST", "/somewhere")
    assert dsn.resolve("dbname=given") == ("dbname=given", "--dsn")
    assert dsn.resolve(None) == ("dbname=from_env", "MODB_DSN")
    monkeypatch.delenv("MODB_DSN")
    conninfo, origin = dsn.resolve(None)
    assert conninfo == "" and "PGHOST" in origin


def _modb(home: Path, *args: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("MODB_DSN", *dsn.LIBPQ_VARIABLES)}
    env["MODB_HOME"] = str(home)
    # A user's Python environment must not reach the server's PL/Python (it runs apt's numpy).
    env["PYTHONPATH"] = os.pathsep.join(p for p in sys.path if "site-packages" in p)
    return subprocess.run(
        [sys.executable, "-m", "modb.cli", *args], capture_output=True, text=True, env=env
    )


def test_embedded_cluster_lifecycle():
    home = Path(tempfile.mkdtemp(prefix="modb-embedded-")) / "home"
    try:
        # the postgres OS user must reach MODB_HOME: first see the error that says so
        if os.geteuid() == 0:
            r = _modb(home, "db", "start")
            assert r.returncode == 1 and "cannot reach" in r.stderr, r.stderr
            shutil.rmtree(home)
            home.parent.chmod(0o755)
        r = _modb(home, "db", "status")
        assert r.returncode == 3 and "not created" in r.stdout
        r = _modb(home, "list")  # the first use creates and starts it
        assert r.returncode == 0 and "no clips stored yet" in r.stdout, r.stderr
        r = _modb(home, "db", "status")
        assert r.returncode == 0 and r.stdout.startswith("running")
        url = _modb(home, "db", "url").stdout.strip()
        assert f"host={home / 'run'}" in url and "dbname=modb" in url
        assert (home / "run" / ".s.PGSQL.5432").exists()
        # other users cannot reach the socket
        assert oct((home / "run").stat().st_mode & 0o777) == "0o700"
        conf = (home / "pgdata" / "postgresql.auto.conf").read_text()
        assert "listen_addresses = ''" in conf  # no TCP
        if os.geteuid() == 0:
            assert (home / "pgdata").owner() == "postgres"
        import psycopg

        with psycopg.connect(url, autocommit=True) as conn:
            conn.execute(
                "CREATE FUNCTION pg_temp.numpy_file() RETURNS text LANGUAGE plpython3u "
                "AS $$ import numpy; return numpy.__file__ $$"
            )
            numpy_file = conn.execute("SELECT pg_temp.numpy_file()").fetchone()[0]
            shared_mb = conn.execute(
                "SELECT setting::bigint * 8 / 1024 FROM pg_settings WHERE name = 'shared_buffers'"
            ).fetchone()[0]
        memory_kb = int(
            next(line.split()[1] for line in open("/proc/meminfo") if line.startswith("MemTotal:"))
        )
        # a quarter of the memory
        assert shared_mb == max(128, min(8192, memory_kb // 4 // 1024)), shared_mb
        assert numpy_file.startswith("/usr/lib/python3/dist-packages/"), numpy_file
        assert _modb(home, "db", "stop").returncode == 0
        r = _modb(home, "db", "status")
        assert r.returncode == 3 and r.stdout.startswith("stopped")
        r = _modb(home, "db", "start")  # restarts with its data
        assert r.returncode == 0 and "running" in r.stdout
    finally:
        _modb(home, "db", "stop")
        shutil.rmtree(home.parent, ignore_errors=True)
