"""Graphs of motion models (modb.graphs kind 'models'): nodes naming models, the transitions allowed
between them, each node's type (start, end, idle, standard) and action. Built for the models of a
collection (family.py builds those it lacks first), listed, exported and imported as JSON; the
database checks every graph written (modb.model_graph_problem), so a broken one is refused with
its reason whoever writes it.

A primitive's node type comes from its name as `modb annotate --steps` names them
(modb_kernel.primitives.node_type): `left_start` / `right_start` are start nodes, `left_stop` /
`right_stop` end nodes, `idle` an idle node, steps and turning steps standard nodes; another
primitive whose name says start (begin), end (stop) or idle (stand) takes that type. Transitions
alternate the feet: a primitive swinging the left foot is followed by one swinging the right (a
primitive whose name names no side follows and is followed by any)."""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

import psycopg
from psycopg.types.json import Jsonb

from modb_kernel.primitives import node_type
from modb_kernel.step_search import swing_side

from .store import KIND as MODEL_KIND

KIND = "models"
FORMAT = "modb graph of models"
STEPS = ("left_step", "right_step")
WALKING = STEPS + ("left_turning_step", "right_turning_step")
# other primitives a walk graph takes in, by what their name says they are
ROLES = (("start", re.compile(r"start|begin", re.I)), ("end", re.compile(r"stop|end", re.I)),
         ("idle", re.compile(r"idle|stand", re.I)))  # fmt: skip

LATEST_MODELS = """
SELECT s.primitive, s.id, s.name, s.version, s.skeleton_id
  FROM modb.model_status s
 WHERE s.kind = %s AND s.collection = %s AND s.latest
 ORDER BY s.primitive, s.name
"""


class GraphError(ValueError):
    pass


@dataclass(frozen=True)
class ModelGraph:
    id: int
    name: str
    skeleton_id: int
    data: dict[str, Any]
    created_at: str

    def describe(self) -> str:
        nodes = self.data["nodes"]
        kinds = {}
        for node in nodes.values():
            kinds.setdefault(node.get("type", "standard"), []).append(node)
        types = ", ".join(f"{len(v)} {k}" for k, v in sorted(kinds.items()))
        return (f"{self.name} (graph of models): {len(nodes)} nodes ({types}), "
                f"{len(self.data.get('transitions', []))} transitions, skeleton "
                f"{self.skeleton_id}" + (f", collection {self.data['collection']}"
                                         if self.data.get("collection") else "")
                + "; models: " + ", ".join(f"{n} = {_model_words(v)}"
                                           for n, v in sorted(nodes.items())))  # fmt: skip


def _model_words(node: dict[str, Any]) -> str:
    """'cmu16_left_step v2 (id 8)': which version of which model a node plays."""
    if "model" in node and "version" in node:
        return f"{node['model']} v{node['version']} (id {node['model_id']})"
    return f"model id {node['model_id']}"


def role(primitive: str) -> str | None:
    """The node type of a primitive in a walk (None: it is not part of one, e.g. an action)."""
    kind = node_type(primitive)
    if kind != "standard" or primitive in WALKING:
        return kind
    for named, pattern in ROLES:
        if pattern.search(primitive):
            return named
    return None


