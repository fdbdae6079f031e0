"""extension/sql/*.sql, the working copy of the next install script: one fragment per subject, each
with a number of its own, and each object defined in one place only (a later file that replaced an
earlier definition would make the earlier one dead text a reader takes for the truth)."""

from __future__ import annotations

import re
from collections import Counter
from pathlib import Path

SQL = Path(__file__).resolve().parents[1] / "extension" / "sql"

CREATE = re.compile(
    r"^\s*CREATE\s+(?:OR\s+REPLACE\s+)?(?:UNIQUE\s+)?"
    r"(FUNCTION|PROCEDURE|AGGREGATE|TABLE|VIEW|TYPE|DOMAIN|SEQUENCE|INDEX|TRIGGER|OPERATOR\s+CLASS"
    r"|OPERATOR|CAST)\s+(?:IF\s+NOT\s+EXISTS\s+)?([^\s(]+)",
    re.I | re.M,
)


def _arguments(text: str, start: int) -> str:
    """The parenthesised argument list from text[start] on (balanced), without blanks: overloads of
    one name are different objects."""
    depth = 0
    for end in range(start, len(text)):
        depth += {"(": 1, ")": -1}.get(text[end], 0)
        if depth == 0:
            return re.sub(r"\s+", "", text[start : end + 1]).lower()
    return ""


def definitions(text: str) -> list[str]:
    """Every object a fragment creates, as 'KIND name(arguments)' (functions) or 'KIND name'."""
    found = []
    for m in CREATE.finditer(text):
        kind = re.sub(r"\s+", " ", m[1].upper())
        name = m[2].lower()
        if kind in ("FUNCTION", "PROCEDURE", "AGGREGATE", "OPERATOR"):
            rest = text.find("(", m.end(1))
            name += _arguments(text, rest) if rest >= 0 else ""
        found.append(f"{kind} {name}")
    return found


def fragments() -> list[Path]:
    return sorted(SQL.glob("*.sql"))


def test_each_fragment_has_a_number_of_its_own():
    numbers = Counter(path.name.split("_", 1)[0] for path in fragments())
    assert len(fragments()) > 10
    assert [n for n, count in numbers.items() if count > 1] == []


def test_each_object_is_defined_once():
    where: dict[str, list[str]] = {}
    for path in fragments():
        for obj in definitions(path.read_text()):
            where.setdefault(obj, []).append(path.name)
    assert len(where) > 100, "the fragments' CREATE statements were not read"
    twice = {obj: files for obj, files in where.items() if len(files) > 1}
    assert twice == {}, f"defined more than once: {twice}"


def test_a_second_definition_is_found():
    text = "CREATE FUNCTION modb.f(a int DEFAULT abs(1)) RETURNS int;\n"
    text += "CREATE FUNCTION modb.f(b text);\n"
    assert definitions(text) == ["FUNCTION modb.f(aintdefaultabs(1))", "FUNCTION modb.f(btext)"]
    assert definitions(text + "create or replace function modb.f(b text)")[-1] == (
        "FUNCTION modb.f(btext)"
    )
