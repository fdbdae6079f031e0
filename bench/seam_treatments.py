"""Seam treatments side by side (docs/synthesis.md, seams): the same seeded courses synthesized
with no treatment, the linear blend, inertialization, and inertialization with stance feet held
(the default since 0.27.0: modb_kernel.foot_hold; the others without it), on the default graph, and
the figures:
seams rougher than a natural step (r > 1), their 99th percentile of r, the worst pose jump, and foot
skating, beside the source clips' own.

    .venv/bin/python bench/seam_treatments.py \
        "host=/var/lib/modb/run dbname=loco user=postgres" 60 11,12,13
"""

import sys

import numpy as np

from modb.bench.synth import seeded_course
from modb.database.connection import connect
from modb.synthesis.avatar import Settings
from modb.synthesis.quality import NaturalSteps, measure
from modb.synthesis.synth import source_motions, synthesize

TREATMENTS = (
    ("none", 0, False),
    ("blend", 5, False),
    ("inertialize", 0, False),
    ("inertialize", 0, True),
)


def main(dsn: str, seconds: float, seeds: list[int]) -> None:
    with connect(dsn) as conn:
        natural = None
        print("| seam | seams with r > 1 | seam r p99 | worst pose jump | foot skating |")
        print("|---|---|---|---|---|")
        for seam, frames, locked in TREATMENTS:
            rows = []
            for seed in seeds:
                goals = seeded_course(seed, n_goals=int(seconds // 5) + 1)
                settings = Settings(seam=seam, blend_frames=frames, foot_hold=locked)
                result = synthesize(conn, goals, seconds, settings)
                if natural is None:
                    first = result.chain[0].snippet_id
                    natural = NaturalSteps.of(source_motions(conn, first, result.collection))
                rep = measure(result.strip, result.chain, goals, natural, 1.0)
                rows.append(
                    (rep.seam_share_over_one, rep.seam_r_p99, rep.pose_jump_max, rep.foot_skating)
                )
            a = np.array(rows)
            label = f"{seam}, {frames} frames" if frames else seam
            label += ", feet held" if locked else ""
            print(
                f"| {label} | {a[:, 0].mean():.1%} | {a[:, 1].mean():.2f} | "
                f"{100 * a[:, 2].max():.1f} cm | {100 * a[:, 3].mean():.1f} cm/s |"
            )
        n = natural
        print(
            f"| the source clips | {n.share_over_one:.1%} | {n.r_p999:.2f} (p99.9) | "
            f"{100 * n.pose_jump_p999:.1f} cm (p99.9) | {100 * n.foot_skating:.1f} cm/s |"
        )


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]), [int(s) for s in sys.argv[3].split(",")])
