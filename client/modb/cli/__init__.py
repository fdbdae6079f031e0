"""The `modb` command: one module per subcommand (load, export, list, synth, graph, serve, demo,
bench, db), put together by `main`, and what the commands print (synth_report, demo_run) or share
(common: the connection and output files; errors: the errors every command can meet). `python -m
modb.cli` runs it too."""

from .main import build_parser, main

__all__ = ["build_parser", "main"]
