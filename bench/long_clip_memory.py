#!/usr/bin/env python3
"""Peak memory of the server process that loads one long clip with its snippets.

Makes a clip of N frames from a real BVH (its frames repeated), loads it with `modb load` into a new
database of the embedded cluster (or --dsn's server on this machine), and reads the loading
backend's memory in /proc until the load ends: its private memory (RssAnon, sampled) and its peak
resident set (VmHWM, which also counts the shared buffers it touched).

    .venv/bin/python bench/long_clip_memory.py --frames 100000
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import psycopg

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

from support.long_clip import repeat_bvh  # noqa: E402

from modb.database.dsn import resolve  # noqa: E402

SOURCE = REPO.parent / "shared" / "mocap" / "bandai-1" / "data" / "dataset-1_walk_active_001.bvh"


def _memory_kib(pid: int) -> tuple[int, int]:
    """(VmHWM, RssAnon) of a process: its peak resident set, which counts the shared buffers it
    touched, and its private memory now."""
    fields = {}
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            key, _, value = line.partition(":")
            fields[key] = value
    except OSError:
        return 0, 0
    return tuple(int(fields.get(k, "0 kB").split()[0]) for k in ("VmHWM", "RssAnon"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=100_000)
    parser.add_argument("--source", type=Path, default=SOURCE)
    parser.add_argument("--dsn", help="a server on this machine (default: the embedded one)")
    parser.add_argument("--mirror", action="store_true", help="also build the mirror image")
    parser.add_argument("--no-snippets", action="store_true", help="store the clip only")
    parser.add_argument(
        "--version", help="install this released version of modb (default: the newest)"
    )
    args = parser.parse_args()
    admin, _ = resolve(args.dsn)
    admin = psycopg.conninfo.make_conninfo(admin, dbname="postgres")
    name = f"long_clip_{args.frames}"
    with psycopg.connect(admin, autocommit=True) as conn:
        conn.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        conn.execute(f'CREATE DATABASE "{name}"')
    dsn = psycopg.conninfo.make_conninfo(admin, dbname=name)
    with psycopg.connect(dsn, autocommit=True) as conn:
        if args.version:
            conn.execute(f"CREATE EXTENSION modb VERSION '{args.version}' CASCADE")
        else:
            conn.execute("CREATE EXTENSION modb CASCADE")
    with tempfile.TemporaryDirectory() as tmp:
        clip = repeat_bvh(args.source, Path(tmp) / "long.bvh", args.frames)
        command = [str(REPO / ".venv" / "bin" / "modb"), "--dsn", dsn, "load", str(clip), "-q"]
        started = time.perf_counter()
        load = subprocess.Popen(
            [
                *command,
                *(["--mirror"] if args.mirror else []),
                *(["--no-snippets"] if args.no_snippets else []),
            ]
        )
        peak, private, backends = 0, 0, set()
        with psycopg.connect(admin, autocommit=True) as watch:
            while load.poll() is None:
                backends |= {
                    r[0]
                    for r in watch.execute(
                        "SELECT pid FROM pg_stat_activity WHERE datname = %s AND pid <> "
                        "pg_backend_pid()",
                        [name],
                    )
                }
                for pid in backends:
                    hwm, anon = _memory_kib(pid)
                    peak, private = max(peak, hwm), max(private, anon)
                time.sleep(0.1)
        elapsed = time.perf_counter() - started
    with psycopg.connect(dsn) as conn:
        snippets, terminators = conn.execute(
            "SELECT (SELECT count(*) FROM modb.snippets), (SELECT count(*) FROM modb.terminators)"
        ).fetchone()
    with psycopg.connect(admin, autocommit=True) as conn:
        conn.execute(f'DROP DATABASE "{name}" WITH (FORCE)')
    print(
        f"{args.frames:,} frames: exit {load.returncode}, {snippets:,} snippets, "
        f"{terminators:,} terminators, {elapsed:.0f} s; the loading backend's peak private memory "
        f"(sampled every 0.1 s) {private / 1024:.0f} MiB, peak resident set with the shared "
        f"buffers it touched {peak / 1024:.0f} MiB"
    )


if __name__ == "__main__":
    main()