def step_graph(models: list[dict[str, Any]], collection: str,
               standing: dict[str, Any] | None = None,
               actions: tuple[str, ...] = ()) -> dict[str, Any]:  # fmt: skip
    """The document of a character: steps and turning steps alternating feet, start nodes
    leading into them, stop (end) nodes after them, an idle node after the stops (after the
    steps where there are none: the synthesis settles into standing) that repeats and leads to
    the starts; `standing` (captured standing frames) where there is no idle model; the
    `actions` (primitives of models among `models`) as action nodes reached from idle and
    leading back to it (without an idle node: from and to the walk, whose end it stands in)."""
    by_primitive = {m["primitive"]: m for m in models}
    missing = [p for p in STEPS if p not in by_primitive]
    if missing:
        raise GraphError(f'collection "{collection}" has no current model of '
                         f"{' or '.join(missing)}: build them first (modb model build NAME "
                         f"--collection {collection} --primitive {missing[0]})")  # fmt: skip
    nodes = {p: _node(m, role(p)) for p, m in sorted(by_primitive.items()) if role(p)}
    for p in actions:
        nodes[p] = {**_node(by_primitive[p], "action"), "action": p}
    sides = {n: swing_side(n) for n in nodes}

    def of(kind: str) -> list[str]:
        return [n for n, v in nodes.items() if v["type"] == kind]

    def joined(ends: list[str], to: list[str]) -> list[dict[str, str]]:
        """Every transition from ends to to that alternates the feet."""
        return [{"from": a, "to": b} for a in ends for b in to
                if sides[a] is None or sides[b] is None or sides[a] != sides[b]]  # fmt: skip

    standard, starts, ends, idles = of("standard"), of("start"), of("end"), of("idle")
    transitions = joined(standard, standard) + joined(starts, standard) + joined(standard, ends)
    for idle in idles:
        transitions += [{"from": e, "to": idle} for e in ends or standard]
        transitions += [{"from": idle, "to": idle}] + [{"from": idle, "to": s} for s in starts]
    for action in actions:
        transitions += [{"from": a, "to": action} for a in idles or ends or standard]
        transitions += [{"from": action, "to": b} for b in idles or starts or standard]
    data = {"nodes": nodes, "transitions": transitions, "collection": collection}
    if standing is not None and not idles:
        data["standing"] = standing
    return data


def _node(model: dict[str, Any], role: str) -> dict[str, Any]:
    return {"model_id": model["id"], "model": model["name"], "version": model["version"],
            "type": role, "action": "walk"}  # fmt: skip


def build(conn: psycopg.Connection, name: str, collection: str,
          chosen: list[str] | None = None,
          standing: dict[str, Any] | None = None,
          actions: list[str] | None = None) -> ModelGraph:  # fmt: skip
    """Stores (or replaces) the graph `name` of the latest versions of the collection's models,
    one per primitive: the only one there is, or the one `chosen` names (refused, naming them,
    when several models of a primitive could serve); standing: captured standing frames for a
    graph without an idle model (family.standing_frames)."""
    with conn.cursor(row_factory=psycopg.rows.dict_row) as cur:
        found = cur.execute(LATEST_MODELS, [MODEL_KIND, collection]).fetchall()
    unknown = sorted(set(chosen or ()) - {m["name"] for m in found})
    if unknown:
        raise GraphError(f'no model {", ".join(unknown)} of collection "{collection}" '
                         "(modb model list --collection names them)")  # fmt: skip
    models = []
    for primitive in dict.fromkeys(m["primitive"] for m in found):
        if role(primitive) is None and primitive not in (actions or ()):
            continue  # not part of a walk, and not one of the actions asked for
        these = [m for m in found if m["primitive"] == primitive]
        picked = [m for m in these if m["name"] in (chosen or ())] or these
        if len(picked) > 1:
            raise GraphError(f'collection "{collection}" has {len(picked)} models of {primitive} ('
                             f"{', '.join(m['name'] for m in picked)}): say which with --model "
                             "NAME")  # fmt: skip
        models.append(picked[0])
    data = step_graph(models, collection, standing,
                      tuple(a for a in actions or () if a in {m["primitive"] for m in models}))
    skeletons = {m["skeleton_id"] for m in models if m["primitive"] in data["nodes"]}
    if len(skeletons) != 1:
        raise GraphError(f'the step models of "{collection}" are of {len(skeletons)} skeletons')
    return save(conn, name, skeletons.pop(), data)


