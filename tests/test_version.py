"""One version number: the installed Python package's, what `modb --version` prints and the
extension's `default_version` in the server are the same, all taken from extension/modb.control."""

import importlib.metadata
import re
import subprocess
import sys
from pathlib import Path

import psycopg

CONTROL = Path(__file__).resolve().parents[1] / "extension" / "modb.control"


def modb_command() -> list[str]:
    """The installed `modb` script beside this interpreter, else the same entry point through -m."""
    script = Path(sys.executable).with_name("modb")
    return [str(script)] if script.exists() else [sys.executable, "-m", "modb.cli"]


def test_the_package_the_command_and_the_extension_have_one_version(cluster):
    package = importlib.metadata.version("modb")
    run = subprocess.run([*modb_command(), "--version"], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    assert run.stdout.startswith("modb "), run.stdout
    command = run.stdout.removeprefix("modb ").strip()
    with psycopg.connect(cluster.dsn("postgres")) as conn:
        row = conn.execute(
            "SELECT default_version FROM pg_available_extensions WHERE name = 'modb'"
        ).fetchone()
    assert row is not None, "the modb extension is not installed in the test cluster's server"
    versions = {
        "importlib.metadata.version('modb')": package,
        "modb --version": command,
        "pg_available_extensions.default_version": row[0],
    }
    assert len(set(versions.values())) == 1, f"more than one version: {versions}"


def test_the_version_is_the_one_in_modb_control():
    source = re.search(r"^default_version\s*=\s*'([^']+)'", CONTROL.read_text(), re.MULTILINE)
    assert source is not None, f"no default_version in {CONTROL}"
    assert importlib.metadata.version("modb") == source.group(1), (
        "the installed package's version is not modb.control's: reinstall it (make setup does)"
    )
