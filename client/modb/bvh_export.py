"""Writing a Motion as BVH in its skeleton's source units and, for BVH sources, channel layout."""

from __future__ import annotations

import io
import os

import numpy as np

from modb_kernel import quaternion

from modb.motion import Joint, Motion
from modb.output import open_output

# For sources without BVH channels (ASF/AMC). Their stored rotations C M C^-1 turn about any axis
# even for a one-dof bone, so every rotating joint gets all three channels.
_ROTATION_CHANNELS = ["Zrotation", "Yrotation", "Xrotation"]


def _channels(joint: Joint, translated: bool, source_format: str) -> list[str]:
    if source_format == "bvh":
        return list(joint.channels)
    positions = ["Xposition", "Yposition", "Zposition"] if translated else []
    return positions + (_ROTATION_CHANNELS if joint.rotation_order else [])


def write_bvh(motion: Motion, out: io.TextIOBase, precision: int = 6) -> None:
    sk = motion.skeleton
    scale = 1.0 / sk.unit_m
    translated = sk.translated
    layout = [_channels(j, k in translated, sk.source_format) for k, j in enumerate(sk.joints)]
    children: dict[int, list[int]] = {k: [] for k in range(len(sk.joints))}
    for k, j in enumerate(sk.joints):
        if j.parent >= 0:
            children[j.parent].append(k)

    def vec(v) -> str:
        return " ".join(f"{x * scale:.{precision}f}" for x in v)

    visited: list[int] = []  # BVH lists motion columns in hierarchy (depth-first) order

    def emit(k: int, depth: int) -> None:
        visited.append(k)
        pad = "\t" * depth
        j = sk.joints[k]
        out.write(f"{pad}{'ROOT' if j.parent < 0 else 'JOINT'} {j.name}\n{pad}{{\n")
        out.write(f"{pad}\tOFFSET {vec(j.offset)}\n")
        out.write(f"{pad}\tCHANNELS {len(layout[k])}{''.join(' ' + c for c in layout[k])}\n")
        for c in children[k]:
            emit(c, depth + 1)
        if j.end_site is not None:
            out.write(f"{pad}\tEnd Site\n{pad}\t{{\n{pad}\t\tOFFSET {vec(j.end_site)}\n{pad}\t}}\n")
        out.write(f"{pad}}}\n")

    out.write("HIERARCHY\n")
    emit(0, 0)
    frame_time = (
        motion.meta.get("load_params", {}).get("frame_time")
        or motion.meta.get("frame_time")
        or 1.0 / motion.fps
    )
    out.write(f"MOTION\nFrames: {motion.n_frames}\nFrame Time: {frame_time:.10g}\n")
    columns = []
    for k in visited:
        j = sk.joints[k]
        if not layout[k]:
            continue
        local = (
            motion.translations[:, translated.index(k)]
            if k in translated
            else np.broadcast_to(np.array(j.offset), (motion.n_frames, 3))
        ) * scale
        order = "".join(c[0] for c in layout[k] if c.endswith("rotation"))
        angles = np.degrees(quaternion.to_euler(motion.rotations[:, k], order)) if order else None
        for c in layout[k]:
            axis = "XYZ".index(c[0])
            columns.append(
                local[:, axis] if c.endswith("position") else angles[:, order.index(c[0])]
            )
    np.savetxt(out, np.stack(columns, axis=1), fmt=f"%.{precision}f", delimiter=" ")


def write_bvh_file(motion: Motion, path: str | os.PathLike, allow_stdout: bool = False) -> None:
    """Writes `motion` as BVH to `path` through open_output (so a regular file is replaced whole,
    a device or FIFO written into, a symlink followed); `-` is standard output if `allow_stdout`."""
    with open_output(path, allow_stdout=allow_stdout) as f:
        write_bvh(motion, f)
