"""Steps found per clip kind, and the alignment of each primitive (BENCHMARKS.md "Steps and their
alignment"): on a database holding the shipped walks (`modb load` of Bandai dataset 2's walks and
walk-turns, dataset 1's walks, CMU 16's trials, each into its own collection), the user's path:
`SELECT * FROM modb.annotate_steps(clip)` per clip and `SELECT * FROM modb.align_primitive(p, c)`,
with the server's default settings. Each is timed beside a baseline run in the same process: reading
the frames the call reads (the clip's, or every example's segment), so the ratio says what finding
and aligning add to reading.

    .venv/bin/python bench/steps_and_alignment.py \
        "host=/var/lib/modb/run dbname=steps_all user=postgres" 3
"""

import re
import statistics
import sys
import time

import psycopg

from modb.database.connection import connect

KINDS = [  # (kind, collection, clip-name pattern)
    ("Bandai 2 walk", "bandai2", r"_walk_"),
    ("Bandai 2 walk-turn-left", "bandai2", r"walk-turn-left"),
    ("Bandai 2 walk-turn-right", "bandai2", r"walk-turn-right"),
    ("Bandai 1 walk (straight)", "bandai1", r"_walk_"),
    ("Bandai 1 walk-back/left/right", "bandai1", r"_walk-"),
    ("CMU 16 walk", "cmu16", r"^16_(15|16|21|22|31|32|47|58)$"),
    ("CMU 16 veer", "cmu16", r"^16_(1[1-4]|2[3-6])$"),
    ("CMU 16 90-degree turn", "cmu16", r"^16_(1[7-9]|20|2[7-9]|30)$"),
    ("CMU 16 slow walk that stops", "cmu16", r"^16_(33|34)$"),
    ("CMU 16 run/jog that stops", "cmu16", r"^16_(08|57)$"),
]


def percentile(values, q):
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(q / 100 * (len(ordered) - 1))))]


def timed(conn, query, params):
    t = time.perf_counter()
    conn.execute(query, params).fetchall()
    return time.perf_counter() - t


def main(dsn: str, rounds: int) -> None:
    with connect(dsn) as conn:
        clips = conn.execute(
            "SELECT clip_id, collection, name, n_frames, fps FROM modb.current_clips "
            "ORDER BY clip_id"
        ).fetchall()
        per_clip, base_clip, counts = [], [], {}
        for clip_id, collection, name, n_frames, fps in clips:
            base_clip.append(
                timed(
                    conn,
                    "SELECT rotations, translations FROM modb.clip_versions "
                    "WHERE clip_id = %s ORDER BY version DESC LIMIT 1",
                    [clip_id],
                )
            )
            t = time.perf_counter()
            steps = conn.execute("SELECT name FROM modb.annotate_steps(%s)", [clip_id]).fetchall()
            per_clip.append(time.perf_counter() - t)
            counts[clip_id] = (collection, name, len(steps), n_frames / fps)
        print(
            f"annotate_steps, {len(clips)} clips: "
            f"median {statistics.median(per_clip) * 1000:.1f} ms, "
            f"p99 {percentile(per_clip, 99) * 1000:.1f} ms; reading the clip's frames: median "
            f"{statistics.median(base_clip) * 1000:.1f} ms; ratio of medians "
            f"{statistics.median(per_clip) / statistics.median(base_clip):.1f}"
        )
        print("| clips | kind | steps per clip, median (min-max) | steps per second of motion |")
        print("|---|---|---|---|")
        for kind, collection, pattern in KINDS:
            rows = [c for c in counts.values() if c[0] == collection and re.search(pattern, c[1])]
            if not rows:
                continue
            n = [r[2] for r in rows]
            rate = sum(n) / sum(r[3] for r in rows)
            print(
                f"| {len(rows)} | {kind} | {statistics.median(n):g} ({min(n)}-{max(n)}) "
                f"| {rate:.2f} |"
            )
        print(
            "| collection | primitive | examples | reference frames | align, median of "
            f"{rounds} (p99) | reading the examples | ratio |"
        )
        print("|---|---|---|---|---|---|---|")
        for collection in ("bandai2", "bandai1", "cmu16"):
            for primitive in ("left_step", "right_step"):
                runs, bases = [], []
                try:
                    with conn.transaction():  # refused when the examples are on several skeletons
                        conn.execute(
                            "SELECT * FROM modb.align_primitive(%s, %s)", [primitive, collection]
                        )
                except psycopg.Error as e:
                    print(
                        f"| {collection} | {primitive} | refused: {e.diag.message_primary} "
                        "| | | | |"
                    )
                    continue
                for _ in range(rounds):
                    conn.execute(
                        "DELETE FROM modb.processed_data WHERE primitive = %s "
                        "AND collection_id = modb.find_collection(%s)",
                        [primitive, collection],
                    )  # every run aligns all
                    bases.append(
                        timed(
                            conn,
                            """
                        SELECT v.rotations[(a->>'start')::int + 1:(a->>'end')::int + 1]
                          FROM modb.current_clips c JOIN modb.clips k ON k.id = c.clip_id
                          JOIN modb.clip_versions v USING (clip_id, version),
                               jsonb_array_elements(v.meta->'annotations') a
                         WHERE k.collection_id = ANY (modb.collection_subtree(%s))
                           AND a->>'name' = %s""",
                            [collection, primitive],
                        )
                    )
                    runs.append(
                        timed(
                            conn,
                            "SELECT * FROM modb.align_primitive(%s, %s)",
                            [primitive, collection],
                        )
                    )
                examples, frames = conn.execute(
                    "SELECT count(*), max(n_frames) FROM modb.processed_data_status "
                    "WHERE collection = %s AND primitive = %s",
                    [collection, primitive],
                ).fetchone()
                print(
                    f"| {collection} | {primitive} | {examples} | {frames} | "
                    f"{statistics.median(runs):.2f} s ({percentile(runs, 99):.2f}) | "
                    f"{statistics.median(bases) * 1000:.0f} ms | "
                    f"{statistics.median(runs) / statistics.median(bases):.0f} |"
                )


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 3)
