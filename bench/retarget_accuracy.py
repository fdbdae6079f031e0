"""How closely retargeting keeps the source's bone directions (CHANGELOG 0.15.0,
docs/retargeting.md): CMU 131 trials onto a Bandai rig and back, and a Bandai walk onto CMU's, each
bone's world direction against the source's at the same instants, by scipy forward kinematics (the
tests' own, support.snippet_oracle), p99 over frames in degrees; and the round trip.

    .venv/bin/python bench/retarget_accuracy.py ../shared/mocap
"""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from support.snippet_oracle import motion_world  # noqa: E402

from modb.editing.retarget import retarget_motion  # noqa: E402
from modb.loader.sources import find_sources  # noqa: E402
from modb.loader.reading import ReadOptions, read_source  # noqa: E402
from modb.resample import at_fps  # noqa: E402

BONES = {
    "thighs": [("left_hip", "left_knee"), ("right_hip", "right_knee")],
    "shins": [("left_knee", "left_ankle"), ("right_knee", "right_ankle")],
    "upper arms": [("left_shoulder", "left_elbow"), ("right_shoulder", "right_elbow")],
    "forearms": [("left_elbow", "left_wrist"), ("right_elbow", "right_wrist")],
    "trunk": [("pelvis", "neck")],
}


def read(path: Path):
    return read_source(find_sources([str(path)], "bench")[0], ReadOptions())


def directions(motion, pairs) -> np.ndarray:
    p = motion_world(motion)[0]
    sk = motion.skeleton
    at = {s: sk.index(j) for s, j in sk.joint_map.items()}
    v = np.stack([p[:, at[b]] - p[:, at[a]] for a, b in pairs], axis=1)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def p99_degrees(a, b) -> dict[str, float]:
    out = {}
    for name, pairs in BONES.items():
        cos = np.clip(np.sum(directions(a, pairs) * directions(b, pairs), axis=-1), -1, 1)
        out[name] = float(np.percentile(np.degrees(np.arccos(cos)), 99))
    return out


def main(mocap: Path) -> None:
    walk = read(sorted((mocap / "bandai-2-dev" / "data").glob("dataset-2_walk_active_*.bvh"))[0])
    trials = [read(mocap / "cmu" / "131" / f"131_0{i}.amc") for i in (1, 3, 9)]
    print(f"{'pair':40s} " + " ".join(f"{b:>10s}" for b in BONES))
    rows = []
    for cmu in trials:
        onto = retarget_motion(cmu, walk.skeleton, walk.fps, walk)
        back = retarget_motion(onto, cmu.skeleton, walk.fps, at_fps(cmu, walk.fps))
        source = at_fps(cmu, walk.fps)
        rows += [
            (f"CMU {cmu.name} -> Bandai", p99_degrees(source, onto)),
            (f"CMU {cmu.name} -> Bandai -> CMU", p99_degrees(source, back)),
        ]
    cmu = trials[0]
    onto = retarget_motion(walk, cmu.skeleton, walk.fps, cmu)
    rows.append((f"Bandai {walk.name} -> CMU", p99_degrees(walk, onto)))
    for label, figures in rows:
        print(f"{label:40s} " + " ".join(f"{figures[b]:10.2f}" for b in BONES))


if __name__ == "__main__":
    main(Path(sys.argv[1]))
