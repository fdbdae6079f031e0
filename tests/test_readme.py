"""README.md and docs/ as a reader follows them: every command and SQL block runs, in the order
written (the README, then the docs in DOCS order, on the database the README built), on real data
in an embedded database of its own; docs/reference.md's lists are what the code says; the README
stays short enough to finish, and the development map names every folder."""

from __future__ import annotations

import os
import re
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
DOCS = REPO / "docs"
REFERENCE = DOCS / "reference.md"
DEVELOPMENT = DOCS / "development.md"
MOCAP_AS_WRITTEN = "../shared/mocap"  # where the README says the real data is
# The order the docs' blocks run in, after the README's: each may use what the README (and the
# docs before it) loaded. Every docs/*.md is listed (a test checks), so a new one is run too.
IN_ORDER = (
    "loading.md",
    "internals.md",
    "querying.md",
    "performance.md",
    "synthesis.md",
    "retargeting.md",
    "jobs.md",
    "primitives.md",
    "models.md",
    "web.md",
    "rest.md",
    "roles.md",
    "replication.md",
    "troubleshooting.md",
    "reference.md",
    "development.md",
    "wheel.md",
)
MAX_README_LINES = 500
MAX_LINE = 120


def _documents() -> list[Path]:
    return [README] + [DOCS / name for name in IN_ORDER]


def _all_blocks() -> list[readme.Block]:
    found = []
    for path in _documents():
        found += readme.blocks(path.read_text(), str(path.relative_to(REPO)))
    return found


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
    return readme.Block(block.line, block.language, text, block.not_run, block.path)


def test_every_readme_and_docs_block_runs_in_order(tmp_path):
    mocap = Path(os.environ.get("MODB_MOCAP", REPO / MOCAP_AS_WRITTEN))
    if not mocap.exists():
        pytest.skip(f"README's examples use the real data, not found at {mocap} (set MODB_MOCAP)")
    home = Path(tempfile.mkdtemp(prefix="modb-readme-"))
    env = _environment(home)
    runner = readme.Runner(cwd=tmp_path, env=env, python=sys.executable, dsn=Cluster(home).dsn())
    ran = 0
    try:
        for block in _all_blocks():
            readme.check_not_run(block)
            if block.language in readme.RUNNABLE and block.not_run is None:
                runner.run(_as_here(block, mocap))
                ran += 1
    finally:
        subprocess.run(["modb", "db", "stop"], env=env, cwd=REPO, capture_output=True)
        shutil.rmtree(home, ignore_errors=True)
        # where the time went (pytest shows it with -s, and keeps it in --junitxml's output)
        for where, seconds in sorted(runner.seconds, key=lambda x: -x[1])[:15]:
            print(f"{seconds:7.1f} s  {where}")
    assert ran >= 30, f"only {ran} README and docs blocks ran"


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


def test_a_broken_docs_block_fails_naming_its_file(tmp_path):
    runner = readme.Runner(cwd=tmp_path, env=_environment(tmp_path), python=sys.executable)
    (broken,) = readme.blocks("# x\n\n```sh\nfalse\n```\n", "docs/x.md")
    with pytest.raises(AssertionError, match=r"docs/x.md:3: the sh block failed"):
        runner.run(broken)


def test_every_doc_is_run_in_a_stated_order():
    assert sorted(p.name for p in DOCS.glob("*.md")) == sorted(IN_ORDER)


def test_the_reference_lists_are_the_comments_and_the_help(fresh_db):
    written = reference.sections(REFERENCE.read_text())
    with psycopg.connect(fresh_db) as conn:
        expected = reference.generated(conn)
    assert set(written) == set(expected), "docs/reference.md lacks a generated list"
    for name, table in expected.items():
        assert written[name] == table, (
            f"docs/reference.md's {name} list is stale: run tests/support/reference.py "
            "(see its docstring)"
        )


def test_the_knob_list_names_every_knob(fresh_db):
    text = REFERENCE.read_text()
    section = text[text.index("## Knobs") :]
    section = section[: section.index("\n#")]
    written = {line.split("`")[1] for line in section.splitlines() if line.startswith("- `modb.")}
    with psycopg.connect(fresh_db) as conn:
        (knobs,) = conn.execute("SELECT modb.match_knobs()").fetchone()
    assert written == {f"modb.{k}" for k in knobs}


def test_the_readme_states_the_version_once():
    import modb

    assert README.read_text().count(f"This is modb {modb.__version__} ") == 1


def test_the_readme_is_short_and_every_doc_narrow():
    """The README stays a text a reader can finish: new material goes to docs/."""
    lines = README.read_text().splitlines()
    assert len(lines) <= MAX_README_LINES, (
        f"README.md has {len(lines)} lines (at most {MAX_README_LINES}): move detail to docs/"
    )
    for path in [*_documents(), REPO / "BENCHMARKS.md", REPO / "tests" / "README.md"]:
        for number, line in enumerate(path.read_text().splitlines(), 1):
            assert len(line) <= MAX_LINE, (
                f"{path.relative_to(REPO)}:{number} is {len(line)} characters (at most {MAX_LINE})"
            )


def _anchor(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces as hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def test_every_link_between_the_docs_reaches_its_file_and_heading():
    link = re.compile(r"\]\(([^)\s]+)\)")
    for path in [*_documents(), REPO / "BENCHMARKS.md"]:
        text = re.sub(r"^```.*?^```", "", path.read_text(), flags=re.S | re.M)
        for target in link.findall(text):
            if re.match(r"[a-z]+:", target):
                continue
            file, _, anchor = target.partition("#")
            linked = (path.parent / file).resolve() if file else path
            assert linked.exists(), f"{path.relative_to(REPO)} links to missing {target}"
            if anchor and linked.suffix == ".md":
                headings = re.findall(r"^#+ (.+)$", linked.read_text(), re.M)
                assert anchor in {_anchor(h) for h in headings}, (
                    f"{path.relative_to(REPO)} links to {target}: no such heading"
                )


def _tracked_folders() -> set[str]:
    listed = subprocess.run(
        ["git", "ls-files"], cwd=REPO, capture_output=True, text=True, check=False
    )
    if listed.returncode != 0:
        pytest.skip("not a git checkout: no tracked folders to compare the map with")
    folders = {str(Path(f).parent) for f in listed.stdout.splitlines()} - {"."}
    return {f for f in folders if not f.startswith("tests/artifacts") and "node_modules" not in f}


def test_the_development_map_names_every_folder():
    text = DEVELOPMENT.read_text()
    section = text[text.index("## The map") :]
    named = {
        line.split()[0].rstrip("/")
        for line in section.splitlines()
        if line and not line[0].isspace() and line.split()[0].endswith("/")
    }
    # a name with VERSION in it stands for each released version's folder (0.24.0, ...)
    patterns = [re.compile(re.escape(n).replace("VERSION", r"\d+\.\d+\.\d+") + "$") for n in named]
    missing = sorted(f for f in _tracked_folders() if not any(p.match(f) for p in patterns))
    assert not missing, f"docs/development.md's map lacks {missing}"
