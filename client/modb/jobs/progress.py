"""A running job's progress, log and result in modb_jobs.progress, written on a connection of its
own (committed at once: `modb jobs show` and the web page see it while the job's own work is still
in its transaction)."""

from __future__ import annotations

import time

import psycopg
from psycopg.types.json import Jsonb

UPSERT = """
INSERT INTO modb_jobs.progress AS p (job_id, done, total, unit, log, result, error)
VALUES (%(job)s, coalesce(%(done)s::bigint, 0), %(total)s::bigint, %(unit)s::text,
        coalesce(%(log)s::text[], '{}'), %(result)s::jsonb, %(error)s::text)
ON CONFLICT (job_id) DO UPDATE SET
    done = coalesce(%(done)s::bigint, p.done), total = coalesce(%(total)s::bigint, p.total),
    unit = coalesce(%(unit)s::text, p.unit), log = p.log || coalesce(%(log)s::text[], '{}'),
    result = coalesce(%(result)s::jsonb, p.result), error = coalesce(%(error)s::text, p.error),
    updated_at = now()
WHERE p.runner IS NOT DISTINCT FROM current_setting('modb_jobs.runner', true)
"""  # (an attempt another worker has taken over since writes nothing more)
MIN_INTERVAL_S = 0.5  # progress counts written at most this often (log lines, results: always)


class JobProgress:
    def __init__(self, conninfo: str, job_id: int):
        self.job_id = job_id
        self._conn = psycopg.connect(conninfo, autocommit=True)
        self._written = 0.0
        self.done, self.total = 0, None
        # A retried job starts again: its count, result and error; its log keeps the earlier lines.
        # This process runs the attempt now (the connection names it: connection.as_worker).
        self._conn.execute(
            "INSERT INTO modb_jobs.progress (job_id, runner) "
            "VALUES (%s, current_setting('modb_jobs.runner', true)) ON CONFLICT (job_id) DO UPDATE "
            "SET done = 0, total = NULL, unit = NULL, result = NULL, error = NULL, "
            "runner = excluded.runner, updated_at = now()",
            [job_id],
        )

    def _write(self, **values) -> None:
        row = {"job": self.job_id, "done": None, "total": None, "unit": None, "log": None,
               "result": None, "error": None, **values}  # fmt: skip
        self._conn.execute(UPSERT, row)

    def advance(self, done: int, total: int, unit: str) -> None:
        self.done = done
        if total != self.total:
            self.total = total
            self._write(done=done, total=total, unit=unit)
        elif time.monotonic() - self._written >= MIN_INTERVAL_S:
            self._write(done=done)
        else:
            return
        self._written = time.monotonic()

    def log(self, line: str) -> None:
        self._write(log=[line])

    def partial(self, result: dict) -> None:
        """What the job made so far (a cancelled or failed job keeps it)."""
        self._write(result=Jsonb(result))

    def finish(self, result: dict) -> None:
        self._write(done=self.total if self.total is not None else self.done, result=Jsonb(result))

    def fail(self, error: str) -> None:
        self._write(error=error)

    def close(self) -> None:
        self._conn.close()
