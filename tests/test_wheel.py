"""The wheel a user installs with pip: built from this clone, installed into a fresh virtual
environment outside it, and run from there against the extension `make setup` installed in the
server. What the wheel must hold is read from the source tree here, not from setup.py."""

from __future__ import annotations

import json
import posixpath
import re
import shutil
import subprocess
import sys
import time
import venv
import zipfile
from pathlib import Path

import psycopg
import pytest
from support.browser import fetch, serving
from support.data import REPO, mocap
from support.databases import scratch_database

WEB = REPO / "client" / "modb" / "web"
# Source folder -> where its files go in the wheel.
PACKAGE_FOLDERS = {
    REPO / "client" / "modb": "modb",
    REPO / "loader": "modb/loader",
    REPO / "extension" / "plpython" / "modb_kernel": "modb_kernel",
}
IMPORT = re.compile(r"""(?:^|\n)\s*(?:import|export)\s[^'";]*?from\s*['"]([^'"]+)['"]""")


def _run(*args, **kwargs) -> subprocess.CompletedProcess:
    r = subprocess.run([str(a) for a in args], capture_output=True, text=True, **kwargs)
    assert r.returncode == 0, f"{' '.join(map(str, args))}:\n{r.stdout}\n{r.stderr}"
    return r


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """Built from a copy of the clone without earlier builds' leftovers (a build in place reuses
    build/ and *.egg-info, which can hold files the configuration no longer names)."""
    source, dist = tmp_path_factory.mktemp("source") / "modb", tmp_path_factory.mktemp("dist")
    leftovers = shutil.ignore_patterns("*.egg-info", "__pycache__", ".*cache")

    def ignore(folder: str, names: list[str]) -> set[str]:
        top = {".git", ".venv", "build", "tests"} if Path(folder) == REPO else set()
        return leftovers(folder, names) | (top & set(names))

    shutil.copytree(REPO, source, ignore=ignore)
    _run(sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", dist, source)
    (built,) = dist.glob("modb-*.whl")
    return built


@pytest.fixture(scope="module")
def user(tmp_path_factory, wheel) -> tuple[Path, Path]:
    """(the fresh venv's modb command, a working folder outside the clone)."""
    env = tmp_path_factory.mktemp("venv")
    venv.EnvBuilder(with_pip=True).create(env)
    _run(env / "bin" / "pip", "install", "-q", wheel)
    return env / "bin" / "modb", tmp_path_factory.mktemp("home")


def _source_files() -> set[str]:
    """Every file a run of the installed package may read, as a path in the wheel."""
    wanted = set()
    for folder, target in PACKAGE_FOLDERS.items():
        for f in folder.rglob("*"):
            rel = f.relative_to(folder)
            if f.is_dir() or {"node_modules", "__pycache__"} & set(rel.parts):
                continue
            if f.suffix == ".py" or rel.parts[:2] == ("web", "static") or f.name == "py.typed":
                wanted.add(f"{target}/{rel.as_posix()}")
    wanted.add("modb/bench/select_next_snippet.pgbench")
    return wanted


def test_the_wheel_holds_every_module_static_file_and_type_marker(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    missing = sorted(_source_files() - names)
    assert not missing, f"left out of the wheel: {missing}"
    assert {"modb/py.typed", "modb_kernel/py.typed", "modb/loader/sources.py"} <= names


def test_the_installed_command_runs_outside_the_clone(user):
    modb, home = user
    control = (REPO / "extension" / "modb.control").read_text()
    version = re.search(r"default_version\s*=\s*'([^']+)'", control)[1]
    assert _run(modb, "--version", cwd=home).stdout.split() == ["modb", version]
    python = modb.with_name("python")
    where = _run(python, "-c", "import modb.web.app, modb.loader; print(modb.__file__)", cwd=home)
    assert REPO not in Path(where.stdout.strip()).parents  # the wheel's copy, not the clone's


def _module_imports(page: str) -> tuple[list[str], dict[str, str]]:
    """A page's module scripts and its import map."""
    scripts = re.findall(r'<script type="module" src="([^"]+)"', page)
    mapping = re.search(r'<script type="importmap">\s*(\{.*?\})\s*</script>', page, re.S)
    return scripts, json.loads(mapping[1])["imports"] if mapping else {}


def _resolve(specifier: str, base: str, imports: dict[str, str]) -> str:
    for prefix, target in imports.items():
        if specifier == prefix or (prefix.endswith("/") and specifier.startswith(prefix)):
            return target + specifier[len(prefix) :]
    return posixpath.normpath(posixpath.join(posixpath.dirname(base), specifier))  # as a browser


def _fetch_modules(address: str, page: str) -> set[str]:
    """Every module the page loads, fetched as the browser would (each must be served as
    JavaScript); their paths."""
    status, _, body = fetch(address, page)
    assert status == 200, page
    todo, imports = _module_imports(body.decode())
    assert todo, f"{page} has no module script"
    fetched: set[str] = set()
    while todo:
        path = todo.pop()
        if path in fetched:
            continue
        status, kind, body = fetch(address, path)
        assert status == 200 and "javascript" in kind, f"{page} imports {path}: {status}"
        fetched.add(path)
        todo += [_resolve(s, path, imports) for s in IMPORT.findall(body.decode())]
    return fetched


def test_the_installed_server_serves_the_pages_every_module_they_import_and_takes_a_token(
    cluster, user
):
    modb, home = user
    with scratch_database(cluster, "wheel_serve") as dsn:
        made = _run(modb, "--dsn", dsn, "token", "create", "wheel", "--role", "loader", cwd=home)
        bearer = {"Authorization": f"Bearer {made.stdout.strip()}"}
        with serving(dsn, "--require-token", modb=(str(modb),), cwd=home) as address:
            assert fetch(address, "/api/collections")[0] == 401
            status, _, body = fetch(address, "/api/collections", bearer)
            assert status == 200 and json.loads(body) == []
            for name in sorted(p.name for p in (WEB / "static").iterdir()):
                status, _, body = fetch(address, f"/static/{name}")
                assert status == 200 and body == (WEB / "static" / name).read_bytes(), name
            fetched = _fetch_modules(address, "/") | _fetch_modules(address, "/avatar")
            assert "/vendor/three/build/three.core.js" in fetched  # three.module.js's own import


def test_the_installed_command_loads_a_real_file(cluster, user):
    modb, home = user
    walk = mocap("bandai-2-dev", "data", "dataset-2_walk_active_001.bvh")
    frames = int(re.search(r"Frames:\s*(\d+)", walk.read_text())[1])
    with scratch_database(cluster, "wheel_load") as dsn:
        _run(modb, "--dsn", dsn, "load", walk, "--collection", "wheel", cwd=home)
        listing = _run(modb, "--dsn", dsn, "list", cwd=home).stdout
        assert "dataset-2_walk_active_001" in listing
        with psycopg.connect(dsn) as conn:
            stored, snippets = conn.execute(
                "SELECT c.n_frames, (SELECT count(*) FROM modb.snippets s"
                " WHERE s.clip_id = c.clip_id) FROM modb.current_clips c"
                " WHERE c.name = 'dataset-2_walk_active_001'"
            ).fetchone()
        assert stored == frames and snippets > 0
        # the installed command's worker runs a job: the clip retargeted onto its own skeleton at
        # another rate, computed in the worker's process
        _run(modb, "--dsn", dsn, "worker", "--init", cwd=home)
        job_id = _run(modb, "--dsn", dsn, "retarget", "wheel/dataset-2_walk_active_001", "--to",
                      "wheel/dataset-2_walk_active_001", "--fps", "60", "--collection", "moved",
                      "--background", cwd=home).stdout.strip()  # fmt: skip
        worker = subprocess.Popen([modb, "--dsn", dsn, "worker"], cwd=home, stderr=subprocess.PIPE)
        try:
            with psycopg.connect(dsn) as conn:
                deadline = time.monotonic() + 120
                while (state := conn.execute(
                    "SELECT state FROM modb.jobs WHERE id = %s", [int(job_id)]
                ).fetchone()[0]) != "done":  # fmt: skip
                    assert state in ("queued", "running") and time.monotonic() < deadline, state
                    time.sleep(0.2)
                moved = conn.execute(
                    "SELECT n_frames, fps FROM modb.current_clips WHERE collection = 'moved'"
                ).fetchone()
        finally:
            worker.terminate()
            worker.wait(timeout=60)
        assert moved == (2 * frames - 1, 60.0), moved
