"""The README's Reference tables, generated from the extension's COMMENTs and the command's parser.

`tests/test_readme.py` checks the README holds exactly what this generates; after changing a COMMENT
or a command's help, rewrite the tables with

    .venv/bin/python tests/support/reference.py "$(.venv/bin/modb db url)"
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import psycopg

README = Path(__file__).resolve().parents[2] / "README.md"
SECTION = re.compile(r"(<!-- reference: (\w+) -->\n)(.*?)(<!-- /reference -->)", re.S)

# Every function of schema modb with its identity arguments and COMMENT, by name.
FUNCTIONS = """
SELECT p.proname, pg_get_function_identity_arguments(p.oid),
       pg_get_function_result(p.oid), coalesce(obj_description(p.oid, 'pg_proc'), '')
  FROM pg_proc p
 WHERE p.pronamespace = 'modb'::regnamespace
 ORDER BY p.proname, pg_get_function_identity_arguments(p.oid)
"""


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def _short_types(text: str) -> str:
    return text.replace("double precision", "float8").replace(
        "timestamp with time zone", "timestamptz"
    )


def functions_table(conn: psycopg.Connection) -> str:
    rows = ["| function | returns | what it does (its COMMENT) |", "|---|---|---|"]
    for name, args, result, comment in conn.execute(FUNCTIONS):
        signature = _short_types(f"modb.{name}({args})")
        rows.append(
            f"| `{_cell(signature)}` | `{_cell(_short_types(result))}` | {_cell(comment)} |"
        )
    return "\n".join(rows) + "\n"


def _subcommands(parser: argparse.ArgumentParser) -> list[tuple[str, argparse.ArgumentParser, str]]:
    found = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {a.dest: a.help or "" for a in action._choices_actions}
            found.extend((name, sub, helps.get(name, "")) for name, sub in action.choices.items())
    return found


def commands_table() -> str:
    from modb.cli.main import build_parser

    rows = ["| command | what it does (its `--help`) | usage |", "|---|---|---|"]
    todo = [("modb", build_parser())]
    while todo:
        prefix, parser = todo.pop(0)
        for name, sub, help_text in _subcommands(parser):
            usage = (
                " ".join(sub.format_usage().split()).removeprefix("usage: ").replace(" [-h]", "")
            )
            rows.append(f"| `{prefix} {name}` | {_cell(help_text)} | `{_cell(usage)}` |")
            todo.append((f"{prefix} {name}", sub))
    return "\n".join(rows) + "\n"


def generated(conn: psycopg.Connection) -> dict[str, str]:
    return {"functions": functions_table(conn), "commands": commands_table()}


def sections(markdown: str) -> dict[str, str]:
    """The README's reference sections by name, as written."""
    return {m.group(2): m.group(3) for m in SECTION.finditer(markdown)}


def rewrite(markdown: str, tables: dict[str, str]) -> str:
    return SECTION.sub(lambda m: m.group(1) + tables[m.group(2)] + m.group(4), markdown)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: reference.py DSN  (rewrites README.md's reference tables)")
    with psycopg.connect(sys.argv[1]) as connection:
        README.write_text(rewrite(README.read_text(), generated(connection)))
