"""The released install script and the fragments it was built from: same catalogue, same code.

Once a version is released its frozen script, extension/sql/released/modb--VERSION.sql, is what
installs (until the next release, which keeps only its own and 0.1.0's install script:
build_sql.py), and extension/sql/*.sql with the kernel become the working copy of the next
version. Until that version starts (default_version moves on), a fresh install built from them must
give exactly the released catalogue: the fragments can be reorganised, and the kernel sources
reformatted, without changing what installs.

pg_dump leaves out an extension's member objects, so each script runs as a plain script (the same
shim applied to both) into a fresh database of its own, and the two `pg_dump --schema-only` outputs
are compared. From 0.24.0 the functions import the version's kernel package, installed beside
modb.so from its frozen copy (extension/plpython/released/VERSION/): each of its modules must parse
to the same code (docstrings and comments aside) as today's file in extension/plpython/modb_kernel,
and every released kernel must be installed as the tree has it.
"""

from __future__ import annotations

import ast
import difflib
import os
import re
import subprocess
import sys
from pathlib import Path

import psycopg
import pytest

from modb.database.cluster import _bindir
from modb.version import __version__ as VERSION

REPO = Path(__file__).resolve().parents[1]
EXTENSION = REPO / "extension"
RELEASED = EXTENSION / "sql" / "released"
KERNEL = EXTENSION / "plpython" / "modb_kernel"
RELEASED_KERNELS = EXTENSION / "plpython" / "released"
FROZEN = RELEASED / f"modb--{VERSION}.sql"
FROZEN_KERNEL = RELEASED_KERNELS / VERSION

released_only = pytest.mark.skipif(
    not FROZEN.exists(), reason=f"{VERSION} is not released: the fragments are its working copy"
)
CONFIG_DUMP = re.compile(r"^SELECT pg_catalog\.pg_extension_config_dump\((.*)\);\n", re.M)
GUARD = re.compile(r"^\\echo Use .* \\quit\n", re.M)


def built_script() -> str:
    """The install script built from today's fragments and kernel, as the extension's Makefile
    builds it."""
    r = subprocess.run(
        [sys.executable, str(EXTENSION / "build_sql.py"), VERSION], capture_output=True, text=True
    )
    assert r.returncode == 0, r.stderr
    return r.stdout


def as_plain_script(text: str) -> tuple[str, list[str]]:
    """The script runnable outside CREATE EXTENSION, and the arguments of its
    pg_extension_config_dump calls."""
    assert len(GUARD.findall(text)) == 1
    config_dump = CONFIG_DUMP.findall(text)
    text = CONFIG_DUMP.sub("", GUARD.sub("", text)).replace("MODULE_PATHNAME", "$libdir/modb")
    # As CREATE EXTENSION runs it: function bodies are not checked (a SQL function may call a later
    # one).
    return "SET check_function_bodies = off;\n" + text, config_dump


# Local variables renamed in the kernel since a release, as release -> module -> function ->
# {released name: today's name}: the released code, so renamed, must equal today's.
RENAMED = {
    "0.8.0": {"modb_kernel.terminators": {"headings": {"l": "hip_axis"}}},  # E741 refuses `l`
}.get(VERSION, {})


def code_of(source: str, renamed: dict[str, dict[str, str]] | None = None) -> str:
    """What a module does: its syntax tree without docstrings (comments and layout are not in it),
    with the local variables of `renamed` functions renamed."""
    tree = ast.parse(source)
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                if isinstance(body[0].value.value, str):
                    node.body = body[1:]
        if isinstance(node, ast.FunctionDef) and node.name in (renamed or {}):
            names = [n for n in ast.walk(node) if isinstance(n, ast.Name)]
            clash = {n.id for n in names} & set(renamed[node.name].values())
            assert not clash, (node.name, clash)
            for n in names:
                n.id = renamed[node.name].get(n.id, n.id)
    return ast.dump(tree)


def kernel_modules(folder: Path) -> dict[str, str]:
    """A kernel package's modules, by path inside it, with their sources."""
    return {
        p.relative_to(folder).as_posix(): p.read_text()
        for p in sorted(folder.rglob("*.py"))
        if "__pycache__" not in p.parts
    }


