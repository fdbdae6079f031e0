"""Hot standbys of the embedded database: PostgreSQL's own streaming replication, for reads.

Each standby lives in $MODB_HOME/replicas/NAME (data, socket directory, log), is made by
pg_basebackup from the primary, streams from it through a physical replication slot of its own
name, and serves read-only queries (hot standby) with `hot_standby_feedback` on, so the primary's
vacuum does not remove rows a walk's selections on the standby still read. The primary's
`max_slot_wal_keep_size` bounds what a stopped standby's slot keeps: past it the slot is lost and
the standby must be made again (`remove`, `add`), but the primary's disk never fills.

After the primary stops, `promote NAME` makes a standby the primary ($MODB_HOME/primary names it, so
`modb db url` and every default connection follow) and points the other standbys at it.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import time
from dataclasses import dataclass
from pathlib import Path

import psycopg
from psycopg.conninfo import make_conninfo

from .cluster import PORT, Cluster, ClusterError, _bindir, shared_buffers_mb

NAME = re.compile(r"^[a-z][a-z0-9_]{0,30}$")
# What a stopped standby's slot may hold back on the primary before it is given up.
MAX_SLOT_WAL_KEEP = "4GB"
# Shared buffers of a standby: an eighth of what the primary takes, so several fit beside it.
STANDBY_BUFFER_SHARE = 8
SLOT_RELEASE_SECONDS = 10  # a stopped standby's walsender lets go of its slot


@dataclass(frozen=True)
class Replica:
    name: str
    home: Path

    @property
    def node(self) -> Cluster:
        return Cluster(self.home, node=self.home)


def _checked(name: str) -> str:
    if not NAME.match(name) or name == "primary":  # the avatar server's name for the primary
        raise ClusterError(
            f"{name!r} is not a standby name: use lower-case letters, digits and _ (start with a "
            "letter, at most 31), other than 'primary'"
        )
    return name


class Replicas:
    """The standbys of `cluster` (the embedded database's primary)."""

    def __init__(self, cluster: Cluster) -> None:
        self.cluster = cluster
        self.folder = cluster.home / "replicas"

    def all(self) -> list[Replica]:
        primary = self.cluster.node_home
        if not self.folder.is_dir():
            return []
        return [
            Replica(d.name, d)
            for d in sorted(self.folder.iterdir())
            # standby.signal: a node promoted before and then left is no standby (and must
            # never be started as one more primary)
            if (d / "pgdata" / "standby.signal").exists() and d != primary
        ]

    def get(self, name: str) -> Replica:
        for r in self.all():
            if r.name == name:
                return r
        raise ClusterError(f"no standby named {name!r} (`modb db replica list` shows them)")

    def _primary_conn(self) -> psycopg.Connection:
        if not self.cluster.is_running():
            raise ClusterError("the primary is not running: `modb db start` first")
        return psycopg.connect(self.cluster.dsn("postgres"), autocommit=True)

    def add(self, name: str) -> Replica:
        """A new standby streaming from the primary, started."""
        _checked(name)
        home = self.folder / name
        if home.exists():
            raise ClusterError(f"{home} exists: choose another name or `modb db replica remove`")
        with self._primary_conn() as conn:
            if conn.execute("SHOW max_slot_wal_keep_size").fetchone()[0] == "-1":
                conn.execute(f"ALTER SYSTEM SET max_slot_wal_keep_size = '{MAX_SLOT_WAL_KEEP}'")
                conn.execute("SELECT pg_reload_conf()")
            if conn.execute(
                "SELECT 1 FROM pg_replication_slots WHERE slot_name = %s", [name]
            ).fetchone():
                raise ClusterError(
                    f"the primary has a replication slot {name!r} already (another standby's?): "
                    f"choose another name, or drop it there with SELECT "
                    f"pg_drop_replication_slot('{name}')"
                )
            conn.execute("SELECT pg_create_physical_replication_slot(%s, true)", [name])
        node = Cluster(self.cluster.home, node=home)
        node.make_directories()
        try:
            self.cluster._run(
                _bindir() / "pg_basebackup",
                "-D",
                node.datadir,
                "-d",
                self.cluster.dsn("postgres"),
                "-S",
                name,
                "-X",
                "stream",
                "--checkpoint=fast",
            )
            (node.datadir / "standby.signal").touch()
            if os.geteuid() == 0:
                shutil.chown(node.datadir / "standby.signal", "postgres", "postgres")
            for stale in ("postmaster.pid", "postmaster.opts"):
                (node.datadir / stale).unlink(missing_ok=True)
            self._configure(node, name)
            node.run_server()
        except BaseException:
            with contextlib.suppress(ClusterError):  # it may have started after all
                node.stop()
            shutil.rmtree(home, ignore_errors=True)
            with contextlib.suppress(ClusterError, psycopg.Error):  # the first error is the one
                self._drop_slot(name)
            raise
        return Replica(name, home)

    def _configure(self, node: Cluster, name: str) -> None:
        """The standby's own socket, smaller buffers, and where it streams from (later lines of
        postgresql.auto.conf win over the primary's copied ones)."""
        with open(node.datadir / "postgresql.auto.conf", "a") as conf:
            conf.write(
                "# written by modb db replica add: a hot standby\n"
                f"unix_socket_directories = {_quoted(str(node.socket_dir))}\n"
                f"shared_buffers = {max(128, shared_buffers_mb() // STANDBY_BUFFER_SHARE)}MB\n"
                "hot_standby = on\n"
                "hot_standby_feedback = on\n"
                f"primary_conninfo = {_quoted(self._primary_conninfo(name))}\n"
                f"primary_slot_name = '{name}'\n"
            )
        if os.geteuid() == 0:
            shutil.chown(node.datadir / "postgresql.auto.conf", "postgres", "postgres")

    def _primary_conninfo(self, name: str) -> str:
        return make_conninfo(
            host=str(self.cluster.socket_dir),
            port=PORT,
            user=self.cluster.os_user,
            application_name=name,
        )

    def _drop_slot(self, name: str) -> None:
        """Drops the standby's slot on the primary, once its walsender has let go of it."""
        with self._primary_conn() as conn:
            deadline = time.monotonic() + SLOT_RELEASE_SECONDS
            while True:
                row = conn.execute(
                    "SELECT active FROM pg_replication_slots WHERE slot_name = %s", [name]
                ).fetchone()
                if row is None:
                    return
                if not row[0]:
                    conn.execute("SELECT pg_drop_replication_slot(%s)", [name])
                    return
                if time.monotonic() > deadline:
                    raise ClusterError(
                        f"the slot {name!r} is still in use on the primary: is another server "
                        "streaming through it?"
                    )
                time.sleep(0.1)

    def remove(self, name: str) -> None:
        """Stops the standby, drops its slot (the primary must run: a slot left there would
        keep WAL for it) and deletes its data."""
        replica = self.get(name)
        self._primary_conn().close()  # refused now, before anything is stopped, if it is down
        replica.node.stop()
        self._drop_slot(name)
        shutil.rmtree(replica.home)

    def status(self) -> list[dict]:
        """Per standby: its name, conninfo, whether it runs, and its replay lag seen from the
        primary (bytes of WAL not yet replayed, and time)."""
        lag: dict[str, tuple] = {}
        try:
            with self._primary_conn() as conn:
                for row in conn.execute(
                    "SELECT application_name, pg_wal_lsn_diff(pg_current_wal_lsn(), replay_lsn), "
                    "replay_lag FROM pg_stat_replication"
                ):
                    lag[row[0]] = row[1:]
                slots = dict(conn.execute("SELECT slot_name, wal_status FROM pg_replication_slots"))
        except (ClusterError, psycopg.Error):
            slots = {}
        out = []
        for r in self.all():
            behind = lag.get(r.name)
            out.append(
                {
                    "name": r.name,
                    "dsn": r.node.dsn(),
                    "running": r.node.is_running(),
                    "streaming": behind is not None,
                    "replay_lag_bytes": None
                    if behind is None or behind[0] is None
                    else int(behind[0]),  # fmt: skip
                    # "lost": the primary gave up its WAL (max_slot_wal_keep_size): make it again
                    "slot": slots.get(r.name),
                    "replay_lag": None if behind is None or behind[1] is None else str(behind[1]),
                }
            )
        return out

    def promote(self, name: str) -> Replica:
        """Make standby `name` the primary (the old one must be stopped) and point the other
        standbys at it, each with a slot of its own there. Run again after a failure past the
        promotion itself, it finishes pointing them."""
        home = self.folder / _checked(name)
        if self.cluster.node_home == home:  # promoted already
            self._lead(self.all())
            return Replica(name, home)
        if self.cluster.is_running():
            raise ClusterError(
                "the primary is still running: stop it first (`modb db stop`); two primaries "
                "would split the data"
            )
        replica = self.get(name)
        node = replica.node
        node.run_server()
        others = [r for r in self.all() if r.name != name]
        replayed = {r.name: _replayed(r.node) for r in [replica, *others] if r.node.is_running()}
        ahead = [n for n, lsn in replayed.items() if lsn > replayed[name]]
        if ahead:  # the others could not follow a primary behind them
            raise ClusterError(
                f"{ahead[0]} has replayed more of the old primary's WAL than {name}: promote "
                f"{ahead[0]}"
            )
        try:
            node._run(_bindir() / "pg_ctl", "promote", "-w", "-D", node.datadir)
        except ClusterError:
            if _in_recovery(node):  # else it was promoted, only slower than pg_ctl waited
                raise
        # from now on it is the primary, whatever fails below (a rerun finishes that)
        (self.cluster.home / "primary").write_text(str(home.relative_to(self.cluster.home)) + "\n")
        Replicas(Cluster(self.cluster.home))._lead(others)
        return replica

    def _lead(self, standbys: list[Replica]) -> None:
        """This primary (promoted) gets its own buffers and a slot for each standby, and they
        stream from it."""
        with self._primary_conn() as conn:
            for other in standbys:
                conn.execute(
                    "SELECT pg_create_physical_replication_slot(%s, true) WHERE NOT EXISTS "
                    "(SELECT FROM pg_replication_slots WHERE slot_name = %s)",
                    [other.name, other.name],
                )
            # a primary's buffers, from its next restart on
            conn.execute(f"ALTER SYSTEM SET shared_buffers = '{shared_buffers_mb()}MB'")
        for other in standbys:
            with open(other.node.datadir / "postgresql.auto.conf", "a") as conf:
                conf.write(
                    "# written by modb db replica promote: the new primary\n"
                    f"primary_conninfo = {_quoted(self._primary_conninfo(other.name))}\n"
                )
            if other.node.is_running():
                other.node._run(_bindir() / "pg_ctl", "reload", "-D", other.node.datadir)
            else:
                other.node.run_server()


def _quoted(value: str) -> str:
    """A postgresql.conf string value."""
    return "'" + value.replace("\\", "\\\\").replace("'", "''") + "'"


def _in_recovery(node: Cluster) -> bool:
    """Whether the server is still a standby (True too when it does not answer)."""
    try:
        with psycopg.connect(node.dsn("postgres"), autocommit=True, connect_timeout=10) as conn:
            return conn.execute("SELECT pg_is_in_recovery()").fetchone()[0]
    except psycopg.Error:
        return True


def _replayed(node: Cluster) -> int:
    """The WAL position a standby has replayed, as a number."""
    with psycopg.connect(node.dsn("postgres"), autocommit=True) as conn:
        (lsn,) = conn.execute(
            "SELECT pg_wal_lsn_diff(coalesce(pg_last_wal_replay_lsn(), '0/0'), '0/0')"
        ).fetchone()
    return int(lsn)
