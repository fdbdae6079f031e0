"""Avatar mode's settings: what a page may ask for, read from its message and checked in advance.

A page may ask for a profile, graph, collection, lead time, arrival radius and the tunable knobs;
the database checks them before any avatar uses them.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import psycopg

from modb.synthesis.avatar import Settings

# The knobs the panel tunes (a subset of modb.match_knobs(); modb.graph is its own setting).
TUNABLE_KNOBS = (
    "position_threshold",
    "angle_threshold",
    "velocity_threshold",
    "angular_velocity_threshold",
    "norm",
    "joints",
    "velocity_terms",
    "annotations",
)
# Seconds: longer than any snippet, the next query would start before this one plays.
MAX_LEAD_TIME = 2.0


class SettingsRefused(ValueError):
    pass


def settings_from(message: dict[str, Any], current: Settings) -> Settings:
    """The settings a {"type": "settings", ...} message asks for; missing keys keep `current`'s."""
    unknown = sorted(
        set(message)
        - {"type", "profile", "graph", "collection", "lead_time", "arrival_radius", "knobs"}
    )
    if unknown:
        raise SettingsRefused(f"unknown setting {unknown[0]!r:.200}")
    asked = message.get("knobs") or {}
    if not isinstance(asked, dict):
        raise SettingsRefused(f"knobs is an object of knob: value, got {asked!r:.200}")
    knobs = dict(current.knobs)
    for knob, value in asked.items():
        if knob not in TUNABLE_KNOBS:
            raise SettingsRefused(
                f"unknown knob {knob!r:.200}: the panel tunes {', '.join(TUNABLE_KNOBS)}"
            )
        if value is None or value == "":
            knobs.pop(knob, None)  # back to the profile's
        elif isinstance(value, (str, int, float)) and not isinstance(value, bool):
            knobs[knob] = str(value)
        else:
            raise SettingsRefused(f"knob {knob} takes a text or number, got {value!r:.200}")
    changes: dict[str, Any] = {"knobs": knobs}
    for name in ("profile", "graph", "collection"):
        if name in message:
            value = message[name]
            if value is not None and not isinstance(value, str):
                raise SettingsRefused(f"{name} is a name, got {value!r:.200}")
            changes[name] = value or (None if name != "profile" else "default")
    for name, unit, least, most in (
        ("lead_time", "seconds", 0.0, MAX_LEAD_TIME),
        ("arrival_radius", "metres", 0.01, 10.0),
    ):
        if name in message:
            value = message[name]
            number = not isinstance(value, bool) and isinstance(value, (int, float))
            try:
                number = number and math.isfinite(value)
            except OverflowError:  # an integer too large for a float
                number = False
            if not number or not least <= value <= most:
                raise SettingsRefused(
                    f"{name} must be {least:g}-{most:g} {unit}, got {value!r:.200}"
                )
            changes[name] = float(value)
    return replace(current, **changes)


def check_settings(conn: psycopg.Connection, settings: Settings) -> None:
    """Resolves the settings as a selection would (modb.match_plan, the collection) in a transaction
    of its own, so that the database says what is wrong before any avatar uses them."""
    try:
        with conn.transaction():
            for knob, value in {**settings.knobs, "graph": settings.graph or ""}.items():
                conn.execute("SELECT set_config(%s, %s, true)", [f"modb.{knob}", value])
            conn.execute(
                "SELECT modb.match_plan(%s), modb.check_request(NULL, '{0,1}', 1, %s)",
                [settings.profile, settings.collection],
            )
    except psycopg.Error as e:
        # A knob's SET is refused by the setting itself (0.10.0): the reason is in its detail.
        detail = f": {e.diag.message_detail}" if e.diag.message_detail else ""
        hint = f" ({e.diag.message_hint})" if e.diag.message_hint else ""
        raise SettingsRefused(f"{e.diag.message_primary or e}{detail}{hint}") from None
