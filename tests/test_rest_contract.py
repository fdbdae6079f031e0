"""The REST bodies' contract (issue 57): the refusals the REST tests' bodies met before the bodies
were declared as pydantic models are met alike (tests/support/rest_refusals.json: the same status,
a 400 naming the same field); and every route with a body takes a body made from its published
OpenAPI schema and refuses, with a 400 naming the field, one violation of each constraint the
schema documents."""

from __future__ import annotations

import copy
import json
import os
import re
from collections import Counter

from support import rest_refusals

RECORD = os.environ.get("MODB_RECORD_REST_REFUSALS") == "1"


def test_the_frozen_refusals_are_refused_alike(fresh_db):
    """Each case the REST tests send, replayed in order on a small site: the status frozen, and
    for a 400 the field its frozen message named (both messages read by the same named_field; the
    fixture's "field" is what it read as they were frozen). MODB_RECORD_REST_REFUSALS=1 freezes
    them anew (only ever against the code before a change to the bodies)."""
    frozen = [] if RECORD else json.loads(rest_refusals.FIXTURE.read_text())["cases"]
    cases = rest_refusals.cases() if RECORD else frozen
    differ, reworded = [], []
    with rest_refusals.site(fresh_db) as s:
        for k, case in enumerate(cases):
            got = rest_refusals.answer(rest_refusals.send(s, case))
            if RECORD:
                frozen.append({**case, **got})
                continue
            named = rest_refusals.named_field(case["error"]) if "error" in case else None
            if (got["status"], got.get("field")) != (case["status"], named):
                differ.append((k, case, got))
            elif named and got["error"] != case["error"]:
                reworded.append((case["error"], got["error"]))
    if RECORD:
        rest_refusals.write_fixture(frozen)
        return
    shown = "\n".join(
        f"{k} {c['method']} {c['path']} {json.dumps(c.get('body'))[:120]}: frozen {c['status']} "
        f"{rest_refusals.named_field(c.get('error', ''))!r} ({c.get('error', '')[:100]}), now "
        f"{g['status']} {g.get('field')!r} ({g.get('error', '')[:100]})"
        for k, c, g in differ
    )
    assert not differ, f"{len(differ)} of {len(cases)} answered otherwise:\n{shown}"
    assert len(cases) > 500
    print(f"{len(reworded)} of {sum(c['status'] == 400 for c in cases)} refusals reworded:")
    for was, now in sorted(set(reworded)):
        print(f"  {was[:110]}\n  -> {now[:110]}")


# --- bodies derived from the published schema -----------------------------------------------------

# Path parameters of the routes with a body, on the contract's site (setup_contract makes them).
PATH_VALUES = {
    "ident": None,  # by route: see _url
    "clip_id": "$CLIP",
    "version": "$VERSION",
    "skeleton_id": "$SKELETON",
    "name": "contract",
    "path": "walks/contract",
}
# What the schema cannot say (which ids exist, a skeleton's joints, which field a change changes):
# the values a valid body takes for these fields; the rest is made from the schema.
SEEDS = {
    ("POST", "/api/clips/{ident}/retarget"): {"skeleton": "$SKELETON"},
    ("POST", "/api/collections/{path}/retarget"): {"skeleton": "$SKELETON"},
    ("POST", "/api/edit-scripts/{name}/apply"): {"clips": ["$CLIP"]},
    ("PUT", "/api/skeletons/{skeleton_id}/maps"): {
        "joint_map": "$MAPS:joint_map", "mirror_pairs": "$MAPS:mirror_pairs"},
    ("PUT", "/api/models/{ident}"): {"data": {"v": 2}},
    ("PUT", "/api/graphs/{ident}"): {"data": {"v": 2}},
    ("PATCH", "/api/collections/{path}"): {"name": "patched"},
}  # fmt: skip
MISSING = object()
NOT_GIVEN = "<none>"


