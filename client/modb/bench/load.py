"""`modb bench load`: on real files, parse speed beside bvhio's readAsBvh, and durable load speed.

Every figure is measured in the same run as its baseline (the machine is shared and noisy): parsers
alternate file by file over several rounds, and the ratio is taken per round.
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path

import numpy as np
import psycopg

from modb.database.connection import connect
from modb.loader.bvh import read_bvh
from modb.loader.ingest import load_files
from modb.loader.sources import find_sources
from modb.loader.reading import ReadOptions


def _percentiles(values: list[float]) -> tuple[float, float]:
    return float(np.median(values)), float(np.percentile(values, 99))


def _motion_lines_only(path: str) -> np.ndarray:
    """Ceiling for numpy readers: frame lines through loadtxt, no hierarchy, checks or hash."""
    with open(path) as f:
        text = f.read()
    return np.loadtxt(text[text.index("Frame Time:") :].splitlines()[1:], ndmin=2)


def bench_parse(files: list[Path], rounds: int) -> dict:
    import bvhio  # the baseline: optional ('.[test]'), so `modb bench load` checks for it first

    frames = {f: read_bvh(str(f)).n_frames for f in files}  # warm the page cache and imports
    total = sum(frames.values())
    parsers = {"bvhio": bvhio.readAsBvh, "modb": read_bvh, "loadtxt": _motion_lines_only}
    per_file: dict[str, list[float]] = {name: [] for name in parsers}
    rates: dict[str, list[float]] = {name: [] for name in parsers}
    for _ in range(rounds):
        spent = dict.fromkeys(parsers, 0.0)
        for f in files:
            for name, parse in parsers.items():
                t = time.perf_counter()
                parse(str(f))
                dt = time.perf_counter() - t
                spent[name] += dt
                per_file[name].append(dt * 1000)
        for name in spent:
            rates[name].append(total / spent[name])
    ratios = {name: [m / b for m, b in zip(rates[name], rates["bvhio"])] for name in parsers}
    return {
        "files": len(files),
        "frames": total,
        "rounds": rounds,
        "rates": rates,
        "ratios": ratios,
        "per_file_ms": {k: _percentiles(v) for k, v in per_file.items()},
    }


def bench_load(files: list[Path], rounds: int, admin_dsn: str, make_dsn) -> dict:
    rates, per_file = [], []
    sync = None
    for r in range(rounds):
        name = f"modb_bench_load_{r}"
        with psycopg.connect(admin_dsn, autocommit=True) as admin:
            admin.execute(f'DROP DATABASE IF EXISTS "{name}"')
            admin.execute(f'CREATE DATABASE "{name}"')
        try:
            with psycopg.connect(make_dsn(name), autocommit=True) as c:
                c.execute("CREATE EXTENSION modb CASCADE")
            with connect(make_dsn(name)) as conn:
                sync = conn.execute("SHOW synchronous_commit").fetchone()[0]
                sources = find_sources([str(f) for f in files], "bench")
                times: list[float] = []
                last = [time.perf_counter()]

                def tick(_result) -> None:
                    now = time.perf_counter()
                    times.append((now - last[0]) * 1000)
                    last[0] = now

                summary = load_files(
                    conn, sources, ReadOptions(), keep_going=False, progress=tick, snippets=False
                )
                assert not summary.failed, summary.failed[0].message
                rates.append(summary.frames / summary.elapsed)
                per_file.extend(times)
        finally:
            with psycopg.connect(admin_dsn, autocommit=True) as admin:
                admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
    return {"rates": rates, "per_file_ms": _percentiles(per_file), "synchronous_commit": sync}


def report(folder: Path, parse: dict, load: dict) -> str:
    b = parse["rates"]["bvhio"]
    pb = parse["per_file_ms"]["bvhio"]

    def parse_row(label: str, name: str) -> str:
        p50, p99 = parse["per_file_ms"][name]
        return (
            f"| {label} | {statistics.median(parse['rates'][name]):,.0f} | {p50:.2f} / {p99:.2f} | "
            f"{statistics.median(parse['ratios'][name]):.2f}x |"
        )

    lines = [
        f"Data: {folder} ({parse['files']} files, {parse['frames']:,} frames), {parse['rounds']} "
        f"rounds.",
        "",
        "| what | frames/s (median of rounds) | per file ms p50 / p99 | vs bvhio (median ratio) |",
        "|---|---|---|---|",
        f"| parse: bvhio readAsBvh (baseline) | {statistics.median(b):,.0f} | {pb[0]:.2f} / "
        f"{pb[1]:.2f} | 1.00x |",
        parse_row("parse: modb read_bvh", "modb"),
        parse_row(
            "parse: numpy loadtxt of the frame lines alone (ceiling, not a reader)", "loadtxt"
        ),
        f"| load: parse + store, one committed transaction per file "
        f"(synchronous_commit={load['synchronous_commit']}) "
        f"| {statistics.median(load['rates']):,.0f} | {load['per_file_ms'][0]:.2f} / "
        f"{load['per_file_ms'][1]:.2f} | "
        f"{statistics.median(load['rates']) / statistics.median(b):.2f}x |",
    ]
    return "\n".join(lines)
