"""README.md as a reader follows it: every command and SQL block runs, in the order written, on real
data in an embedded database of its own; the Reference tables are what the code says."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import psycopg
import pytest
from support import readme, reference

from modb.database.cluster import Cluster

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"
MOCAP_AS_WRITTEN = "../shared/mocap"  # where the README says the real data is


def _environment(home: Path) -> dict[str, str]:
    """A reader's shell after `make setup`: modb on PATH, no database chosen: the embedded one."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("PG") and k != "MODB_DSN"}
    env["MODB_HOME"] = str(home)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    return env


def _as_here(block: readme.Block, mocap: Path) -> readme.Block:
    """The block with the README's data path (relative to the clone) made absolute: the blocks run
    in a scratch folder, so that what they write stays out of the clone."""
    text = block.text.replace(MOCAP_AS_WRITTEN, str(mocap.resolve()))
    return readme.Block(block.line, block.language, text, block.not_run)


def test_every_readme_block_runs_in_order(tmp_path):
    mocap = Path(os.environ.get("MODB_MOCAP", REPO / MOCAP_AS_WRITTEN))
    if not mocap.exists():
        pytest.skip(f"README's examples use the real data, not found at {mocap} (set MODB_MOCAP)")
    home = Path(tempfile.mkdtemp(prefix="modb-readme-"))
    env = _environment(home)
    runner = readme.Runner(cwd=tmp_path, env=env, python=sys.executable, dsn=Cluster(home).dsn())
    ran = 0
    try:
        for block in readme.blocks(README.read_text()):
            readme.check_not_run(block)
            if block.language in readme.RUNNABLE and block.not_run is None:
                runner.run(_as_here(block, mocap))
                ran += 1
    finally:
        subprocess.run(["modb", "db", "stop"], env=env, cwd=REPO, capture_output=True)
        shutil.rmtree(home, ignore_errors=True)
    assert ran >= 20, f"only {ran} README blocks ran"


def test_a_broken_readme_command_fails_with_its_line(tmp_path):
    markdown = "# x\n\n```sh\necho fine\n```\n\ntext\n\n```sh\nmodb lod x.bvh\n```\n"
    runner = readme.Runner(cwd=tmp_path, env=_environment(tmp_path), python=sys.executable)
    first, broken = readme.blocks(markdown)
    runner.run(first)
    with pytest.raises(AssertionError, match=r"README.md:9: the sh block failed"):
        runner.run(broken)


def test_only_the_allowed_blocks_may_be_left_unrun():
    markdown = (
        "<!-- not run: a server -->\n```sh\nmodb serve --port 8080\n```\n"
        "<!-- not run: slow -->\n```sh\nmodb list\n```\n"
    )
    served, listed = readme.blocks(markdown)
    readme.check_not_run(served)
    with pytest.raises(AssertionError, match="README.md:6: marked `not run: slow`"):
        readme.check_not_run(listed)


def test_the_reference_tables_are_the_comments_and_the_help(fresh_db):
    written = reference.sections(README.read_text())
    with psycopg.connect(fresh_db) as conn:
        expected = reference.generated(conn)
    assert set(written) == set(expected), "README lacks a reference table"
    for name, table in expected.items():
        assert written[name] == table, (
            f"README's {name} table is stale: run tests/support/reference.py (see its docstring)"
        )


def test_the_knob_table_names_every_knob(fresh_db):
    text = README.read_text()
    section = text[text.index("### Knobs") :]
    section = section[: section.index("\n#")]
    written = {line.split("`")[1] for line in section.splitlines() if line.startswith("| `modb.")}
    with psycopg.connect(fresh_db) as conn:
        (knobs,) = conn.execute("SELECT modb.match_knobs()").fetchone()
    assert written == {f"modb.{k}" for k in knobs}


def test_the_readme_states_the_version_once():
    import modb

    assert README.read_text().count(f"This is modb {modb.__version__} ") == 1