class Schema:
    """The published document's schemas, $refs followed."""

    def __init__(self, document: dict) -> None:
        self.defs = document["components"]["schemas"]

    def open(self, node: dict) -> dict:
        while "$ref" in node:
            target = self.defs[node["$ref"].rsplit("/", 1)[1]]
            node = {**target, **{k: v for k, v in node.items() if k != "$ref"}}
        return node

    def valid(self, node: dict, seed=MISSING):
        """A value the schema takes (the seed's where it gives one)."""
        node = self.open(node)
        if seed is not MISSING and not (isinstance(seed, dict) and "properties" in node):
            return seed  # (a seed for a model's fields: those, and the rest from the schema)
        if "const" in node:
            return node["const"]
        if "enum" in node:
            return node["enum"][0]
        for union in ("anyOf", "oneOf"):
            if union in node and "type" not in node:
                branches = [b for b in node[union] if self.open(b).get("type") != "null"]
                return self.valid(branches[0], seed)
        kind = node.get("type")
        if kind == "object":
            seed = seed if isinstance(seed, dict) else {}
            properties = node.get("properties", {})
            keys = [*seed, *node.get("required", ())]
            if node.get("oneOf"):  # fields of which one is given
                keys += node["oneOf"][0]["required"]
            for k in properties:
                if len(dict.fromkeys(keys)) >= node.get("minProperties", 0):
                    break
                keys.append(k)
            out = {k: self.valid(properties[k], seed.get(k, MISSING)) for k in dict.fromkeys(keys)}
            if not properties and isinstance(node.get("additionalProperties"), dict):
                names = {"type": "string", **node.get("propertyNames", {})}  # (names are strings)
                out[self.valid(names)] = self.valid(node["additionalProperties"])
            return out
        if kind == "array":
            n = max(node.get("minItems", 0), 1 if node.get("maxItems", 1) else 0)
            return [self.valid(node.get("items", {})) for _ in range(n)]
        if kind == "string":
            value = "a" * max(node.get("minLength", 1), 1)
            assert re.search(node.get("pattern", ""), value), node
            return value
        if kind in ("integer", "number"):
            low, high = node.get("minimum", -(2**31)), node.get("maximum", 2**31)
            return 1 if low <= 1 <= high else low
        if kind == "boolean":
            return False
        if kind == "null":
            return None
        return {}  # any JSON value

    def violations(self, node: dict, body, path: tuple) -> list[tuple[str, tuple, object]]:
        """(the constraint, where, the whole body breaking it there and nowhere else) for each
        constraint the schema at `path` of `body` states, and those of the schemas inside it."""
        node = self.open(node)
        here = _get(body, path)
        out: list[tuple[str, tuple, object]] = []

        def breaks(constraint: str, value, named: tuple = path) -> None:
            """`value` in place of the value at `path`; the 400 must name `named`."""
            out.append((constraint, named, _set(body, path, value)))

        for union in ("anyOf", "oneOf"):
            if union in node and "type" not in node:
                for branch in node[union]:
                    branch = self.open(branch)
                    if branch.get("type") == "null":
                        continue
                    own = here if _fits(branch, here) else self.valid(branch)
                    out += self.violations(branch, _set(body, path, own), path)
                return out
        kind = node.get("type")
        if kind:
            breaks(f"type {kind}", WRONG[kind])
        if "const" in node or "enum" in node:
            breaks("const", "no-such-value")
        for key, step in (("minimum", -1), ("maximum", 1)):
            if key in node:
                breaks(key, node[key] + step)
        if "minLength" in node and node["minLength"] > 0:
            breaks("minLength", "a" * (node["minLength"] - 1))
        if "maxLength" in node:
            breaks("maxLength", "a" * (node["maxLength"] + 1))
        if "pattern" in node:
            bad = next(c for c in NOT_MATCHING if not re.search(node["pattern"], c))
            breaks("pattern", bad)
        if "not" in node:
            breaks("not", self.valid({**{k: v for k, v in node.items() if k != "not"},
                                      **node["not"]}))  # fmt: skip
        if kind == "array":
            item = node.get("items", {})
            if node.get("minItems", 0) > 0:
                breaks("minItems", here[: node["minItems"] - 1])
            if "maxItems" in node:
                breaks("maxItems", [here[0] if here else self.valid(item)] * (node["maxItems"] + 1))
            full = here if here else [self.valid(item)]
            out += self.violations(item, _set(body, path, full), (*path, 0))
        if kind == "object":
            out += self._object_violations(node, body, path, here, breaks)
        return out

    def _object_violations(self, node, body, path, here, breaks):
        out = []
        properties = node.get("properties", {})
        for k in node.get("required", ()):
            breaks("required", {n: v for n, v in here.items() if n != k}, (*path, k))
        if node.get("additionalProperties") is False:
            breaks("additionalProperties", {**here, "unknown_field": 1}, (*path, "unknown_field"))
        if node.get("minProperties", 0) > 0:
            breaks("minProperties", {})
        for branch in node.get("oneOf", ()):  # one of these fields, not none nor two
            others = [k for b in node["oneOf"] for k in b["required"] if b is not branch]
            both = {**here, **{k: self.valid(properties[k]) for k in branch["required"] + others}}
            breaks("oneOf (two)", both)
            chosen = branch["required"] + others
            breaks("oneOf (none)", {k: v for k, v in here.items() if k not in chosen})
            break
        values = node.get("additionalProperties")
        if isinstance(values, dict):  # an object of names to values
            names = {"type": "string", **node.get("propertyNames", {})}
            key = next(iter(here), None) or self.valid(names)
            entry = here.get(key, self.valid(values))
            if "maxProperties" in node:
                many = {f"k{i}": entry for i in range(node["maxProperties"] + 1)}
                breaks("maxProperties", many)
            for constraint, _, bad_name in self.violations(names, key, ()):
                if isinstance(bad_name, str):
                    breaks(f"propertyNames {constraint}", {bad_name: entry}, (*path, " key"))
            out += self.violations(values, _set(body, path, {**here, key: entry}), (*path, key))
        for k, sub in properties.items():
            given = _get(body, (*path, k)) if k in here else self.valid(sub)
            out += self.violations(sub, _set(body, (*path, k), given), (*path, k))
        return out


