"""Length units of a source file: an explicit choice, or a stated rule on the figure's size (the
ranges a loaded clip must fall in are in limits.py)."""

from __future__ import annotations

import numpy as np

NAMED_UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254}

# Figure extent (largest side of the rest pose's bounding box, in file units)
# -> unit. Humans are about 1-2.5 m tall or wide; the ranges do not overlap, and
# inches are left out on purpose: 40-100 in overlaps plausible centimetre figures.
_AUTO_RANGES = (("m", 0.5, 3.0), ("cm", 50.0, 300.0), ("mm", 500.0, 3000.0))


class UnitsError(ValueError):
    pass


def parse_units(value: str) -> str | float:
    """'auto', a named unit, or metres per unit as a positive number."""
    if value == "auto" or value in NAMED_UNITS:
        return value
    try:
        factor = float(value)
    except ValueError:
        raise UnitsError(
            f"unknown units {value!r}: use auto, m, cm, mm, in or metres per unit (e.g. 0.0564444)"
        )
    if not factor > 0 or not np.isfinite(factor):
        raise UnitsError(f"units must be a positive number of metres per unit, got {value!r}")
    return factor


def resolve_units(units: str | float, rest_points: np.ndarray) -> tuple[float, str]:
    """Metres per unit and the rule that gave it, as told to the user.

    rest_points: joint and end-site positions of the rest pose in file units.
    """
    if isinstance(units, float):
        return units, f"--units {units:g}: {units:g} m per unit"
    if units != "auto":
        return NAMED_UNITS[units], f"--units {units}: {NAMED_UNITS[units]:g} m per unit"
    extent = float(np.max(np.ptp(rest_points, axis=0))) if len(rest_points) else 0.0
    for name, lo, hi in _AUTO_RANGES:
        if lo <= extent <= hi:
            return NAMED_UNITS[name], (
                f"units auto: rest pose spans {extent:.4g} units, within {lo:g}-{hi:g} -> {name} "
                f"({NAMED_UNITS[name]:g} m per unit)"
            )
    raise UnitsError(
        f"cannot infer units: the rest pose spans {extent:.4g} units, outside every range "
        f"(m 0.5-3, cm 50-300, mm 500-3000); pass --units (m, cm, mm, in, or metres per unit; "
        f"CMU's ASF-derived files use 0.0254/0.45 = 0.0564444)"
    )
