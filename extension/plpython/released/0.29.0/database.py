"""The statements that read and write clips, run the same way in the server's PL/Python and in a job
worker on another machine: a Statement is SQL with $n parameters and their types, run by a Database
the caller supplies (Server here, around plpy; the client's jobs package has one around psycopg).
Rows come back as dicts; jsonb columns are selected as text, so both sides parse the same JSON."""

from dataclasses import dataclass


@dataclass(frozen=True)
class Statement:
    sql: str
    types: tuple = ()


class StoreError(Exception):
    """Refused: a message, a hint saying what to do, and the SQLSTATE the server raises it with."""

    def __init__(self, message, hint=None, sqlstate=None):
        super().__init__(message)
        self.hint = hint
        self.sqlstate = sqlstate


_NOTHING = Statement("SELECT")  # an empty statement: what the executor checks interrupts in


class Server:
    """A Database inside a PL/Python function: each statement prepared once per call."""

    def __init__(self, plpy):
        self._plpy = plpy
        self._plans = {}

    def _plan(self, statement):
        plan = self._plans.get(statement)
        if plan is None:
            plan = self._plans[statement] = self._plpy.prepare(statement.sql, list(statement.types))
        return plan

    def run(self, statement, params=()):
        return [dict(row) for row in self._plpy.execute(self._plan(statement), list(params))]

    def check_interrupts(self):
        """Lets a cancel or a statement timeout in: Python code between statements never reaches
        PostgreSQL's interrupt checks, so long work calls this between pieces (each about 20 us);
        a pending one raises here, as PostgreSQL's error."""
        self.run(_NOTHING)

    def rows(self, statement, params=()):
        """The rows one at a time (a cursor): memory stays bounded over many."""
        cursor = self._plpy.cursor(self._plan(statement), list(params))
        while True:
            batch = cursor.fetch(1)
            if not batch:
                return
            yield dict(batch[0])


def raise_in_plpy(plpy, error):
    """A StoreError as the server's error (its hint and SQLSTATE kept)."""
    options = {"hint": error.hint} if error.hint else {}
    if error.sqlstate:
        options["sqlstate"] = error.sqlstate
    plpy.error(str(error), **options)
