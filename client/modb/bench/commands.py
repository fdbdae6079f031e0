"""What a benchmark that fills a database of its own asks of the command line: `modb load` and
`modb graph build`, quiet, with their messages and exit status. modb.cli.bench gives them, so that
the benchmarks import nothing of the command line above them."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol


class Commands(Protocol):
    def load(self, dsn: str, files: Sequence[str], collection: str) -> int:
        """`modb --dsn DSN load FILES --collection COLLECTION --quiet`: its exit status."""
        ...

    def build_graph(self, dsn: str, name: str, collection: str) -> int:
        """`modb --dsn DSN graph build NAME --collection COLLECTION --quiet`: its exit status."""
        ...