def save(conn: psycopg.Connection, name: str, skeleton_id: int, data: dict[str, Any]) -> ModelGraph:
    """Inserts or replaces the graph (the database checks it)."""
    with conn.transaction():
        conn.execute("INSERT INTO modb.graph_names (name, kind) VALUES (%s, %s) "
                     "ON CONFLICT DO NOTHING", [name, KIND])  # fmt: skip
        conn.execute(
            "INSERT INTO modb.graphs (name, kind, skeleton_id, data) VALUES (%s, %s, %s, %s) "
            "ON CONFLICT (name, kind) DO UPDATE SET skeleton_id = excluded.skeleton_id, "
            "data = excluded.data",
            [name, KIND, skeleton_id, Jsonb(data)],
        )
    return load(conn, name)


def listing(conn: psycopg.Connection) -> list[ModelGraph]:
    rows = conn.execute(
        "SELECT id, name, skeleton_id, data, created_at::text FROM modb.graphs WHERE kind = %s "
        "ORDER BY name", [KIND]
    ).fetchall()  # fmt: skip
    return [ModelGraph(*r) for r in rows]


def load(conn: psycopg.Connection, name: str) -> ModelGraph:
    row = conn.execute(
        "SELECT id, name, skeleton_id, data, created_at::text FROM modb.graphs "
        "WHERE kind = %s AND name = %s", [KIND, name]
    ).fetchone()  # fmt: skip
    if row is None:
        raise GraphError(f'no graph of models "{name}" (modb model graph list names them)')
    return ModelGraph(*row)


def delete(conn: psycopg.Connection, name: str) -> None:
    load(conn, name)
    with conn.transaction():  # its row goes with its name (83_graphs.sql)
        conn.execute("DELETE FROM modb.graph_names WHERE name = %s AND kind = %s", [name, KIND])


def export_document(conn: psycopg.Connection, name: str) -> dict[str, Any]:
    """The graph as a file: its nodes name their models by name and version, so it imports into
    another database that holds those models."""
    graph = load(conn, name)
    nodes = {}
    for node_name, node in graph.data["nodes"].items():
        row = conn.execute("SELECT name, version FROM modb.models WHERE id = %s",
                           [node["model_id"]]).fetchone()  # fmt: skip
        if row is None:
            raise GraphError(f'node "{node_name}" names model {node["model_id"]}, which is gone')
        nodes[node_name] = {k: v for k, v in node.items() if k != "model_id"} | {
            "model": row[0], "version": row[1]}  # fmt: skip
    return {"format": FORMAT, "name": graph.name, "data": {**graph.data, "nodes": nodes}}


def import_document(conn: psycopg.Connection, document: Any, name: str | None) -> ModelGraph:
    """Stores an exported graph, its nodes' models found here by name and version."""
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        raise GraphError(f'not a graph of models: expected "format": "{FORMAT}"')
    data = document.get("data")
    if not isinstance(data, dict) or not isinstance(data.get("nodes"), dict):
        raise GraphError('"data" must hold "nodes" (and "transitions")')
    nodes, skeletons = {}, set()
    if not data["nodes"]:
        raise GraphError('"nodes" is empty: a graph of models has at least one node')
    for node_name, node in data["nodes"].items():
        if not isinstance(node, dict):
            raise GraphError(f'node "{node_name}" must be an object with "model" and "version"')
        row = conn.execute(
            "SELECT id, skeleton_id FROM modb.models "
            "WHERE name = %s AND version = %s AND kind = %s",
            [node.get("model"), node.get("version"), MODEL_KIND],
        ).fetchone()
        if row is None:
            raise GraphError(f'node "{node_name}": no motion model "{node.get("model")}" version '
                             f'{node.get("version")} here: import that model first')  # fmt: skip
        nodes[node_name] = {**node, "model_id": row[0]}
        skeletons.add(row[1])
    if len(skeletons) != 1:
        raise GraphError(f"its models are of {len(skeletons)} skeletons here")
    return save(conn, name or document.get("name") or "imported", skeletons.pop(),
                {**data, "nodes": nodes})  # fmt: skip
