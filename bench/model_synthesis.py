"""Synthesis from graphs of models (BENCHMARKS.md "Synthesis from models"): on the database of
bench/motion_models.py (Bandai dataset 2's walks and walk-turns, CMU 16's trials, their step models
built), a graph of each collection's step models (`modb model graph`), then the user's path: `SELECT
* FROM modb.synthesize_from_models(graph, goals, seconds, seed)` with the server's default settings,
over a course fixed before any tuning. Timed per second of motion, beside the baseline in the same
run: decoding as many steps with modb.sample_motion (no search, no joining). The strips' quality
(modb.synthesis.from_models.measure) and the server's report land in OUT.

    .venv/bin/python bench/model_synthesis.py "host=/var/lib/modb/run dbname=DB user=postgres" OUT 5
"""

import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

from modb.database.connection import connect
from modb.synthesis.from_models import Source, measure, synthesize

COURSE = [(0.0, 6.0), (6.0, 8.0), (6.0, 2.0), (0.0, 0.0), (-6.0, 4.0), (-2.0, 10.0)]
SECONDS = 60.0
COLLECTIONS = ("bandai2", "cmu16")


def percentile(values, q):
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(q / 100 * (len(ordered) - 1))))]


def main(dsn: str, out: Path, rounds: int) -> None:
    out.mkdir(parents=True, exist_ok=True)
    for collection in COLLECTIONS:
        graph = f"{collection}_walk"
        subprocess.run([sys.executable, "-m", "modb.cli", "--dsn", dsn, "model", "graph", graph,
                        "--collection", collection, "--model", f"{collection}_left_step",
                        "--model", f"{collection}_right_step"], check=True,
                       capture_output=True)  # fmt: skip
        with connect(dsn) as conn:
            models = conn.execute(
                "SELECT n.value->>'model' FROM modb.graphs g, jsonb_each(g.data->'nodes') n "
                "WHERE g.name = %s AND g.kind = 'models' ORDER BY n.key", [graph]
            ).fetchall()  # fmt: skip
            runs, decodes, strip = [], [], None
            for k in range(rounds):
                t = time.perf_counter()
                strip = synthesize(conn, graph, COURSE, SECONDS, seed=k)
                runs.append(time.perf_counter() - t)
                steps = len(strip.report["steps"])
                t = time.perf_counter()
                for (name,) in models:  # as many steps decoded, half from each model
                    conn.execute("SELECT count(*) FROM modb.sample_motion(%s, %s, %s)",
                                 [name, max(1, steps // len(models)), k]).fetchone()  # fmt: skip
                decodes.append(time.perf_counter() - t)
            figures = measure(strip, Source.of(conn, graph))
        walked = figures["stood_from_seconds"] or figures["seconds"]
        result = {
            "collection": collection,
            "course": COURSE,
            "seconds": SECONDS,
            "walked_seconds": walked,
            "rounds": rounds,
            "synthesis_s_median": statistics.median(runs),
            "synthesis_s_p99": percentile(runs, 99),
            "compute_per_motion_second": statistics.median(runs) / walked,
            "decode_only_s_median": statistics.median(decodes),
            "ratio_to_decode_only": statistics.median(runs) / statistics.median(decodes),
            "figures": figures,
        }
        (out / f"{collection}.json").write_text(json.dumps(result, indent=2) + "\n")
        print(json.dumps({k: v for k, v in result.items() if k != "figures"}, indent=2))
        print(json.dumps({k: figures[k] for k in ("aims", "constraint_error_median",
                                                  "pose_jump_max", "source_pose_jump_p999",
                                                  "stance_sliding", "source_stance_sliding",
                                                  "foot_skating", "source_foot_skating")},
                         indent=2))  # fmt: skip
        for g in figures["goals"]:
            print(g)


if __name__ == "__main__":
    main(sys.argv[1], Path(sys.argv[2]), int(sys.argv[3]) if len(sys.argv) > 3 else 5)