WRONG = {"integer": "1", "number": "1.5", "string": 5, "boolean": "true", "array": "a",
         "object": [], "null": 0}  # fmt: skip
NOT_MATCHING = ["a\x01b", " ", "..", "a//b", "/", "a\tb"]


def _fits(node: dict, value) -> bool:
    """Whether a oneOf branch is the one this value is (its const fields hold)."""
    if not isinstance(value, dict):
        return False
    consts = {k: p["const"] for k, p in node.get("properties", {}).items() if "const" in p}
    return all(value.get(k) == v for k, v in consts.items())


def _get(value, path: tuple):
    for key in path:
        value = value[key]
    return value


def _set(value, path: tuple, new):
    """A copy of `value` with `new` at `path`."""
    if not path:
        return copy.deepcopy(new)
    out = copy.deepcopy(value)
    _get(out, path[:-1])[path[-1]] = copy.deepcopy(new)
    return out


def _shown_path(path: tuple) -> str:
    out = ""
    for key in path:
        if key == " key":
            out += " key"
        elif isinstance(key, int):
            out += f"[{key}]"
        else:
            out += f".{key}" if out else key
    return out or "the body"


def _names(error: str, path: tuple, route: tuple[str, str]) -> bool:
    """Whether the 400's message names the field at `path`."""
    scripts = (("PUT", "/api/edit-scripts/{name}"), ("POST", "/api/clips/{ident}/edit-preview"))
    if route in scripts and len(path) > 1:
        # an edit script's commands are the kernel's: "commands: command 1: trim: "start" must be"
        head = error.startswith("commands: command 1: ")
        return head and (len(path) < 3 or f'"{path[2]}"' in error or "unknown command" in error)
    return rest_refusals.named_field(error) == _shown_path(path)


def _fields(value, path: tuple = ()) -> set[str]:
    """Every field of a body, as a 400 names it ("the body" for the whole)."""
    out = {_shown_path(path)}
    if isinstance(value, dict):
        for k, v in value.items():
            out |= _fields(v, (*path, k))
    elif isinstance(value, list):
        for k, v in enumerate(value):
            out |= _fields(v, (*path, k))
    return out


