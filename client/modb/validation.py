"""Checking a number a caller gives (an option, a setting, an API argument) against its range, with
a message that names the range: shared by the command line's options and synthesis' settings, so
both refuse the same values in the same words."""

from __future__ import annotations

import math
import numbers


def number_range(
    least: float, most: float, above: bool = False, whole: bool = False, unit: str = ""
) -> str:
    """What checked_number accepts, in words: 'a number greater than 0 and at most 3600 seconds'."""
    unit = f" {unit}" if unit else ""
    if whole:
        return f"a whole number from {least} to {most}{unit}"
    if above:
        return f"a number greater than {least:g} and at most {most:g}{unit}"
    return f"a number from {least:g} to {most:g}{unit}"


def checked_number(
    name: str,
    value: object,
    least: float,
    most: float,
    above: bool = False,
    whole: bool = False,
    unit: str = "",
) -> int | float:
    """`value` if it is a finite number (a whole one if `whole`) from `least` (excluded if `above`)
    to `most`; else ValueError naming `name` and the range."""
    kind = numbers.Integral if whole else numbers.Real
    ok = isinstance(value, kind) and not isinstance(value, bool)
    try:
        ok = ok and math.isfinite(value)
        ok = ok and (least < value if above else least <= value) and value <= most
    except OverflowError:  # an integer too large for a float
        ok = False
    if not ok:
        span = number_range(least, most, above, whole, unit)
        raise ValueError(f"{name} must be {span}, got {value!r:.200}")
    return int(value) if whole else float(value)
