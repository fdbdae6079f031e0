#!/usr/bin/env python3
"""Does the upgrade chain install what a version's own install script installed?

PostgreSQL installs `CREATE EXTENSION modb VERSION 'x'` from modb--x.sql when it is there, else from
the oldest install script and the upgrade scripts up to x (modb--0.1.0.sql, modb--0.1.0--0.2.0.sql,
...). The tree keeps only the first and the current install script, so every version in between is
installed the second way. This builds each version both ways, in a private server whose extension
folder holds exactly the scripts asked for, and compares the two catalogues:

- `pg_dump --schema-only --binary-upgrade` of each database (which, unlike a plain dump, writes the
  extension's member objects: functions with their bodies, volatility, strictness, parallel safety,
  cost and rows; tables with columns, defaults, constraints and storage; indexes, triggers, views,
  types, operators, operator classes, casts, sequences, comments, privileges, initial privileges),
  without its lines that set OIDs or transaction ids and without sequence values (data: the chain
  takes more generation numbers), cut into one block per object; blocks compare as a set, and the
  GRANT and REVOKE lines of a block as a set, so an order that means nothing does not count;
- the extension's row (version, relocatable, its configuration tables with their conditions, by
  name), its member list (pg_describe_object), and the rows of its tables (the shipped profiles).

From 0.24.0 the PL/Python functions import the version's kernel package installed beside modb.so
(extension/Makefile): the private server's library folder gets the commit's frozen kernels (and the
working copy as the commit's version while it is not released), never the installed ones.

The frozen install scripts come from git history (`git show COMMIT:extension/sql/released/...`):
by default the last commit that still had them (HEAD while it has them). The upgrade scripts, the
base script and the control file come from the same commit; modb.so is this tree's build (or the
installed one).

    python3 extension/compare_chain.py                        # every version 0.2.0 .. 0.16.0
    python3 extension/compare_chain.py --versions 0.9.0 --tamper "COMMENT ON SCHEMA modb IS 'x'"
    python3 extension/compare_chain.py --versions 0.16.0 --built   # today's fragments

Exits 1 when any version differs, printing the objects that differ. Runs as root (the server then
runs as the postgres OS user) or as a user that may run initdb.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
RELEASED = "extension/sql/released"
KERNELS = "extension/plpython/released"  # a folder per released version (0.24.0 on)
KERNEL = "extension/plpython/modb_kernel"  # the working copy
BINDIR = Path("/usr/lib/postgresql/15/bin")
VERSIONS = [f"0.{n}.0" for n in range(2, 17)]
# pg_dump --binary-upgrade lines that only carry OIDs (or an extension's configuration as OIDs).
OID_LINE = re.compile(
    r"^(-- For binary upgrade, (must preserve|set heap's|set toast's) .*"
    r"|SELECT pg_catalog\.binary_upgrade_set_next_\w+\(.*\);"
    r"|SELECT pg_catalog\.binary_upgrade_create_empty_extension\(.*\);"
    r"|UPDATE pg_catalog\.pg_class|SET relfrozenxid = .*|WHERE oid = '\d+';)$"
)
# Blocks that are data, not catalogue: a sequence's value (the chain takes more generations).
DATA = ("SEQUENCE SET ",)
HEADER = re.compile(r"^-- (?:Data for )?Name: (.*?); Type: (.*?); Schema: (.*?); Owner: .*$")


def git(*args: str) -> str:
    return subprocess.run(
        ["git", "-C", str(REPO), *args], check=True, capture_output=True, text=True
    ).stdout


def has(commit: str, path: str) -> bool:
    command = ["git", "-C", str(REPO), "cat-file", "-e", f"{commit}:{path}"]
    return subprocess.run(command, capture_output=True).returncode == 0


def default_commit(versions: list[str]) -> str:
    """The last commit with the frozen install scripts of these versions: HEAD while it has them,
    else the parent of the commit that deleted them."""
    paths = [f"{RELEASED}/modb--{v}.sql" for v in versions]
    missing = [p for p in paths if not has("HEAD", p)]
    if not missing:
        return git("rev-parse", "HEAD").strip()
    deleted = git("rev-list", "-1", "HEAD", "--", missing[0]).strip()
    commit = git("rev-parse", f"{deleted}^").strip() if deleted else ""
    if not commit or not all(has(commit, p) for p in paths):
        sys.exit(f"no commit has all of {', '.join(paths)}: name one with --commit")
    return commit


def as_server_user(cmd: list[str], **kw) -> subprocess.CompletedProcess:
    if os.geteuid() == 0:
        cmd = ["runuser", "-u", "postgres", "--", *cmd]
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    env.pop("VIRTUAL_ENV", None)
    return subprocess.run(cmd, capture_output=True, text=True, env=env, **kw)


class Server:
    """A private PostgreSQL 15 whose share/extension folder is its own.

    PostgreSQL finds its share and lib folders relative to where its binary is, so the server
    binaries are copied into a tree of links to the real folders, but for share/extension (links to
    every file but modb's) and modb.so."""

    def __init__(self, root: Path, module: Path, commit: str):
        self.root = root
        self.bin = root / "lib/postgresql/15/bin"
        self.ext = root / "share/postgresql/15/extension"
        self.lib = root / "lib/postgresql/15/lib"
        self.data = root / "data"
        self.run = root / "run"
        self.commit = commit
        for folder in (self.bin, self.ext, self.lib, self.run):
            folder.mkdir(parents=True)
        for name in ("postgres", "pg_ctl", "initdb"):
            shutil.copy2(BINDIR / name, self.bin / name)
        share = Path("/usr/share/postgresql/15")
        for entry in share.iterdir():
            if entry.name != "extension":
                (self.ext.parent / entry.name).symlink_to(entry)
        for entry in (share / "extension").iterdir():
            if not entry.name.startswith("modb"):
                (self.ext / entry.name).symlink_to(entry)
        for entry in Path("/usr/lib/postgresql/15/lib").iterdir():
            if entry.name != "modb.so" and not entry.name.startswith("modb_kernel_"):
                (self.lib / entry.name).symlink_to(entry)
        shutil.copy2(module, self.lib / "modb.so")
        self.put_kernels()
        self.released = [
            Path(p).name for p in git("ls-tree", "--name-only", commit, f"{RELEASED}/").split()
        ]
        # the control file, the base script and every upgrade script, as released
        self.put("modb.control", git("show", f"{commit}:extension/modb.control"))
        for name in self.released:
            if name == "modb--0.1.0.sql" or name.count("--") == 2:
                self.put(name, self.frozen(name))
        for path in (root, root / "share", root / "lib", root / "lib/postgresql"):
            path.chmod(0o755)
        if os.geteuid() == 0:
            shutil.chown(self.run, "postgres")
            self.data.mkdir()
            shutil.chown(self.data, "postgres")

    def put_kernels(self) -> None:
        """The kernel packages of the commit (0.24.0 on), never the installed ones: each released
        version's frozen copy, and the working copy as the commit's version while it is not
        released (extension/Makefile installs the same)."""
        control = git("show", f"{self.commit}:extension/modb.control")
        current = re.search(r"^default_version\s*=\s*'([^']+)'", control, re.M)[1]
        sources = {}
        for path in git("ls-tree", "-r", "--name-only", self.commit, f"{KERNELS}/").split():
            version, _, name = path[len(KERNELS) + 1 :].partition("/")
            sources.setdefault(version, []).append((path, name))
        if current not in sources:
            working = git("ls-tree", "-r", "--name-only", self.commit, f"{KERNEL}/").split()
            sources[current] = [(p, p[len(KERNEL) + 1 :]) for p in working]
        for version, files in sources.items():
            folder = self.lib / ("modb_kernel_" + version.replace(".", "_"))
            for path, name in files:
                if name.endswith(".py"):
                    (folder / name).parent.mkdir(parents=True, exist_ok=True)
                    (folder / name).write_text(git("show", f"{self.commit}:{path}"))
            for entry in [folder, *folder.rglob("*")]:
                entry.chmod(0o755 if entry.is_dir() else 0o644)

    def frozen(self, name: str) -> str:
        return git("show", f"{self.commit}:{RELEASED}/{name}")

    def put(self, name: str, text: str) -> None:
        (self.ext / name).write_text(text)
        (self.ext / name).chmod(0o644)

    def start(self) -> None:
        r = as_server_user(
            [
                str(self.bin / "initdb"),
                "-D",
                str(self.data),
                "-U",
                "postgres",
                "--auth=trust",
                "--encoding=UTF8",
                "--locale=C.UTF-8",
            ]
        )
        assert r.returncode == 0, r.stderr
        with open(self.data / "postgresql.auto.conf", "a") as conf:
            conf.write(
                f"listen_addresses = ''\nunix_socket_directories = '{self.run}'\n"
                "fsync = off\nsynchronous_commit = off\nfull_page_writes = off\n"
            )
        r = as_server_user(
            [
                str(self.bin / "pg_ctl"),
                "start",
                "-w",
                "-D",
                str(self.data),
                "-l",
                str(self.run / "postgres.log"),
            ]
        )
        assert r.returncode == 0, r.stderr

    def stop(self) -> None:
        as_server_user([str(self.bin / "pg_ctl"), "stop", "-m", "fast", "-D", str(self.data)])

    def dsn(self, db: str) -> str:
        return f"host={self.run} dbname={db} user=postgres"

    def psql(self, db: str, sql: str) -> str:
        r = subprocess.run(
            [
                str(BINDIR / "psql"),
                "-X",
                "-q",
                "-A",
                "-t",
                "-v",
                "ON_ERROR_STOP=1",
                "-d",
                self.dsn(db),
                "-c",
                sql,
            ],
            capture_output=True,
            text=True,
        )
        if r.returncode != 0:
            raise RuntimeError(f"{db}: {sql[:200]}: {r.stderr.strip()}")
        return r.stdout

    def database(self, name: str, version: str, script: str | None) -> None:
        """Database `name` with modb `version`: from `script` (a frozen install script, put in the
        extension folder for this CREATE EXTENSION only) or, without it, from the chain."""
        self.psql("postgres", f'DROP DATABASE IF EXISTS "{name}"')
        self.psql("postgres", f'CREATE DATABASE "{name}"')
        target = self.ext / f"modb--{version}.sql"
        assert not target.exists() or version == "0.1.0"
        if script is not None:
            self.put(target.name, script)
        try:
            self.psql(name, f"CREATE EXTENSION modb VERSION '{version}' CASCADE")
        finally:
            if script is not None:
                target.unlink()
        got = self.psql(name, "SELECT extversion FROM pg_extension WHERE extname = 'modb'")
        assert got.strip() == version, got

    def describe(self, db: str) -> dict[str, str]:
        """The database's catalogue as {object: normalized text}."""
        r = subprocess.run(
            [
                str(BINDIR / "pg_dump"),
                "--schema-only",
                "--binary-upgrade",
                "--restrict-key=modb",
                "-d",
                self.dsn(db),
            ],
            capture_output=True,
            text=True,
        )
        assert r.returncode == 0, r.stderr
        blocks: dict[str, list[str]] = {}
        key = "(preamble)"
        for line in r.stdout.splitlines():
            m = HEADER.match(line)
            if m:
                key = f"{m[2]} {m[3]}.{m[1]}" if m[3] != "-" else f"{m[2]} {m[1]}"
                while key in blocks:  # pg_dump names some objects twice (e.g. ACLs of columns)
                    key += "'"
                blocks[key] = []
            elif line and line != "--" and not OID_LINE.match(line):
                blocks.setdefault(key, []).append(line)
        described = {
            k: "\n".join(
                [x for x in v if not x.startswith(("GRANT ", "REVOKE "))]
                + sorted(x for x in v if x.startswith(("GRANT ", "REVOKE ")))
            )
            for k, v in blocks.items()
            if not k.startswith(DATA)
        }
        # pg_dump writes the extension's configuration tables as OIDs: here by name, in order
        described["extension row"] = self.psql(
            db,
            """
            SELECT e.extversion, e.extrelocatable, n.nspname,
                   (SELECT string_agg(c::regclass::text || ' ' || coalesce(w, ''), ', '
                                      ORDER BY c::regclass::text)
                      FROM unnest(e.extconfig, e.extcondition) AS t(c, w))
              FROM pg_extension e JOIN pg_namespace n ON n.oid = e.extnamespace
             WHERE e.extname = 'modb'""",
        )
        described["extension members"] = self.psql(
            db,
            """
            SELECT string_agg(pg_describe_object(classid, objid, objsubid), E'\n'
                              ORDER BY pg_describe_object(classid, objid, objsubid))
              FROM pg_depend WHERE deptype = 'e'
               AND refobjid = (SELECT oid FROM pg_extension WHERE extname = 'modb')""",
        )
        # what the scripts put in the tables (the shipped profiles; generation numbers aside)
        for table in self.psql(
            db,
            """
                SELECT c.oid::regclass FROM pg_class c
                 WHERE c.relnamespace = 'modb'::regnamespace AND c.relkind = 'r' ORDER BY 1
                """,
        ).split():
            column = "name" if table == "modb.generations" else "t"
            described[f"rows of {table}"] = self.psql(
                db,
                f"SELECT count(*), md5(coalesce(string_agg({column}::text, E'\\n' ORDER BY "
                f"{column}::text), '')) FROM {table} t",
            )
        return described


def compare(a: dict[str, str], b: dict[str, str]) -> list[str]:
    differences = []
    for key in sorted(set(a) | set(b)):
        if a.get(key) != b.get(key):
            if key not in a or key not in b:
                differences.append(f"{key}: only {'from the chain' if key in a else 'frozen'}")
            else:
                lines = [x for x in a[key].splitlines() if x not in b[key].splitlines()]
                lines += [x for x in b[key].splitlines() if x not in a[key].splitlines()]
                differences.append(f"{key}: " + " | ".join(x[:160] for x in lines[:4]))
    return differences


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--commit", help="where the frozen scripts are (default: the last commit that had them)"
    )
    parser.add_argument("--versions", nargs="+", default=VERSIONS)
    parser.add_argument(
        "--module", type=Path, help="modb.so (default: this tree's build, else the installed one)"
    )
    parser.add_argument(
        "--tamper",
        help="SQL run in each frozen-script database before it is "
        "described: shows that a difference is found",
    )
    parser.add_argument(
        "--built",
        action="store_true",
        help="compare each frozen install script with the one build_sql.py builds today from "
        "sql/*.sql (for the current version: what tests/test_release.py checks, here as extension "
        "members), not with the chain",
    )
    args = parser.parse_args()
    commit = args.commit or default_commit(args.versions)
    module = args.module or next(
        p for p in (HERE / "modb.so", Path("/usr/lib/postgresql/15/lib/modb.so")) if p.exists()
    )
    print(f"frozen scripts from {git('rev-parse', '--short', commit).strip()}, module {module}")
    root = Path(tempfile.mkdtemp(prefix="modb-chain-"))
    failed = 0
    try:
        server = Server(root, module, commit)
        server.start()
        print(f"{'version':<8} {'objects':>7}  result")
        for version in args.versions:
            started = time.monotonic()
            built = None
            if args.built:
                built = subprocess.run(
                    [sys.executable, str(HERE / "build_sql.py"), version],
                    check=True,
                    capture_output=True,
                    text=True,
                ).stdout
            server.database("chain", version, built)
            server.database("frozen", version, server.frozen(f"modb--{version}.sql"))
            if args.tamper:
                server.psql("frozen", args.tamper)
            chain, frozen = server.describe("chain"), server.describe("frozen")
            differences = compare(chain, frozen)
            failed += bool(differences)
            objects = sum(1 for k in frozen if not k.startswith(("(", "extension ", "rows ")))
            result = "equal" if not differences else f"{len(differences)} differ"
            print(f"{version:<8} {objects:>7}  {result} ({time.monotonic() - started:.0f} s)")
            for d in differences:
                print(f"    {d}")
            sys.stdout.flush()
        server.stop()
    finally:
        shutil.rmtree(root, ignore_errors=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