def _malformed(r, body) -> bool:
    """A 400 refusing the body as malformed: its message names a field of it (not the database's
    refusal of a body it could read, such as too few examples to align)."""
    return rest_refusals.named_field(r.json().get("error", "")) in _fields(body)


def _url(s, path: str) -> str:
    ident = {"/api/clips/{ident}/retarget": "$CLIP", "/api/clips/{ident}/action": "$CLIP",
             "/api/clips/{ident}/edit-preview": "$CLIP",
             "/api/models/{ident}": "$MODEL",
             "/api/graphs/{ident}": "$GRAPH"}[path] if "{ident}" in path else None  # fmt: skip
    values = {**PATH_VALUES, "ident": ident}
    return re.sub(r"\{(\w+)\}", lambda m: str(values[m.group(1)]), path)


def setup_contract(s) -> None:
    """What the routes' path parameters name: a model, a graph, a collection to rename, an edit
    script to apply."""
    h = {"Authorization": f"Bearer {s.token}"}
    for table in ("models", "graphs"):
        r = s.client.post(f"/api/{table}", json={"name": "contract", "kind": "motion", "data": {}},
                          headers=h)  # fmt: skip
        assert r.status_code == 201, r.text
        s.kept[f"${table[:-1].upper()}"] = r.json()["id"]
    r = s.client.post("/api/collections", json={"path": "walks/contract"}, headers=h)
    assert r.status_code == 201, r.text
    commands = {"commands": [{"op": "trim", "start": 0, "end": 9}]}
    assert s.client.put("/api/edit-scripts/contract", json=commands, headers=h).status_code == 201


def test_every_body_is_checked_as_its_schema_says(fresh_db):
    """For each route with a JSON body in /api/openapi.json: a body made from its schema is taken
    (done, or a 404 for what this database has not, such as job tables, or the database's refusal
    of what it holds, such as too few examples to align; never a 400 naming a field), and one
    violation of each constraint the schema states (type, required, const, minimum/maximum,
    length, pattern, items, additionalProperties, minProperties, oneOf, not, the names of an
    object of names) is a 400 naming the field."""
    with rest_refusals.site(fresh_db) as s:
        setup_contract(s)
        document = s.client.get("/api/openapi.json").json()
        schema = Schema(document)
        routes = [
            (method.upper(), path, op["requestBody"]["content"]["application/json"]["schema"])
            for path, ops in document["paths"].items()
            for method, op in ops.items()
            if "application/json" in op.get("requestBody", {}).get("content", {})
        ]
        taken, refused, wrong = [], Counter(), []
        for method, path, body_schema in routes:
            case = {"method": method, "path": _url(s, path), "if_match": path.endswith(("/maps",
                    "/meta"))}  # fmt: skip
            seed = rest_refusals._fill(SEEDS.get((method, path), MISSING), s)
            node = schema.open(body_schema)
            branches = node.get("oneOf", [node]) if "type" not in node else [node]
            for branch in branches:  # a union: each kind's
                body = schema.valid(branch, seed)
                r = rest_refusals.send(s, {**case, "body": body})
                taken.append((method, path, r.status_code))
                if r.status_code >= 500 or (r.status_code == 400 and _malformed(r, body)):
                    wrong.append(f"{method} {path} {json.dumps(body)[:200]}: {r.text[:300]}")
                for constraint, at, bad in schema.violations(branch, body, ()):
                    r = rest_refusals.send(s, {**case, "body": bad})
                    refused[constraint.split(" (")[0]] += 1
                    error = r.json().get("error", "") if r.status_code == 400 else r.text
                    if r.status_code != 400 or not _names(error, at, (method, path)):
                        shown = f"{constraint} at {_shown_path(at)}: {json.dumps(bad)[:200]}"
                        wrong.append(f"{method} {path} {shown}: {r.status_code} {error[:300]}")
    print(f"{len(routes)} routes with a body; valid bodies answered {taken}; "
          f"{refused.total()} violations: {dict(refused.most_common())}")  # fmt: skip
    assert not wrong, f"{len(wrong)} answered otherwise:\n" + "\n".join(wrong)
    assert len(routes) >= 15 and refused.total() > 300
