"""What a benchmark that fills a database of its own asks of the command line: `modb load`,
`modb graph build`, `modb annotate --steps`, `modb model build` and `modb model graph`, quiet, with
their messages and exit status. modb.cli.bench gives them, so that the benchmarks import nothing of
the command line above them."""

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

    def annotate_steps(self, dsn: str, collection: str) -> int:
        """`modb --dsn DSN annotate --steps COLLECTION --quiet`: its exit status."""
        ...

    def build_model(self, dsn: str, name: str, collection: str, primitive: str) -> int:
        """`modb --dsn DSN model build NAME --collection COLLECTION --primitive PRIMITIVE --quiet`:
        its exit status."""
        ...

    def build_model_graph(self, dsn: str, name: str, collection: str) -> int:
        """`modb --dsn DSN model graph NAME --collection COLLECTION`: its exit status."""
        ...
