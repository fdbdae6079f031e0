"""The benchmark's largest database: the real clips again at other playback speeds.

Rotations are slerped and translations interpolated; the copies are stored as clips of their own
under `resampled-x<speed>/` until there are as many snippets as asked. Reported as such: these are
not new captures, only denser coverage of the same motions.
"""

from __future__ import annotations

import sys
import numpy as np
import psycopg
from tqdm import tqdm

from modb.loader.ingest import store_motion

from modb.clips import read_motion
from modb.resample import sampled
from modb.motion import Motion

# Around 1x, alternating slower and faster, so each step adds gaits a little off the captured ones.
SPEEDS = (0.8, 1.25, 0.9, 1.1, 0.85, 1.15, 0.95, 1.05)
# the copies' collections: resampled-x<speed>/<the original's path>
COLLECTION_PREFIX = "resampled-x"


def at_speed(motion: Motion, speed: float) -> Motion:
    """The motion played `speed` times as fast at the same frame rate: frame k shows time k x speed
    / fps of the original."""
    if not speed > 0:
        raise ValueError(f"speed must be positive, got {speed}")
    last = motion.n_frames - 1
    # Never past the end by rounding.
    return sampled(motion, np.minimum(np.arange(int(last / speed + 1e-9) + 1) * speed, last))


def resampled_snippets(conn: psycopg.Connection) -> int:
    """How many of the database's snippets are speed-resampled copies."""
    return conn.execute(
        "SELECT count(*) FROM modb.snippets s JOIN modb.clips c ON c.id = s.clip_id "
        "WHERE modb.collection_path(c.collection_id) LIKE %s",
        [COLLECTION_PREFIX + "%"],
    ).fetchone()[0]


def add_resampled_clips(conn: psycopg.Connection, size: int, seed: int, progress=None) -> int:
    """Adds speed-resampled copies of the clips until there are at least `size` snippets.

    A copy is mirrored when its original is; one transaction per clip. Returns the snippet count.
    """
    total = conn.execute("SELECT count(*) FROM modb.snippets").fetchone()[0]
    originals = conn.execute(
        "SELECT c.id, modb.collection_path(c.collection_id), bool_or(s.mirrored) FROM modb.clips c "
        "JOIN modb.snippets s ON s.clip_id = c.id "
        "WHERE modb.collection_path(c.collection_id) NOT LIKE %s GROUP BY c.id ORDER BY c.id",
        [COLLECTION_PREFIX + "%"],
    ).fetchall()
    order = np.random.default_rng(seed).permutation(len(originals))
    with tqdm(
        total=size, initial=total, unit=" snippets", file=sys.stderr, disable=progress is None
    ) as bar:
        for speed in SPEEDS:
            for k in order:
                if total >= size:
                    return total
                clip_id, path, mirrored = originals[k]
                motion = at_speed(read_motion(conn, clip_id), speed)
                motion.meta = {"resampled_from": {"clip": clip_id, "speed": speed}}
                added = store_motion(
                    conn,
                    motion,
                    f"{COLLECTION_PREFIX}{speed:.2f}/{path}",
                    f"speed {speed}",
                    snippets=True,
                    mirrored=mirrored,
                ).snippets
                total += added
                bar.update(added)
    return total
