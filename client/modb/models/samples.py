"""A model's samples as motions of its skeleton (modb.sample_motion draws them in the server), and
written as engines take them: BVH, one file per sample, or glb, one animation per sample."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import psycopg

from modb.database import pgarray
from modb.motion import Motion, Skeleton

SAMPLES = """
SELECT sample, fps, rotations, translations FROM modb.sample_motion(%s, %s, %s, %s) ORDER BY sample
"""
SKELETON = """
SELECT s.name, s.hierarchy, s.joint_map, s.mirror_pairs FROM modb.models m
  JOIN modb.skeletons s ON s.id = m.skeleton_id
 WHERE m.name = %s AND m.kind = 'motion_primitive' AND (%s::int IS NULL OR m.version = %s)
 ORDER BY m.version DESC LIMIT 1
"""


def sample_motions(conn: psycopg.Connection, name: str, n: int, seed: int,
                   version: int | None = None) -> list[Motion]:  # fmt: skip
    """n samples of the model (its latest version, or the one given), named NAME_sample_NN."""
    pgarray.register(conn)
    with conn.cursor(binary=True) as cur:
        rows = cur.execute(SAMPLES, [name, n, seed, version]).fetchall()
    skeleton_row = conn.execute(SKELETON, [name, version, version]).fetchone()
    skeleton = Skeleton.from_row(skeleton_row[1], skeleton_row[2], skeleton_row[3], skeleton_row[0])
    width = max(2, len(str(n)))
    out = []
    for k, fps, rotations, translations in rows:
        r = np.asarray(rotations, dtype=np.float64)
        t = (np.zeros((len(r), 0, 3)) if translations is None
             else np.asarray(translations, dtype=np.float64))  # fmt: skip
        out.append(Motion(skeleton, float(fps), r, t, f"{name}_sample_{k:0{width}d}",
                          meta={"model": name, "seed": seed, "sample": k}))  # fmt: skip
    return out


def numbered(path: str, k: int, n: int) -> str:
    """FILE.bvh -> FILE_01.bvh (as many digits as n needs, at least two)."""
    base, ext = os.path.splitext(path)
    return f"{base}_{k:0{max(2, len(str(n)))}d}{ext}"


def write_samples(conn: psycopg.Connection, name: str, n: int, seed: int, version: int | None,
                  out: str) -> list[str]:  # fmt: skip
    """Writes the samples to `out` (see the module); returns the files written."""
    from modb.bvh_export import write_bvh_file
    from modb.gltf_export import is_gltf_name, write_gltf_file

    suffix = Path(out).suffix.lower()
    if suffix != ".bvh" and not is_gltf_name(out):
        raise ValueError(f"{out}: name a .bvh, .glb or .gltf file")
    motions = sample_motions(conn, name, n, seed, version)
    if suffix == ".bvh":
        files = [numbered(out, k + 1, n) for k in range(len(motions))]
        for motion, path in zip(motions, files):
            write_bvh_file(motion, path)
        return files
    write_gltf_file(motions[0], out, also=motions[1:])
    return [out]
