"""What a write's JSON body may hold, declared once per endpoint and checked before any work: each
rule takes (where, value) and returns the value to use or raises Invalid naming the field and what
it expects ("mirror: true or false, got 'no'"). Numbers are numbers (never booleans or strings),
booleans booleans, lists lists of the right items, objects only the fields they know. Lists of ids
come back without repeats, so a clip named twice is edited once. Plain Python: the command line
checks edit scripts with the same rules."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

from modb.loader.limits import FPS_RANGE
from modb.validation import checked_number, number_range
from modb_kernel.edits import script_errors

MAX_ID = 2**63 - 1  # a bigint
MAX_IDS = 10_000  # ids in one request
MAX_NAME = 200  # characters of a name or path
CONTROL = re.compile(r"[\x00-\x1f\x7f]")


class Invalid(ValueError):
    """A body that is not what the endpoint takes: a 400 with this message."""


def _shown(value: Any) -> str:
    return f"{value!r:.60}"


class Rule:
    expects = "anything"

    def __call__(self, where: str, value: Any) -> Any:
        return value

    def refuse(self, where: str, value: Any) -> Invalid:
        return Invalid(f"{where}: {self.expects}, got {_shown(value)}")


@dataclass(frozen=True)
class Whole(Rule):
    least: int = 1
    most: int = MAX_ID
    what: str = "an id"

    @property
    def expects(self) -> str:
        return f"{self.what} (a whole number from {self.least} to {self.most})"

    def __call__(self, where: str, value: Any) -> int:
        if type(value) is not int or not self.least <= value <= self.most:
            raise self.refuse(where, value)
        return value


@dataclass(frozen=True)
class Number(Rule):
    least: float
    most: float
    unit: str = ""

    @property
    def expects(self) -> str:
        return number_range(self.least, self.most, unit=self.unit)

    def __call__(self, where: str, value: Any) -> float:
        if isinstance(value, float) and not math.isfinite(value):
            raise self.refuse(where, value)
        try:
            return checked_number(where, value, self.least, self.most, unit=self.unit)
        except ValueError:
            raise self.refuse(where, value) from None


FPS = Number(*FPS_RANGE, unit="fps")


class Flag(Rule):
    expects = "true or false"

    def __call__(self, where: str, value: Any) -> bool:
        if type(value) is not bool:
            raise self.refuse(where, value)
        return value


@dataclass(frozen=True)
class Text(Rule):
    most: int = MAX_NAME
    lines: bool = False  # newlines and tabs allowed (a comment)

    @property
    def expects(self) -> str:
        return f"a string of 1 to {self.most} characters" + ("" if self.lines else " on one line")

    def __call__(self, where: str, value: Any) -> str:
        if not isinstance(value, str) or not value.strip() or len(value) > self.most:
            raise self.refuse(where, value)
        bad = CONTROL.search(value.replace("\n", "").replace("\t", "") if self.lines else value)
        if bad:
            raise Invalid(f"{where}: holds the control character {bad.group()!r}")
        return value


class Name(Text):
    """A collection's name: a path segment."""

    expects = "a name of 1 to 200 characters without '/' (and not '.' or '..')"

    def __call__(self, where: str, value: Any) -> str:
        value = super().__call__(where, value)
        if "/" in value or value.strip() in (".", ".."):
            raise self.refuse(where, value)
        return value


class CollectionPath(Rule):
    """'a/b/c': names joined by '/', none empty, '.' or '..'."""

    expects = "a collection path such as 'bandai/walks' (names joined by '/')"

    def __call__(self, where: str, value: Any) -> str:
        if not isinstance(value, str) or not value or len(value) > MAX_NAME:
            raise Invalid(f"{where}: {self.expects}, of 1 to {MAX_NAME} characters, got "
                          f"{_shown(value)}")  # fmt: skip
        for k, segment in enumerate(value.split("/"), 1):
            if not segment.strip() or segment.strip() in (".", ".."):
                raise Invalid(
                    f"{where}: segment {k} of {value!r} is {segment!r}: each segment is a name "
                    "(not empty, '.' or '..')"
                )
            bad = CONTROL.search(segment)
            if bad:
                raise Invalid(f"{where}: segment {k} holds the control character {bad.group()!r}")
        return value


@dataclass(frozen=True)
class Nullable(Rule):
    rule: Rule

    @property
    def expects(self) -> str:
        return f"{self.rule.expects}, or null"

    def __call__(self, where: str, value: Any) -> Any:
        return None if value is None else self.rule(where, value)


class JsonObject(Rule):
    expects = "a JSON object"

    def __call__(self, where: str, value: Any) -> dict:
        if not isinstance(value, dict):
            raise self.refuse(where, value)
        return value


