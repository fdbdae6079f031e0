"""The embedded default database: a private PostgreSQL cluster that modb creates and runs itself.

It listens only on a unix socket under $MODB_HOME/run (no TCP), trusts
connections through that socket, and keeps the socket directory closed to
other users. initdb refuses root, so when run as root the cluster lives in
/var/lib/modb and is run by the `postgres` OS user.
"""

from __future__ import annotations

import os
import pwd
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import psycopg

DATABASE = "modb"
PORT = 5432  # names the socket file only: the cluster has no TCP listener


def shared_buffers_mb() -> int:
    memory = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    return max(128, min(8192, memory // 4 // 2**20))


class ClusterError(RuntimeError):
    pass


def _bindir() -> Path:
    """PostgreSQL 15's server binaries, Debian's layout first: `pg_config` may be a newer major."""
    debian = Path("/usr/lib/postgresql/15/bin")
    if (debian / "initdb").exists():
        return debian
    try:
        out = subprocess.run(
            ["pg_config", "--bindir"], capture_output=True, text=True, check=True
        ).stdout.strip()
        if (Path(out) / "initdb").exists():
            return Path(out)
    except (OSError, subprocess.CalledProcessError):
        pass
    raise ClusterError("PostgreSQL 15 server binaries not found (no initdb): run `make setup`")


def _server_environment() -> dict[str, str]:
    """Our environment minus what would make the server's PL/Python import the client's packages.

    PL/Python must run Debian's python3 with apt's numpy and the extension's own code, never a
    virtualenv's or the user's site-packages (DESIGN.md).
    """
    env = {
        k: v
        for k, v in os.environ.items()
        if not k.startswith("PYTHON") and k not in ("VIRTUAL_ENV", "CONDA_PREFIX")
    }
    env["PYTHONNOUSERSITE"] = "1"
    return env


def default_home() -> Path:
    if os.environ.get("MODB_HOME"):
        return Path(os.environ["MODB_HOME"])
    if os.geteuid() == 0:
        return Path("/var/lib/modb")
    return Path(os.environ.get("XDG_DATA_HOME", Path.home() / ".local" / "share")) / "modb"


@dataclass
class Cluster:
    """The embedded database in `home`: its primary, or with `node`, one server of it (a standby
    in home/replicas/NAME, database.replicas)."""

    home: Path
    node: Path | None = None

    @classmethod
    def default(cls) -> Cluster:
        return cls(default_home())

    @property
    def node_home(self) -> Path:
        """Where this server's data, socket and log are: `home` itself, unless a standby was
        promoted (home/primary names it)."""
        if self.node is not None:
            return self.node
        marker = self.home / "primary"
        return self.home / marker.read_text().strip() if marker.exists() else self.home

    @property
    def datadir(self) -> Path:
        return self.node_home / "pgdata"

    @property
    def socket_dir(self) -> Path:
        return self.node_home / "run"

    @property
    def logfile(self) -> Path:
        return self.node_home / "postgres.log"

    @property
    def os_user(self) -> str:
        """The OS user that owns and runs the cluster (and its superuser's name)."""
        return "postgres" if os.geteuid() == 0 else pwd.getpwuid(os.geteuid()).pw_name

    def dsn(self, dbname: str = DATABASE) -> str:
        return f"host={self.socket_dir} port={PORT} dbname={dbname} user={self.os_user}"

    def _run(self, *args: str, check: bool = True) -> subprocess.CompletedProcess:
        cmd = [str(a) for a in args]
        if os.geteuid() == 0:
            cmd = ["runuser", "-u", "postgres", "--", *cmd]
        result = subprocess.run(cmd, capture_output=True, text=True, env=_server_environment())
        if check and result.returncode != 0:
            raise ClusterError(
                f"{Path(str(args[0])).name} failed: {(result.stderr or result.stdout).strip()}"
                f" (log: {self.logfile})"
            )
        return result

    def is_initialized(self) -> bool:
        return (self.datadir / "PG_VERSION").exists()

    def is_running(self) -> bool:
        if not self.is_initialized():
            return False
        return (
            self._run(_bindir() / "pg_ctl", "status", "-D", self.datadir, check=False).returncode
            == 0
        )

    def make_directories(self) -> None:
        """This server's directories, closed to other users, owned by the OS user that runs it."""
        for d in dict.fromkeys((self.home, self.node_home, self.socket_dir)):
            d.mkdir(parents=True, exist_ok=True)
            os.chmod(d, 0o700)
            if os.geteuid() == 0:
                shutil.chown(d, "postgres", "postgres")

    def init(self) -> None:
        self.make_directories()
        if os.geteuid() == 0 and self._run("test", "-w", self.home, check=False).returncode != 0:
            raise ClusterError(
                f"the postgres OS user, which runs the cluster, cannot reach {self.home}: a parent "
                f"directory is closed to it; choose a MODB_HOME it can reach (default "
                f"/var/lib/modb)"
            )
        self._run(
            _bindir() / "initdb",
            "-D",
            self.datadir,
            "-U",
            self.os_user,
            "--auth=trust",
            "--encoding=UTF8",
            "--locale=C.UTF-8",
        )
        with open(self.datadir / "postgresql.auto.conf", "a") as conf:
            conf.write(
                "# written by modb: private cluster, unix socket only\n"
                "listen_addresses = ''\n"
                f"unix_socket_directories = '{self.socket_dir}'\n"
                "unix_socket_permissions = 0700\n"
                f"port = {PORT}\n"
                # The selection reads the feature index at random: it should stay in shared buffers
                # (a million
                # snippets: an 800 MB index). A quarter of the memory, PostgreSQL's usual advice.
                f"shared_buffers = {shared_buffers_mb()}MB\n"
                # Loaded at start: modb's settings are checked at SET, and sessions share the block
                # directory and resolved match plans (0.29.0).
                "shared_preload_libraries = 'modb'\n"
            )

    def start(self) -> None:
        """Create the cluster if needed, start it, and ensure database `modb` has the extension."""
        if not self.is_initialized():
            self.init()
        started = not self.is_running()
        self.run_server()
        if not self._preloads_modb():
            self._preload_modb(restart=started)
        elif self._runs_an_older_library():
            # A preloaded library is the one loaded at the server's start: the update below needs
            # the one installed since (modb.library_version), and this cluster is private.
            print("modb: restarting the server: it runs an older modb.so than the one installed",
                  file=sys.stderr)  # fmt: skip
            self._pg_ctl("restart")
        self.ensure_database(DATABASE)

    def run_server(self) -> None:
        """Start this server if it is not running."""
        if not self.is_running():
            self._pg_ctl("start")

    def _pg_ctl(self, action: str) -> None:
        self._run(_bindir() / "pg_ctl", action, "-w", "-D", self.datadir, "-l", self.logfile)

    def _preloads_modb(self) -> bool:
        with psycopg.connect(self.dsn("postgres"), autocommit=True) as conn:
            preloaded = conn.execute("SHOW shared_preload_libraries").fetchone()[0]
        return "modb" in [name.strip() for name in preloaded.split(",")]

    def _runs_an_older_library(self) -> bool:
        """Whether the library the server loaded is older than the extension installed on disk."""
        probe = (
            "CREATE FUNCTION pg_temp.modb_library_version() RETURNS text LANGUAGE c "
            "AS '$libdir/modb', 'modb_library_version'"
        )
        with psycopg.connect(self.dsn("postgres"), autocommit=True) as conn:
            available = conn.execute(
                "SELECT string_to_array(default_version, '.')::int[] FROM pg_available_extensions "
                "WHERE name = 'modb'"
            ).fetchone()
            if available is None:
                return False  # not installed: CREATE EXTENSION below says so
            try:
                with conn.transaction(force_rollback=True):
                    conn.execute(probe)
                    (loaded,) = conn.execute(
                        "SELECT string_to_array(pg_temp.modb_library_version(), '.')::int[]"
                    ).fetchone()
            except psycopg.errors.UndefinedFunction:
                return True  # a library before 0.29.0
        return loaded < available[0]

    def _preload_modb(self, restart: bool) -> None:
        """Clusters made before 0.29.0 load modb per session: from their next start, at the
        server's (sessions share the block directory and match plans). Restarted now if this call
        started it."""
        with psycopg.connect(self.dsn("postgres"), autocommit=True) as conn:
            conn.execute("ALTER SYSTEM SET shared_preload_libraries = 'modb'")
        if restart:
            self._pg_ctl("restart")
        else:
            print(
                "modb: this server loads modb per session; from its next start it loads it once "
                "and its sessions share the block directory (modb db stop, then modb db start)",
                file=sys.stderr,
            )

    def ensure_database(self, dbname: str) -> None:
        with psycopg.connect(self.dsn("postgres"), autocommit=True) as conn:
            if not conn.execute(
                "SELECT 1 FROM pg_database WHERE datname = %s", [dbname]
            ).fetchone():
                conn.execute(f'CREATE DATABASE "{dbname}"')
        with psycopg.connect(self.dsn(dbname), autocommit=True) as conn:
            conn.execute("CREATE EXTENSION IF NOT EXISTS modb CASCADE")
            version = (
                "SELECT string_to_array(extversion, '.')::int[] FROM pg_extension "
                "WHERE extname = 'modb'"
            )
            before = conn.execute(version).fetchone()[0]
            conn.execute("ALTER EXTENSION modb UPDATE")
            if before < [0, 8, 0] <= conn.execute(version).fetchone()[0]:
                # 0.8.0 rewrote every feature cube. Its upgrade script cannot VACUUM, so the
                # tables are vacuumed and the index rebuilt here.
                conn.execute("VACUUM ANALYZE modb.snippets, modb.terminators")
                conn.execute("REINDEX INDEX modb.snippets_begin_features_idx")
            ensure_writer_role(conn)
            from modb.jobs.schema import install as install_job_tables  # procrastinate: 0.16 s

            install_job_tables(conn)
            after = conn.execute(version).fetchone()[0]
            if any(before < [0, v, 0] <= after for v in (11, 18, 29)):
                # 0.11.0 packs the blocks of consecutive snippets that loads left (a few seconds);
                # 0.18.0 derives every block again with its term codes, 0.29.0 with its end bounds
                # (about 30 s a million snippets; they count as unpacked), outside the update,
                # beside live selections.
                # numpy, for the loader (90 ms): not for every `modb db` and connection
                from modb.loader.ingest import pack_blocks

                pack_blocks(conn)

    def stop(self) -> None:
        if self.is_running():
            self._run(_bindir() / "pg_ctl", "stop", "-w", "-m", "fast", "-D", self.datadir)

    def status(self) -> str:
        if not self.is_initialized():
            return f"not created (MODB_HOME={self.home}); `modb db start` creates it"
        state = "running" if self.is_running() else "stopped"
        return f"{state}: data {self.datadir}, socket {self.socket_dir}, log {self.logfile}"


WRITER_ROLE = "modb_web"


def ensure_writer_role(conn) -> None:
    """The login role `modb serve` writes as: a member of modb_loader, not a superuser (the
    embedded cluster trusts its local socket; on other servers, give it a password)."""
    if not conn.execute("SELECT 1 FROM pg_roles WHERE rolname = %s", [WRITER_ROLE]).fetchone():
        conn.execute(
            f"CREATE ROLE {WRITER_ROLE} LOGIN NOSUPERUSER NOCREATEDB NOCREATEROLE "
            "IN ROLE modb_loader"
        )
