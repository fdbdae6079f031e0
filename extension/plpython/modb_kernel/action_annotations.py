"""A clip's action (actions.py finds it) written as annotation segments of its current version:
what modb.annotate_action does in the server and a job worker does in its own process. The action
segment is named as asked and carries its keyframes, the hands that act ("hands") and its kind
("reach" or "repeat"); its standing lead-in and lead-out are `idle` segments marked with the action
("action": NAME). All are marked automatic ("auto": true); a run replaces the automatic segments
of that name and the automatic idle of that action, and keeps every other (a person's, one a person
edited: the editor drops the mark, and other primitives')."""

import json
import re

from . import actions
from . import memory
from .database import StoreError
from .step_annotations import SET_META, current_version, motion_of

NAME = re.compile(r"^[^\x00-\x1f\x7f,!:]{1,64}$")  # a primitive's name, as processed_data has it
IDLE = "idle"


def made_by(annotation, name):
    """Whether a run for action `name` made this segment (and may replace it)."""
    if not annotation.get("auto"):
        return False
    return annotation["name"] == name or (
        annotation["name"] == IDLE and annotation.get("action") == name
    )


def annotate(db, clip, name):
    """Finds the clip's action and stores it, with its lead-in and lead-out, as its current
    version's automatic segments; returns (version, [segment, ...])."""
    if not NAME.match(name or "") or name == IDLE:
        raise StoreError(
            f"{name!r} is no action's name",
            hint="name it as a primitive is named (1 to 64 characters, no control characters, "
            "comma, '!' or ':'), not idle: e.g. raise_right_hand",
            sqlstate="22023",
        )
    row = current_version(db, clip)
    try:
        found = actions.find(*motion_of(row))
    except actions.ActionError as e:
        if str(e).startswith("the joint map"):
            hint = "complete modb.skeletons.joint_map for it, then find its action again"
        else:
            hint = (f"annotate clips of one action done standing, or mark it by hand: "
                    f"modb annotate CLIP --segment {name}:START-END")  # fmt: skip
        raise StoreError(
            f"clip {clip}: no action {name} found: {e}", hint=hint, sqlstate="22023"
        ) from None
    start, end, keyframes, hands, kind = found["action"]
    made = [{"name": IDLE, "start": a, "end": b, "keyframes": [a, b], "auto": True, "action": name}
            for a, b in found["idle"]]  # fmt: skip
    made.append({"name": name, "start": start, "end": end, "keyframes": keyframes, "auto": True,
                 "hands": hands, "kind": kind})  # fmt: skip
    made.sort(key=lambda a: (a["start"], a["end"], a["name"]))
    meta = json.loads(row["meta"])
    before = json.dumps(meta, sort_keys=True)
    kept = [a for a in meta.get("annotations", []) if not made_by(a, name)]
    meta["annotations"] = sorted(kept + made, key=lambda a: (a["start"], a["end"], a["name"]))
    version = row["version"]
    if json.dumps(meta, sort_keys=True) != before:  # the same action again: meta and ETag kept
        db.run(SET_META, [clip, version, json.dumps(meta)])
    del row  # the frames: their memory goes back to the system
    memory.release()
    return version, made