def schema_of(cluster, name: str, script: str, tmp_path: Path) -> str:
    """pg_dump --schema-only of a fresh database into which `script` ran."""
    with psycopg.connect(cluster.dsn("postgres"), autocommit=True) as conn:
        conn.execute(f'DROP DATABASE IF EXISTS "{name}"')
        conn.execute(f'CREATE DATABASE "{name}"')
    try:
        with psycopg.connect(cluster.dsn(name), autocommit=True) as conn:
            conn.execute("CREATE EXTENSION cube")
            conn.execute("CREATE EXTENSION plpython3u")
        path = tmp_path / f"{name}.sql"
        path.write_text(script)
        psql = [str(_bindir() / "psql"), "-X", "-q", "-v", "ON_ERROR_STOP=1", "-1"]
        r = subprocess.run(
            [*psql, "-d", cluster.dsn(name), "-f", str(path)], capture_output=True, text=True
        )
        assert r.returncode == 0, r.stderr
        # a fixed key for psql's \restrict line (else random per dump)
        dump = [str(_bindir() / "pg_dump"), "--schema-only", "--restrict-key=modb"]
        r = subprocess.run([*dump, "-d", cluster.dsn(name)], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        return r.stdout
    finally:
        with psycopg.connect(cluster.dsn("postgres"), autocommit=True) as conn:
            conn.execute(f'DROP DATABASE "{name}" WITH (FORCE)')


@released_only
def test_the_fragments_install_the_released_catalogue(cluster, tmp_path):
    frozen, frozen_config_dump = as_plain_script(FROZEN.read_text())
    built, built_config_dump = as_plain_script(built_script())
    assert sorted(built_config_dump) == sorted(frozen_config_dump)
    assert len(frozen_config_dump) > 0
    pid = os.getpid()
    released = schema_of(cluster, f"release_frozen_{pid}", frozen, tmp_path)
    fragments = schema_of(cluster, f"release_built_{pid}", built, tmp_path)
    package = "modb_kernel_" + VERSION.replace(".", "_")
    assert f"import {package}.kinematics" in released
    assert "CREATE FUNCTION modb.select_next_snippets(" in released
    lines = released.splitlines(True), fragments.splitlines(True)
    diff = "".join(difflib.unified_diff(*lines, str(FROZEN), f"build_sql.py {VERSION}", n=2))
    assert not diff, diff[:20000]


@released_only
def test_the_released_kernel_is_todays_kernel_in_code():
    today, frozen = kernel_modules(KERNEL), kernel_modules(FROZEN_KERNEL)
    assert frozen and sorted(frozen) == sorted(today)
    for module, source in frozen.items():
        name = "modb_kernel." + module[: -len(".py")].replace("/", ".")
        assert code_of(source, RENAMED.get(name)) == code_of(today[module]), module


def released_scripts_with_kernels() -> list[Path]:
    """Every released script whose version imports an installed kernel (0.24.0 on)."""
    versions = {p.name for p in RELEASED_KERNELS.iterdir()} if RELEASED_KERNELS.exists() else set()
    return [p for p in sorted(RELEASED.glob("modb--*.sql")) if p.stem.split("--")[-1] in versions]


def test_scripts_import_the_kernel_and_carry_none_of_it():
    scripts = released_scripts_with_kernels()
    if not scripts:
        pytest.skip("no released version imports an installed kernel yet")
    for script in scripts:
        version = script.stem.split("--")[-1]
        text = script.read_text()
        modules = kernel_modules(RELEASED_KERNELS / version)
        defined = {
            node.name
            for source in modules.values()
            for node in ast.parse(source).body
            if isinstance(node, (ast.FunctionDef, ast.ClassDef))
        }
        assert defined and not [name for name in defined if f"def {name}(" in text], script.name
        package = "modb_kernel_" + version.replace(".", "_")
        check = f"DO LANGUAGE plpython3u $py$\nimport sys\nkernel = sys.modules.get({package!r})"
        assert check in text, script.name


def test_every_released_kernel_is_installed_compiled(cluster):
    """`make setup` installs each released version's kernel as the tree has it, with the server's
    .pyc (the upgrade tests create old versions; two versions run side by side)."""
    with psycopg.connect(cluster.dsn("postgres")) as conn:
        libdir = Path(
            conn.execute("SELECT setting FROM pg_config WHERE name = 'PKGLIBDIR'").fetchone()[0]
        )
    kernels = {p.name: p for p in RELEASED_KERNELS.iterdir()} if RELEASED_KERNELS.exists() else {}
    if not FROZEN.exists():
        kernels[VERSION] = KERNEL
    for version, folder in kernels.items():
        installed = libdir / ("modb_kernel_" + version.replace(".", "_"))
        assert kernel_modules(installed) == kernel_modules(folder), installed
        compiled = {p.name.split(".")[0] for p in installed.rglob("__pycache__/*.pyc")}
        assert compiled == {Path(m).stem for m in kernel_modules(folder)}, installed
