"""Shared fixtures: one private cluster per test run (shared by its xdist workers), fresh databases
copied from a template, the real data built into databases once per run, one browser per worker.
tests/README.md says which fixture to reuse for what."""

from __future__ import annotations

import functools
import itertools
import json
import os
from pathlib import Path

import pytest
from support import shared
from support.browser import chromium
from support.commands import run_modb
from support.data import MOCAP, mocap

from modb.database.connection import connect

# Modules that take longest go first (by their time in a run of the suite), so that the workers
# finish together: pytest-xdist hands out whole modules in this order (make test runs --dist
# loadfile --no-loadscope-reorder), the first to the first worker, the second to the other. The
# avatar page's module builds the shared `locomotion` database (the demo's run) while the other
# worker runs the README, which needs none of it; the other modules that need it come later.
FIRST = (
    "test_avatar_web.py",
    "test_readme.py",
    "test_upgrade.py",
    "test_select_oracle.py",
    "test_select_fast.py",
    "test_synthesis.py",
    "test_model_synthesis.py",
    "test_demo.py",
    "test_nothing_lost.py",
    "test_models.py",
    "test_catalog_edits.py",
    "test_replicas.py",
    "test_worker_outage.py",
    "test_avatar_models_web.py",
    "test_jobs.py",
    "test_export_roundtrip.py",
    "test_model_graphs_web.py",
    "test_bvh_oracle.py",
    "test_wheel.py",
    "test_cli_hardening.py",
    "test_steps.py",
    "test_asf_oracle.py",
    "test_clip_jobs.py",
)
_RUN = pytest.StashKey[Path]()


def pytest_configure(config):
    folder = shared.start_run()
    if folder is not None:  # the process that started pytest (not an xdist worker)
        config.stash[_RUN] = folder


def pytest_unconfigure(config):
    if _RUN in config.stash:
        shared.end_run(config.stash[_RUN])


# Markers, given here from what a test uses so that none is forgotten (`make test-quick` leaves out
# `slow` and `browser`): `browser`, a test that drives chromium; `data`, one whose module reads the
# real capture (../shared/mocap, through support.data.mocap or the fixtures built from it); `slow`,
# every test of a module in FIRST (over half a minute) and every test that needs `locomotion`.
DATA_FIXTURES = {"locomotion", "cmu", "cmu16_walks"}


@functools.cache
def _reads_capture(path: Path) -> bool:
    return "mocap(" in path.read_text()


def pytest_collection_modifyitems(items):
    rank = {name: i for i, name in enumerate(FIRST)}
    # (a stable sort: the other modules keep their order)
    items.sort(key=lambda item: rank.get(Path(item.fspath).name, len(FIRST)))
    for item in items:
        path = Path(item.fspath)
        if path.name in rank or "locomotion" in item.fixturenames:  # (minutes to build)
            item.add_marker(pytest.mark.slow)
        if "chromium_driver" in item.fixturenames:
            item.add_marker(pytest.mark.browser)
        if DATA_FIXTURES & set(item.fixturenames) or _reads_capture(path):
            item.add_marker(pytest.mark.data)


@pytest.fixture(scope="session")
def cluster():
    """The run's private cluster (a temporary MODB_HOME), stopped and removed at the end."""
    return shared.cluster()


_counter = itertools.count()


@pytest.fixture
def fresh_db(cluster, request) -> str:
    """Conninfo of a new database with the extension installed (dropped after the test)."""
    name = f"t{os.getpid()}_{next(_counter)}"
    dsn = shared.create_database(cluster, name)
    yield dsn
    shared.drop_database(cluster, name)


@pytest.fixture
def db(fresh_db):
    with connect(fresh_db) as conn:
        yield conn


def _load(dsn: str, *args, process: bool = True) -> None:
    r = run_modb(dsn, *args, process=process)
    assert r.returncode == 0, r.stderr


