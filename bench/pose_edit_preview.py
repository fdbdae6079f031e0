"""The pose editor's preview per drag update (issue 64): POST /api/clips/ID/edit-preview of the
real `modb serve`, timed as the page sees it (the request sent, the answer read and decoded), one
request at a time as the page sends them during a drag. 50 updates of an `ik` drag (the right wrist
moved 0 to 10 cm up and 5 cm forward at 2 s, a 0.5 s blend each side) on a Bandai walk and on a CMU
16 walk, beside a baseline in the same run: 50 updates of a `rotate` of the same joint (0 to 20
degrees, the same blend), which runs no solver. Prints the median and p99 per update and the
frames and bytes each answer carries.

    .venv/bin/python bench/pose_edit_preview.py DSN [MOCAP]

DSN: a database with the extension; the two clips are loaded into collection bench/pose_preview
unless it holds them already. MOCAP: the real data (../shared/mocap by default).
"""

import subprocess
import sys
import time
from pathlib import Path

import httpx
import numpy as np
import psycopg

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from support.browser import MODB, serving  # noqa: E402

CLIPS = {
    "Bandai walk": ("bandai-2-dev", "data", "dataset-2_walk_active_001.bvh"),
    "CMU 16_15": ("cmu", "16", "16_15.amc"),
}
COLLECTION = "bench/pose_preview"
UPDATES = 50
WARMUP = 5


def clip_ids(dsn: str, mocap: Path) -> dict[str, int]:
    out = {}
    for label, parts in CLIPS.items():
        name = Path(parts[-1]).stem
        query = "SELECT clip_id FROM modb.current_clips WHERE collection = %s AND name = %s"
        with psycopg.connect(dsn) as conn:
            found = conn.execute(query, [COLLECTION, name]).fetchone()
        if found is None:
            subprocess.run([*MODB, "--dsn", dsn, "load", str(mocap.joinpath(*parts)),
                            "--collection", COLLECTION, "-q"], check=True)  # fmt: skip
            with psycopg.connect(dsn) as conn:
                found = conn.execute(query, [COLLECTION, name]).fetchone()
        out[label] = found[0]
    return out


def command(kind: str, k: int) -> dict:
    share = k / UPDATES
    if kind == "ik":
        return {"op": "ik", "joint": "right_wrist", "time": 2.0,
                "offset": [0.0, round(0.1 * share, 6), round(0.05 * share, 6)],
                "before": 0.5, "after": 0.5}  # fmt: skip
    return {"op": "rotate", "joint": "right_wrist", "time": 2.0,
            "rotation": [0.0, 0.0, round(20.0 * share, 6)],
            "before": 0.5, "after": 0.5}  # fmt: skip


def drag(client: httpx.Client, clip: int, kind: str) -> tuple[np.ndarray, int, int]:
    """(milliseconds per update, frames per answer, bytes per answer)."""
    times, frames, size = [], 0, 0
    for k in range(-WARMUP, UPDATES):
        body = {"commands": [command(kind, max(k, 1))]}
        t = time.perf_counter()
        r = client.post(f"/api/clips/{clip}/edit-preview", json=body)
        answer = r.json()
        took = (time.perf_counter() - t) * 1000
        assert r.status_code == 200, r.text
        if k >= 0:
            times.append(took)
            frames, size = answer["count"], len(r.content)
    return np.array(times), frames, size


def main() -> None:
    dsn = sys.argv[1]
    mocap = Path(sys.argv[2]) if len(sys.argv) > 2 else Path(__file__).resolve().parents[2] / (
        "shared/mocap")  # fmt: skip
    ids = clip_ids(dsn, mocap)
    print(f"{UPDATES} updates each (after {WARMUP} not counted), one request at a time")
    print("| clip | command | median ms | p99 ms | frames sent | bytes |")
    print("|---|---|---:|---:|---:|---:|")
    with serving(dsn) as address, httpx.Client(base_url=f"http://{address}", timeout=60) as client:
        for label, clip in ids.items():
            for kind in ("rotate", "ik"):
                ms, frames, size = drag(client, clip, kind)
                print(f"| {label} | {kind} | {np.median(ms):.1f} | {np.percentile(ms, 99):.1f} | "
                      f"{frames} | {size:,} |")  # fmt: skip


if __name__ == "__main__":
    main()
