"""The `modb` command: one module per subcommand (load, export, list, synth, graph, serve, demo,
bench, db), put together by `main`. `python -m modb.cli` runs it too."""

from .main import build_parser, main

__all__ = ["build_parser", "main"]