@pytest.fixture(scope="session")
def locomotion(cluster, tmp_path_factory):
    """The database `modb demo --data ../shared/mocap` makes: every locomotion clip of Bandai
    dataset 2 (419 files, collection COLLECTION, 57,616 snippets) with the transition graph GRAPH
    over them, beside CMU 01_01 and CMU 131; built once per run by the demo itself, shared by the
    synthesis and avatar tests (which only read it) and test_demo (which checks what the demo
    printed and wrote: shared.kept("demo")): the same load and graph, built once. The demo runs
    with --no-models: its second half (the steps and graph of motion models of 3,075 steps) would
    add two minutes of a core to the suite; test_demo runs it on CMU 01_01."""
    # development: a database this fixture filled before
    if os.environ.get("MODB_TEST_LOCOMOTION_DSN"):
        return os.environ["MODB_TEST_LOCOMOTION_DSN"]
    for needed in (("cmu", "01"), ("cmu", "131"), ("bandai-2-dev", "data")):
        mocap(*needed)  # skips, naming it, where it is absent (the demo would go to PyPI instead)

    def build(dsn: str) -> None:
        cache = tmp_path_factory.mktemp("demo")
        r = run_modb(dsn, "demo", "--data", MOCAP, "--cache", cache, "--no-models")
        assert r.returncode == 0, r.stderr
        shared.keep("demo", {"stdout": r.stdout, "stderr": r.stderr, "cache": str(cache)})

    return shared.built_once(cluster, "shared_locomotion", build)


@pytest.fixture(scope="session")
def cmu(cluster):
    """CMU 131 (14 ASF/AMC trials, 120 fps) with snippets and their mirror images: built once per
    run, shared by the selection, roles and mirror tests (which only read it)."""
    trials = sorted(mocap("cmu", "131").glob("*.amc"))

    def build(dsn: str) -> None:
        _load(dsn, "load", *trials, "--collection", "cmu/131", "--mirror")

    return shared.built_once(cluster, "shared_cmu", build)


@pytest.fixture(scope="session")
def cmu16_walks(cluster, tmp_path_factory):
    """CMU 16 (walks and turns, ASF/AMC) loaded as collection `cmu16` with snippets, its steps
    annotated, the step models cmu16_left_step and cmu16_right_step and the graph of models `walk`
    over them: built once per run, as a template (support.shared.copy_of_built). cmu16_walks(name)
    is a context manager giving the conninfo of a copy of it named `name`, the caller's to read and
    write, dropped after: name it after the module and os.getpid(). The left steps' model is built
    with its quality report (--report-json); what that build printed and the report are kept:
    shared.kept("cmu16_left_step") (test_models checks them). Built in this process."""
    walks = mocap("cmu", "16")

    def build(dsn: str) -> None:
        def modb(*args) -> None:
            _load(dsn, *args, process=False)

        modb("load", walks, "--collection", "cmu16", "-q")
        modb("annotate", "--steps", "cmu16")
        report = tmp_path_factory.mktemp("cmu16_walks") / "report.json"
        r = run_modb(dsn, "model", "build", "cmu16_left_step", "--collection", "cmu16",
                     "--primitive", "left_step", "--report-json", report,
                     process=False)  # fmt: skip
        assert r.returncode == 0, r.stderr
        shared.keep("cmu16_left_step", {"stdout": r.stdout, "stderr": r.stderr,
                                        "report": json.loads(report.read_text())})  # fmt: skip
        modb("model", "build", "cmu16_right_step", "--collection", "cmu16", "--primitive",
             "right_step", "-q")  # fmt: skip
        r = run_modb(dsn, "model", "graph", "walk", "--collection", "cmu16", process=False)
        assert r.returncode == 0, r.stderr
        # the family: the turning steps' models built here, the starts and stops too few, the
        # standing captured before 16_32's start (test_model_synthesis holds it to these words)
        assert "walk (graph of models): 4 nodes (4 standard), 8 transitions" in r.stdout, r.stdout
        shared.keep("cmu16_family", {"stdout": r.stdout, "stderr": r.stderr})

    return functools.partial(shared.copy_of_built, cluster, "shared_cmu16_walks", build)


@pytest.fixture(scope="session")
def chromium_driver():
    """One headless chromium per worker, for every browser test of it (each module's `browser`
    fixture starts it on a blank page at its own size)."""
    with chromium() as driver:
        yield driver
