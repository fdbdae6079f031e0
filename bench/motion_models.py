"""Motion models of the shipped walks' steps (BENCHMARKS.md "Motion models"): on a database
holding Bandai dataset 2's walks and walk-turns and CMU 16's trials, each in its own collection,
their steps annotated (`modb annotate --steps`), the user's path for `left_step` and `right_step` of
each: `modb model build NAME --collection C --primitive P --report-json F` (aligning first), then
`SELECT * FROM modb.sample_motion(NAME, 10, seed)` with the server's default settings, and ten
samples written as glb. Builds are timed beside reading the processed data they learn from,
sampling beside reading the model's row, in the same run; the reports land in OUT (one JSON file
per model).

    .venv/bin/python bench/motion_models.py "host=/var/lib/modb/run dbname=DB user=postgres" OUT 3
"""

import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

from modb.database.connection import connect
from modb.models.examples import read_inputs

SOURCES = [
    ("bandai2", "Bandai dataset 2 walks and walk-turns"),
    ("cmu16", "CMU 16 walks and turns"),
]
PRIMITIVES = ("left_step", "right_step")
SAMPLE_CALLS = 50
LATEST = "SELECT data FROM modb.models WHERE name = %s ORDER BY version DESC LIMIT 1"


def percentile(values, q):
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(q / 100 * (len(ordered) - 1))))]


def modb(dsn, *args):
    t = time.perf_counter()
    subprocess.run([sys.executable, "-m", "modb.cli", "--dsn", dsn, *map(str, args)], check=True,
                   capture_output=True, text=True)  # fmt: skip
    return time.perf_counter() - t


def main(dsn: str, out: Path, rounds: int) -> None:
    out.mkdir(parents=True, exist_ok=True)
    for collection, about in SOURCES:
        for primitive in PRIMITIVES:
            name = f"{collection}_{primitive}"
            report = out / f"{name}.json"
            builds, reads = [], []
            for k in range(rounds):
                last = k == rounds - 1
                builds.append(modb(dsn, "model", "build", name, "--collection", collection,
                                   "--primitive", primitive, "-q",
                                   *(["--report-json", report] if last else [])))  # fmt: skip
                with connect(dsn) as conn:
                    t = time.perf_counter()
                    read_inputs(conn, collection, primitive)
                    reads.append(time.perf_counter() - t)
            samples, rows = [], []
            with connect(dsn) as conn:
                for seed in range(SAMPLE_CALLS):
                    t = time.perf_counter()
                    conn.execute(
                        "SELECT * FROM modb.sample_motion(%s, 10, %s)", [name, seed]
                    ).fetchall()
                    samples.append(time.perf_counter() - t)
                    t = time.perf_counter()
                    conn.execute(LATEST, [name]).fetchall()
                    rows.append(time.perf_counter() - t)
            glb = out / f"{name}.glb"
            modb(dsn, "model", "sample", name, "-n", "10", "--seed", "1", "--out", glb)
            r = json.loads(report.read_text())
            rec, lik, slide = r["reconstruction"], r["likelihood"], r["foot_sliding"]
            rot, nov = r["rotation_range"], r["novelty"]
            print(f"### {about}: {primitive}")
            print(
                f"- {r['examples']} examples ({r['mirrored_examples']} mirrored); "
                f"{r['spatial_components']} spatial + {r['temporal_components']} temporal "
                f"components; {r['mixture_components']} {r['mixture_covariance']} Gaussians"
            )
            build, read = statistics.median(builds), statistics.median(reads)
            print(
                f"- build (aligned already; no report): median {build:.1f} s over {rounds}; "
                f"reading its processed data: median {read:.2f} s; ratio {build / read:.0f}"
            )
            sample, row = statistics.median(samples), statistics.median(rows)
            print(
                f"- modb.sample_motion(name, 10, seed), {SAMPLE_CALLS} seeds: median "
                f"{sample * 1e3:.0f} ms, p99 {percentile(samples, 99) * 1e3:.0f} ms; reading the "
                f"model's row: median {row * 1e3:.1f} ms; ratio {sample / row:.0f}"
            )
            print(
                f"- leave-one-out ({rec['held_out']} held out): {rec['error_cm']:.2f} cm against "
                f"the mean motion's {rec['mean_motion_error_cm']:.2f} cm (ratio "
                f"{rec['ratio']:.2f}; worst joint {rec['worst_joint_ratio']:.2f})"
            )
            print(
                f"- held-out log-likelihood: mixture {lik['mixture']:.1f}, single Gaussian "
                f"{lik['single_gaussian']:.1f}"
            )
            print(
                f"- foot sliding: samples {slide['samples_m_per_s']:.3f} m/s, training "
                f"{slide['training_m_per_s']:.3f} m/s (ratio {slide['ratio']:.2f}); rotation "
                "range: "
                f"worst {rot['worst_joint']} {rot['samples_degrees']:.1f} against "
                f"{rot['training_degrees']:.1f} degrees; novelty: {nov['samples_nn_cm']:.2f} cm "
                f"against {nov['training_nn_cm']:.2f} cm (ratio {nov['ratio']:.2f})"
            )
            print(f"- all targets met: {r['pass']}\n", flush=True)


if __name__ == "__main__":
    main(sys.argv[1], Path(sys.argv[2]), int(sys.argv[3]))
