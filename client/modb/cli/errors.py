"""The errors every command can meet (the database, the embedded cluster, a reader that left
early), turned into a message on stderr and an exit status: for `modb` itself and for the commands
another command runs (the loads of `modb demo` and `modb bench`)."""

from __future__ import annotations

import os
import sys
from collections.abc import Callable

import psycopg


def reporting_errors(command: Callable[[], int]) -> int:
    """`command()`'s exit status, or 2 with the reason on stderr for a database error or a
    RuntimeError (NotInstalledError, ClusterError); 0 when the reader of the output left early."""
    try:
        return command()
    except psycopg.OperationalError as e:
        print(
            f"modb: cannot connect to the database: {str(e).strip()}\n"
            f"  (check --dsn / MODB_DSN, or `modb db start` for the embedded one)",
            file=sys.stderr,
        )
        return 2
    except psycopg.Error as e:
        from modb.web.database_errors import without_prefixes

        print(
            f"modb: database error: {without_prefixes(e.diag.message_primary or str(e))}"
            + (f"\n  hint: {e.diag.message_hint}" if e.diag.message_hint else ""),
            file=sys.stderr,
        )
        return 2
    except RuntimeError as e:  # NotInstalledError, ClusterError
        print(f"modb: {e}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        # The reader of the output left early (`modb list | head`): not a failure, and no
        # traceback when Python flushes stdout at exit.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
