"""The kernel's statements (modb_kernel.database) run by psycopg in a worker's process, as the
server's PL/Python runs them: the same SQL with $n parameters, each cast to its declared type
    (psycopg
sends values, not types, where plpy.prepare declares them). Results come in binary: real[] as numpy
float32 (modb.database.pgarray), the very values PL/Python gets, not their shortest decimal text."""

from __future__ import annotations

import functools
import re
from collections.abc import Iterator, Sequence
from typing import Any

import psycopg
from psycopg.rows import dict_row

from modb_kernel.database import Statement

PARAMETER = re.compile(r"\$(\d+)(?!\d)")


@functools.cache
def _typed(statement: Statement) -> str:
    return PARAMETER.sub(lambda m: f"(${m[1]}::{statement.types[int(m[1]) - 1]})", statement.sql)


class WorkerDatabase:
    """A Database (modb_kernel.database) on the connection: statements run in its transaction."""

    def __init__(self, conn: psycopg.Connection):
        self._cursor = psycopg.RawCursor(conn, row_factory=dict_row)

    def run(self, statement: Statement, params: Sequence[Any] = ()) -> list[dict[str, Any]]:
        self._cursor.execute(_typed(statement), list(params), binary=True)
        return self._cursor.fetchall() if self._cursor.description else []

    def rows(self, statement: Statement, params: Sequence[Any] = ()) -> Iterator[dict[str, Any]]:
        yield from self.run(statement, params)