@dataclass(frozen=True)
class ListOf(Rule):
    item: Rule
    least: int = 0
    most: int = MAX_IDS
    distinct: bool = False  # repeats dropped (the first kept)

    @property
    def expects(self) -> str:
        count = f"at least {self.least}" if self.least else "any number"
        return f"a list of {count} (at most {self.most:,}) of: {self.item.expects}"

    def __call__(self, where: str, value: Any) -> list:
        if not isinstance(value, list) or not self.least <= len(value) <= self.most:
            raise self.refuse(where, value)
        items = [self.item(f"{where}[{k}]", v) for k, v in enumerate(value)]
        return list(dict.fromkeys(items)) if self.distinct else items


@dataclass(frozen=True)
class Fixed(Rule):
    """A list of exactly `n` items of `item` (an axis, a quaternion, a pair)."""

    item: Rule
    n: int

    @property
    def expects(self) -> str:
        return f"a list of {self.n} of: {self.item.expects}"

    def __call__(self, where: str, value: Any) -> list:
        if not isinstance(value, list) or len(value) != self.n:
            raise self.refuse(where, value)
        return [self.item(f"{where}[{k}]", v) for k, v in enumerate(value)]


@dataclass(frozen=True)
class MapOf(Rule):
    value: Rule
    most: int = 1000

    @property
    def expects(self) -> str:
        return f"an object of at most {self.most} names to: {self.value.expects}"

    def __call__(self, where: str, value: Any) -> dict:
        if not isinstance(value, dict) or len(value) > self.most:
            raise self.refuse(where, value)
        return {Text()(f"{where} key", k): self.value(f"{where}.{k}", v) for k, v in value.items()}


@dataclass(frozen=True)
class Shape(Rule):
    """An object with these fields and no others; `required` must be present (and not null)."""

    fields: dict[str, Rule]
    required: tuple[str, ...] = ()
    name: str = "the body"
    at_least_one: bool = False  # one field at least (a PATCH)

    @property
    def expects(self) -> str:
        return "an object with " + ", ".join(
            f'"{k}"' + ("" if k in self.required else " (optional)") for k in self.fields
        )

    def __call__(self, where: str | None, value: Any) -> dict[str, Any]:
        where = where or self.name
        if not isinstance(value, dict):
            raise self.refuse(where, value)
        unknown = [k for k in value if k not in self.fields]
        if unknown:
            takes = ", ".join(f'"{k}"' for k in self.fields) or "no other field"
            raise Invalid(f"{where}: unknown field {unknown[0]!r:.60}; it takes {takes}")
        missing = [k for k in self.required if value.get(k) is None]
        if missing:
            raise Invalid(f'{where}: "{missing[0]}" is missing: {self.fields[missing[0]].expects}')
        if self.at_least_one and not value:
            raise Invalid(f"{where}: nothing to change: give " + " and/or ".join(
                f'"{k}"' for k in self.fields))  # fmt: skip
        inner = "" if where == self.name else f"{where}."
        return {k: self.fields[k](f"{inner}{k}", v) for k, v in value.items()}


# Edit scripts: the kernel's own check (modb_kernel/edits.py), the one the database's trigger runs,
# so the REST interface, the command line and SQL refuse the same scripts in the same words. Ranges
# that depend on the clip (frames) are checked when the script is applied.


def check_script(commands: Any, where: str = "commands") -> list[dict[str, Any]]:
    """An edit script's commands as given, once checked (Invalid naming every bad command)."""
    problems = script_errors(commands)
    if problems:
        raise Invalid(f"{where}: " + "; ".join(problems))
    return commands


# Joint maps and axes (modb.skeletons): the database checks the joints against the skeleton.


class Axis(Fixed):
    """A direction: three numbers, not all zero."""

    def __init__(self) -> None:
        super().__init__(Number(-1e6, 1e6), 3)

    @property
    def expects(self) -> str:
        return "a direction [x, y, z] (numbers, not all 0)"

    def __call__(self, where: str, value: Any) -> list:
        axis = super().__call__(where, value)
        if not any(axis):
            raise self.refuse(where, value)
        return axis


AXIS = Axis()
JOINT_AXES = Shape(
    {
        "joints": MapOf(Shape({"joint": Text(), "twist": AXIS, "swing": AXIS}, ("joint", "twist",
                                                                                "swing"))),
        "pose": Nullable(ListOf(Fixed(Number(-1.0, 1.0), 4), 0, 100_000)),
    },
)  # fmt: skip


class ParentPath(CollectionPath):
    """Where a collection moves: a collection path, or '' for the top."""

    expects = "a collection path, or '' for the top"

    def __call__(self, where: str, value: Any) -> str:
        return "" if value == "" else super().__call__(where, value)
