"""docs/reference.md's generated lists, from the extension's COMMENTs and the command's parser.

`tests/test_readme.py` checks docs/reference.md holds exactly what this generates (one list item per
function or command, wrapped within 120 columns); after changing a COMMENT or a command's help,
rewrite the lists with

    .venv/bin/python tests/support/reference.py "$(.venv/bin/modb db url)"
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import psycopg

REFERENCE = Path(__file__).resolve().parents[2] / "docs" / "reference.md"
WIDTH = 120
SECTION = re.compile(r"(<!-- reference: (\w+) -->\n)(.*?)(<!-- /reference -->)", re.S)

# Every function of schema modb with its identity arguments and COMMENT, by name.
FUNCTIONS = """
SELECT p.proname, pg_get_function_identity_arguments(p.oid),
       pg_get_function_result(p.oid), coalesce(obj_description(p.oid, 'pg_proc'), '')
  FROM pg_proc p
 WHERE p.pronamespace = 'modb'::regnamespace
 ORDER BY p.proname, pg_get_function_identity_arguments(p.oid)
"""


# A wrapped line must not start with what Markdown reads as a new list item or heading.
_STARTS_BLOCK = re.compile(r"^([-+*#>]|\d+[.)])$")


def _item(text: str) -> str:
    """One list item, wrapped within WIDTH columns; continuation lines indented by two."""
    words = []
    for word in " ".join(text.split()).split(" "):
        if words and _STARTS_BLOCK.match(word):
            words[-1] += "\x01" + word
        else:
            words.append(word)
    lines, line = [], "-"
    for word in words:
        if len(line) + 1 + len(word.replace("\x01", " ")) > WIDTH and line.strip() != "-":
            lines.append(line)
            line = " "
        line += " " + word
    lines.append(line)
    return "\n".join(lines).replace("\x01", " ") + "\n"


def _short_types(text: str) -> str:
    return text.replace("double precision", "float8").replace(
        "timestamp with time zone", "timestamptz"
    )


def functions_table(conn: psycopg.Connection) -> str:
    items = []
    for name, args, result, comment in conn.execute(FUNCTIONS):
        signature = _short_types(f"modb.{name}({args})")
        items.append(_item(f"`{signature}` returns `{_short_types(result)}`: {comment}"))
    return "".join(items)


def _subcommands(parser: argparse.ArgumentParser) -> list[tuple[str, argparse.ArgumentParser, str]]:
    found = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {a.dest: a.help or "" for a in action._choices_actions}
            found.extend((name, sub, helps.get(name, "")) for name, sub in action.choices.items())
    return found


def commands_table() -> str:
    from modb.cli.main import build_parser

    items = []
    todo = [("modb", build_parser())]
    while todo:
        prefix, parser = todo.pop(0)
        for name, sub, help_text in _subcommands(parser):
            usage = (
                " ".join(sub.format_usage().split()).removeprefix("usage: ").replace(" [-h]", "")
            )
            items.append(_item(f"`{prefix} {name}`: {help_text}. Usage: `{usage}`"))
            todo.append((f"{prefix} {name}", sub))
    return "".join(items)


def generated(conn: psycopg.Connection) -> dict[str, str]:
    return {"functions": functions_table(conn), "commands": commands_table()}


def sections(markdown: str) -> dict[str, str]:
    """The reference sections by name, as written."""
    return {m.group(2): m.group(3) for m in SECTION.finditer(markdown)}


def rewrite(markdown: str, tables: dict[str, str]) -> str:
    return SECTION.sub(lambda m: m.group(1) + tables[m.group(2)] + m.group(4), markdown)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: reference.py DSN  (rewrites docs/reference.md's generated lists)")
    with psycopg.connect(sys.argv[1]) as connection:
        REFERENCE.write_text(rewrite(REFERENCE.read_text(), generated(connection)))
