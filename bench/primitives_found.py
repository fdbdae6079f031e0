"""The primitives `modb annotate --steps` finds (issue 60) on each shipped source, read from the
files (no database): per kind, how many and in how many clips, as a Markdown table.

    .venv/bin/python bench/primitives_found.py [../shared/mocap]
"""

import sys
from collections import Counter
from pathlib import Path

from modb.loader.asf import read_amc, read_asf
from modb.loader.bvh import read_bvh
from modb_kernel import primitives

KINDS = ("left_step", "right_step", "left_turning_step", "right_turning_step", "left_start",
         "right_start", "left_stop", "right_stop", "idle")  # fmt: skip


def sources(root: Path):
    b1, b2 = root / "bandai-1" / "data", root / "bandai-2-dev" / "data"
    yield "Bandai 1, all", [read_bvh(str(p)) for p in sorted(b1.glob("*.bvh"))]
    for style in ("active", "elderly", "exhausted"):
        files = [p for kind in ("walk", "walk-turn-left", "walk-turn-right", "run")
                 for p in sorted(b2.glob(f"dataset-2_{kind}_{style}_*.bvh"))]  # fmt: skip
        yield f"Bandai 2 {style} locomotion", [read_bvh(str(p)) for p in files]
    actions = sorted(b2.glob("dataset-2_raise-*.bvh")) + sorted(b2.glob("dataset-2_wave-*.bvh"))
    yield "Bandai 2 hand actions", [read_bvh(str(p)) for p in actions]
    for subject in ("16", "131"):
        folder = root / "cmu" / subject
        asf = read_asf(str(folder / f"{subject}.asf"))
        yield f"CMU {subject}", [read_amc(str(p), asf) for p in sorted(folder.glob("*.amc"))]


def main() -> None:
    root = Path(sys.argv[1] if len(sys.argv) > 1 else "../shared/mocap")
    short = [k.replace("left_", "L ").replace("right_", "R ").replace("_step", "").replace(
        "turning", "turn") for k in KINDS]  # fmt: skip
    print("| source | clips | " + " | ".join(short) + " |")
    print("|---|---:|" + "---:|" * len(KINDS))
    for name, motions in sources(root):
        found, clips = Counter(), Counter()
        for m in motions:
            sk = m.skeleton
            kinds = [p[0] for p in primitives.find(sk.parents, sk.offsets, m.rotations,
                                                   m.translations, sk.translated, sk.names,
                                                   sk.joint_map, m.fps)]  # fmt: skip
            found.update(kinds)
            clips.update(set(kinds))
        cells = [f"{found[k]} ({clips[k]})" if found[k] else "0" for k in KINDS]
        print(f"| {name} | {len(motions)} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
