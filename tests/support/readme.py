"""The code blocks of README.md and docs/*.md, read in order and run the way a reader runs them.

A fenced block tagged `sh`, `sql` or `python` is a command to run; any other tag (`text`, none) is
output or a layout. A block right after a line `<!-- not run: REASON -->` is skipped, and only the
commands NOT_RUN_ALLOWED names may be skipped.
"""

from __future__ import annotations

import re
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path

RUNNABLE = ("sh", "sql", "python")
FENCE = re.compile(r"^```(\w*)[^\n]*\n(.*?)^```\s*$", re.S | re.M)
NOT_RUN = re.compile(r"<!--\s*not run:\s*(.+?)\s*-->\s*\n\s*$")
# What a test cannot run: the whole demo or test suite, a server that runs until stopped, server
# restarts, and the pgbench load recipe.
NOT_RUN_ALLOWED = re.compile(r"\bmake (demo|test)\b|\bmodb\b.*\bserve\b|\brestart\b|\bpgbench\b")


@dataclass(frozen=True)
class Block:
    line: int  # of the opening fence, 1-based
    language: str
    text: str
    not_run: str | None  # the reason, when marked not to run
    path: str = "README.md"  # the file it is in, for messages


def blocks(markdown: str, path: str = "README.md") -> list[Block]:
    """Every fenced block, in order, with the `not run` reason written just before it."""
    found = []
    for m in FENCE.finditer(markdown):
        before = markdown[: m.start()]
        reason = NOT_RUN.search(before[-300:])
        found.append(
            Block(
                line=before.count("\n") + 1,
                language=m.group(1),
                text=m.group(2),
                not_run=reason.group(1) if reason else None,
                path=path,
            )
        )
    return found


def check_not_run(block: Block) -> None:
    """A block may be skipped only for what NOT_RUN_ALLOWED names."""
    if block.not_run is not None and not NOT_RUN_ALLOWED.search(block.text):
        raise AssertionError(
            f"{block.path}:{block.line}: marked `not run: {block.not_run}`, but only `make demo`, "
            f"`make test`, `modb serve`, server restarts and pgbench may be left unrun"
        )


@dataclass
class Runner:
    """Runs blocks in one environment: `sh` with bash -e -o pipefail, `sql` with psql against
    `dsn` (stopping at the first error), `python` with `python`."""

    cwd: Path
    env: dict[str, str]
    python: str
    dsn: str | None = None
    timeout: float = 1200
    seconds: list[tuple[str, float]] = field(default_factory=list)  # each block's, in order

    def command(self, block: Block) -> list[str]:
        if block.language == "sh":
            return ["bash", "-e", "-o", "pipefail", "-c", block.text]
        if block.language == "sql":
            if self.dsn is None:
                raise AssertionError(f"{block.path}:{block.line}: an SQL block before any database")
            return ["psql", "-X", "-q", "-v", "ON_ERROR_STOP=1", "-d", self.dsn, "-f", "-"]
        if block.language == "python":
            return [self.python, "-c", block.text]
        raise ValueError(f"not a runnable block: {block.language!r}")

    def run(self, block: Block) -> subprocess.CompletedProcess:
        """Runs one block; a failure is an AssertionError naming its file, line and output."""
        stdin = block.text if block.language == "sql" else None
        started = time.monotonic()
        r = subprocess.run(
            self.command(block),
            input=stdin,
            cwd=self.cwd,
            env=self.env,
            capture_output=True,
            text=True,
            timeout=self.timeout,
        )
        self.seconds.append((f"{block.path}:{block.line}", time.monotonic() - started))
        if r.returncode != 0:
            raise AssertionError(
                f"{block.path}:{block.line}: the {block.language} block failed "
                f"(exit {r.returncode}):\n{block.text}\n--- stdout\n{r.stdout[-3000:]}"
                f"\n--- stderr\n{r.stderr[-3000:]}"
            )
        return r
