"""The same batch of jobs with 1 worker and with 2 (separate processes, as two machines would run
them): wall time and the ratio, each worker's CPU and the database's CPU per job (BENCHMARKS.md
"Jobs on 1 and 2 workers"), queued before the workers start. The batch, either:

- N transition graph builds over one collection (`modb graph build --background`):

    .venv/bin/python bench/job_workers.py "host=/var/lib/modb/run dbname=mix16 user=postgres" mixc 4

- every clip of a collection retargeted onto a skeleton (a job per two clips, mirror images cut
  too), and two graph builds over the clips made, each waiting for every retargeting (`--after`):

    .venv/bin/python bench/job_workers.py "host=/var/lib/modb/run dbname=mix16 user=postgres" \
        retarget:cmu16:1 2
"""

import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

from modb.database.connection import connect
from modb.jobs.submit import submit

TICK = os.sysconf("SC_CLK_TCK")


def postgres_cpu() -> dict[int, float]:
    """CPU seconds so far of every postgres process (server and backends), by pid."""
    out = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)
            if "postgres" not in fields[0]:
                continue
            values = fields[1].split()
            out[int(stat.parent.name)] = (int(values[11]) + int(values[12])) / TICK
        except (OSError, IndexError, ValueError):
            continue
    return out


def queue_graphs(dsn: str, collection: str, jobs: int, tag: str) -> list[int]:
    ids = []
    for i in range(jobs):
        r = subprocess.run(
            [sys.executable, "-m", "modb.cli", "--dsn", dsn, "graph", "build", f"bench {tag} {i}",
             "--collection", collection, "--background"],
            capture_output=True, text=True, check=True,
        )  # fmt: skip
        ids.append(int(r.stdout))
    return ids


def queue_retargets(dsn: str, source: str, skeleton: int, tag: str) -> list[int]:
    """A retargeting job per clip of `source` into a collection of this run's, then two graph
    builds over it that wait for them all."""
    made = f"bench/{tag}"
    with connect(dsn) as conn:
        who = conn.execute("SELECT current_user").fetchone()[0]
        clips = [
            c
            for (c,) in conn.execute(
                "SELECT clip_id FROM modb.current_clips WHERE collection = %s ORDER BY clip_id",
                [source],
            )
        ]
        ids = [  # two clips a job: the batch stays under a submitter's cap on queued jobs
            submit(conn, "retarget", who, clips=clips[k : k + 2], skeleton=skeleton,
                   collection=made, fps=None, mirrored=True)
            for k in range(0, len(clips), 2)
        ]  # fmt: skip
        return ids + [
            submit(conn, "build_graph", who, after=ids, name=f"bench {tag} {i}", collection=made,
                   min_turn_degrees=0.0)
            for i in range(2)
        ]  # fmt: skip


def run(dsn: str, batch: str, jobs: int, workers: int, round_: int) -> dict:
    tag = f"{workers}w {round_} {os.getpid()}"
    if batch.startswith("retarget:"):
        _, source, skeleton = batch.split(":")
        ids = queue_retargets(dsn, source, int(skeleton), tag)
    else:
        ids = queue_graphs(dsn, batch, jobs, tag)
    seen: dict[int, float] = {}
    base = postgres_cpu()
    start = time.monotonic()
    procs = [
        subprocess.Popen(
            [sys.executable, "-m", "modb.cli", "--dsn", dsn, "worker"], stderr=subprocess.DEVNULL
        )  # fmt: skip
        for _ in range(workers)
    ]
    with connect(dsn) as conn:
        while True:
            for pid, cpu in postgres_cpu().items():
                seen[pid] = max(seen.get(pid, 0.0), cpu)
            left, failed = conn.execute(
                "SELECT count(*) FILTER (WHERE state IN ('waiting', 'queued', 'running')), "
                "       string_agg(error, '; ') FILTER (WHERE state <> 'done') "
                "  FROM modb.jobs WHERE id = ANY(%s)",
                [ids],
            ).fetchone()
            if failed:
                for p in procs:
                    p.terminate()
                raise SystemExit(f"a job failed: {failed}")
            if not left:
                break
            time.sleep(0.2)
        wall = time.monotonic() - start
        per_job = conn.execute(
            "SELECT kind, extract(epoch FROM finished_at - started_at) FROM modb.jobs "
            "WHERE id = ANY(%s)",
            [ids],
        ).fetchall()
    worker_cpu = 0.0
    for p in procs:
        p.terminate()
        _, _, usage = os.wait4(p.pid, 0)  # the worker's CPU (a killed child's is not counted)
        worker_cpu += usage.ru_utime + usage.ru_stime
    db_cpu = sum(cpu - base.get(pid, 0.0) for pid, cpu in seen.items())
    jobs = len(ids)
    return {
        "wall": wall,
        "job_seconds": [(kind, float(s)) for kind, s in per_job],
        "worker_cpu_per_job": worker_cpu / jobs,
        "db_cpu_per_job": db_cpu / jobs,
    }


def main(dsn: str, batch: str, jobs: int, rounds: int = 2) -> None:
    results = {1: [], 2: []}
    for r in range(rounds):
        for workers in (1, 2):  # alternated: the machine's noise falls on both
            results[workers].append(run(dsn, batch, jobs, workers, r))
            print(
                f"round {r} {workers} worker(s): {results[workers][-1]['wall']:.1f} s", flush=True
            )
    print(
        "| workers | wall, median of rounds | job, median | worker CPU / job | database CPU / job |"
    )
    print("|---|---|---|---|---|")
    for workers, rs in results.items():
        kinds = sorted({k for r in rs for k, _ in r["job_seconds"]})
        jobs_s = ", ".join(
            f"{k.removeprefix('modb.')} "
            f"{statistics.median(s for r in rs for kk, s in r['job_seconds'] if kk == k):.1f} s"
            for k in kinds
        )
        print(
            f"| {workers} | {statistics.median(r['wall'] for r in rs):.1f} s | {jobs_s} | "
            f"{statistics.median(r['worker_cpu_per_job'] for r in rs):.1f} s | "
            f"{statistics.median(r['db_cpu_per_job'] for r in rs):.1f} s |"
        )
    one = statistics.median(r["wall"] for r in results[1])
    two = statistics.median(r["wall"] for r in results[2])
    print(f"ratio, 1 worker's wall time over 2 workers': {one / two:.2f}")


if __name__ == "__main__":
    if sys.argv[2].startswith("retarget:"):  # its batch size is the collection's
        main(sys.argv[1], sys.argv[2], 0, int(sys.argv[3]) if len(sys.argv) > 3 else 2)
    else:
        main(
            sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]) if len(sys.argv) > 4 else 2
        )
