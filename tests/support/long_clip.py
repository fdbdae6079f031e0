"""Long clips made at run time from real capture: a real file's frames played over and over."""

from __future__ import annotations

from pathlib import Path


def repeat_bvh(source: Path, target: Path, n_frames: int) -> Path:
    """Writes a BVH with source's hierarchy and its frames repeated to n_frames frames."""
    lines = source.read_text().splitlines()
    motion = next(i for i, line in enumerate(lines) if line.strip() == "MOTION")
    head = lines[: motion + 1]
    frame_time = next(line for line in lines[motion:] if line.split()[:2] == ["Frame", "Time:"])
    frames = [line for line in lines[motion + 3 :] if line.strip()]
    with open(target, "w") as out:
        out.write("\n".join(head) + f"\nFrames: {n_frames}\n{frame_time}\n")
        for i in range(n_frames):
            out.write(frames[i % len(frames)] + "\n")
    return target
