"""`modb bench synth`: a seeded course of goals 1-20 m apart, synthesized for N s, and its report.

The issue's relaxation aim is stated on such a course (10 minutes on Bandai dataset 2 locomotion
with the shipped default profile); this makes it reproducible: same seed, same goals, same chain.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import psycopg

from modb.database.cluster import Cluster
from modb.demo.data import locomotion_files

from .commands import Commands

DATABASE = "modb_bench_synth"

Goal = tuple[float, float]


def seeded_course(seed: int, n_goals: int, near: float = 1.0, far: float = 20.0) -> list[Goal]:
    """Goals from the origin, each `near`-`far` metres from the one before in a random direction."""
    rng = np.random.default_rng(seed)
    x, z = 0.0, 0.0
    goals = []
    for _ in range(n_goals):
        distance, angle = rng.uniform(near, far), rng.uniform(-math.pi, math.pi)
        x, z = x + distance * math.sin(angle), z + distance * math.cos(angle)
        goals.append((round(x, 3), round(z, 3)))
    return goals


GRAPH = "locomotion"  # the transition graph locomotion_database builds


def locomotion_database(folder: Path, commands: Commands) -> str:
    """A fresh database on the embedded cluster holding the locomotion clips of a Bandai dataset 2
    folder, and their transition graph GRAPH (default profile)."""
    files = [str(f) for f in locomotion_files(folder)]
    if not files:
        raise RuntimeError(
            f"no Bandai dataset 2 locomotion files (dataset-2_walk_*.bvh, ...) in {folder}"
        )
    cluster = Cluster.default()
    cluster.start()
    with psycopg.connect(cluster.dsn("postgres"), autocommit=True) as admin:
        admin.execute(f'DROP DATABASE IF EXISTS "{DATABASE}" WITH (FORCE)')
        admin.execute(f'CREATE DATABASE "{DATABASE}"')
    with psycopg.connect(cluster.dsn(DATABASE), autocommit=True) as conn:
        conn.execute("CREATE EXTENSION modb CASCADE")
    if commands.load(cluster.dsn(DATABASE), files, "locomotion") != 0:
        raise RuntimeError(f"loading {folder} failed")
    if commands.build_graph(cluster.dsn(DATABASE), GRAPH, "locomotion") != 0:
        raise RuntimeError(f"building the transition graph of {folder} failed")
    return cluster.dsn(DATABASE)
