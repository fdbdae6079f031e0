"""Synthesis from a graph of motion models (after the DFKI pipeline): step after step, the next
primitive from the graph's transitions, its scores from the tree search and a refinement toward the
step's constraints (step_search), its motion rebuilt, placed where the last step left the body and
joined to it. Plain numpy and scipy: modb.synthesize_from_models runs it in the server, and the
client's `modb synth --models` calls that function, so both give the same motion for a seed.

The world: metres, Y up; the character starts with its pelvis above the origin facing +Z. Each step
is placed so that its stance foot stands where the last step's swing foot landed and its first
heading is the last step's last; the pose's jump at the seam (the step's first frame stands in for
the last one played) decays over the new frames (inertialization), and meanwhile the pelvis is moved
on the ground so that the stance foot keeps to the step's own path: the contact foot stays planted.

Each step's constraints: the swing foot lands where the step, turned toward the current goal by up
to what the model's steps turn, would put it; the body ends facing that way. A goal is reached when
the pelvis comes within the arrival radius on the ground. After the last goal the graph's end node
(type "end") plays once where the current one leads to one, then its idle node (type "idle") over
and over; without those, the character finishes its step and stands in that pose.
"""

import json

import numpy as np

from . import foot_hold, inertialization, memory, motion_model, quaternion
from .database import Statement, StoreError
from .step_search import Rig, StepModel, hip_heading, rotate_y, stance_side, wrap

MAX_SECONDS = 600.0
MAX_COORDINATE = 1e6  # metres from the origin, as the snippet chain's goals
ARRIVAL_RADIUS_M = 0.5
MAX_ARRIVAL_RADIUS_M = 10.0
TURN_REACH = 1.0  # a step asks at most the turn 95% of the model's steps make


class SynthesisError(ValueError):
    pass


def node_types(graph):
    return {name: node.get("type", "standard") for name, node in graph["nodes"].items()}


def successor_lists(graph):
    """node name -> the nodes its transitions lead to, in the graph's order: made once, so that a
    step costs the transitions of its node, not the graph's."""
    out = {name: [] for name in graph["nodes"]}
    for t in graph.get("transitions", []):
        out[t["from"]].append(t["to"])
    return out


def no_interrupts():
    """What a Synthesis calls between pieces of work where nothing can interrupt it (the
    client); the server passes one that lets a cancel or a statement timeout in."""


def stance_floors(models):
    """{(side, point): metres}: the floors of the stance feet the step models' captures stood on
    (their documents' "stance", from 0.27.0; the median where several models stand on one foot)."""
    found = {}
    for model in models:
        stance = model.model.get("stance")
        if stance and model.swing is not None:
            side = stance_side(model.swing)
            for point, height in stance.items():
                found.setdefault((side, point), []).append(height)
    return {key: float(np.median(values)) for key, values in found.items()}


def start_node(graph, rng):
    """A start node (one drawn with rng when several), else the first standard node."""
    types = node_types(graph)
    starts = [n for n, t in types.items() if t == "start"]
    if starts:
        return starts[rng.integers(len(starts))]
    standard = [n for n, t in types.items() if t == "standard"]
    if not standard:
        raise SynthesisError("the graph has no start or standard node to walk from")
    return standard[0]


class Body:
    """The motion so far: frames, and where the body stands at the end of the last step."""

    def __init__(self, rig):
        self.rig = rig
        self.rotations, self.translations = [], []  # as the seams joined them
        self.shown = []  # the rotations played: the stance feet held, where they are
        self.dropped = 0  # frames no longer kept (an avatar keeps the last step's only)
        self.feet = {}  # side -> (x, z) where that ankle stood at the last frame
        self.heading = 0.0  # the last frame's hip heading

    @property
    def n_frames(self):
        return self.dropped + sum(len(r) for r in self.rotations)

    def drop_all_but_the_last_step(self):
        """Frames no longer needed (an avatar has played them): the next seam needs the last."""
        self.dropped += sum(len(r) for r in self.rotations[:-1])
        del self.rotations[:-1], self.translations[:-1], self.shown[:-1]

    def last_two(self):
        r = np.concatenate(self.rotations[-2:])[-2:]
        t = np.concatenate(self.translations[-2:])[-2:]
        return r, t

    def pelvis(self):
        r, t = self.last_two()
        return self.rig.positions(r[-1:], t[-1:])[0, self.rig.pelvis][[0, 2]]


def placed(rig, rotations, translations, yaw, shift):
    """The frames turned by yaw about +Y and moved by shift (x, z) on the ground: the top joints
    carry it (a skeleton whose top joint has no translation cannot travel)."""
    turn = quaternion.about_axis("Y", yaw)
    rotations, translations = rotations.copy(), translations.copy()
    for j, parent in enumerate(rig.parents):
        if parent >= 0:
            continue
        if j not in rig.translated:
            raise SynthesisError(f"top joint {rig.names[j]} has no translation: it cannot travel")
        k = rig.translated.index(j)
        rotations[:, j] = quaternion.multiply(turn[None], rotations[:, j])
        moved = quaternion.rotate(np.broadcast_to(turn, (len(translations), 4)), translations[:, k])
        translations[:, k] = moved + np.array([shift[0], 0.0, shift[1]])
    return quaternion.canonical(rotations), translations


class Synthesis:
    def __init__(self, graph, models, rig, goals, seconds, seed, radius=ARRIVAL_RADIUS_M,
                 interrupts=no_interrupts, hold_feet=True):  # fmt: skip
        """graph: the graph document; models: node name -> StepModel; goals: [(x, z)];
        interrupts: called before each piece of work (a step, a successor's search); hold_feet:
        stance feet held from touchdown to lift-off (foot_hold)."""
        if not 0 < seconds <= MAX_SECONDS:
            raise SynthesisError(f"seconds is {seconds}: give more than 0, at most {MAX_SECONDS:g}")
        rates = {m.model["fps"] for m in models.values()}
        if len(rates) != 1:
            raise SynthesisError(f"the graph's models are at {len(rates)} frame rates: retarget "
                                 "their examples to one first")  # fmt: skip
        self.graph, self.models, self.rig = graph, models, rig
        self.types, self.successors = node_types(graph), successor_lists(graph)
        self.interrupts = interrupts
        self.fps = rates.pop()
        self.goals = [np.asarray(g, dtype=np.float64) for g in goals]
        self.seconds, self.radius = float(seconds), float(radius)
        self.rng = np.random.default_rng(seed)
        self.seams = inertialization.Seams(rig.parents, rig.offsets, rig.translated, rig.pelvis)
        self.body = Body(rig)
        self.hold = foot_hold.FootHold(rig.parents, rig.offsets, rig.translated, rig.names,
                                       rig.joint_map, self.fps,
                                       stance_floors(models.values())) if hold_feet else None
        self.steps, self.notes = [], []
        self.node = None  # the node of the last step
        self.goal = 0  # index of the current goal
        self.reached = {}  # goal index -> frame reached
        self.closest = np.inf  # metres: the pelvis's least distance to the current goal so far
        self.stood_from = None

    @property
    def wanted_frames(self):
        return int(round(self.seconds * self.fps)) + 1

    def run(self):
        """The strip: steps toward the goals until the last is reached or the time is up, then
        what follows the last goal (finish)."""
        while self.body.n_frames < self.wanted_frames and self.goal < len(self.goals):
            self.walk_step()
        if self.body.n_frames < self.wanted_frames:
            self.finish(self.node)
        if self.goal < len(self.goals):
            x, z = self.goals[self.goal]
            self.notes.append(f"goal {self.goal + 1} ({x:g}, {z:g}) not reached in "
                              f"{self.seconds:g} s (closest {self.closest:.2f} m)")  # fmt: skip
        return self

    def walk_step(self):
        """One more step toward the current goal: from a start node first, then from the graph's
        transitions (an avatar calls this as its queue of frames runs low)."""
        node, search = (start_node(self.graph, self.rng), None) if self.node is None else (
            self.next_node(self.node))  # fmt: skip
        self.step(node, search=search)
        self.node = node

    def next_node(self, node):
        """(the successor whose tree search meets the next step's constraints best, that search's
        (scores, candidates examined) or None when there was one successor only)."""
        types = self.types
        choices = [n for n in self.successors[node] if types[n] in ("standard", "start")]
        choices = [n for n in choices if types[n] == "standard"] or choices
        if not choices:
            raise SynthesisError(f'node "{node}" leads to no standard node: the walk cannot go on')
        if len(choices) == 1:
            return choices[0], None
        searched = []
        for n in choices:
            self.interrupts()
            target = self.target(self.models[n])
            found, examined = self.models[n].search(target, self.rng)
            searched.append((float(self.models[n].errors(found, target)[0]), n,
                             (found, examined)))  # fmt: skip
        _, best, search = min(searched, key=lambda row: row[0])
        return best, search  # the search that chose it is the step's

    def target(self, model, toward=None):
        """(landing x, z, turn) in the step's frame: the model's usual step turned toward the
        current goal, by at most TURN_REACH times what its steps turn."""
        if toward is None and self.goal < len(self.goals):
            toward = self.goals[self.goal]
        turn = 0.0
        if toward is not None:
            where = self.body.pelvis() if self.body.rotations else np.zeros(2)
            to_goal = toward - where
            travel = self.body.heading + np.arctan2(*model.usual_travel)
            wanted = wrap(np.arctan2(to_goal[0], to_goal[1]) - travel)
            reach = TURN_REACH * model.turn_reach
            turn = float(np.clip(wanted, -reach, reach))
        landing = rotate_y(model.usual_landing, turn / 2)
        return np.array([landing[0], landing[1], model.usual_turn + turn])

    def step(self, node, toward=None, search=None):
        self.interrupts()
        model = self.models[node]
        target = self.target(model, toward)
        found, examined = model.search(target, self.rng) if search is None else search
        refined = model.refine(found, target)
        record = {
            "node": node,
            "model": model.model.get("name"),
            "swing": model.swing,
            "version": model.model.get("version"),
            "goal": self.goal + 1 if self.goal < len(self.goals) else None,
            "first_frame": self.body.n_frames,
            "target": target.round(4).tolist(),
            "tree_error_m": float(model.errors(found, target)[0]),
            "error_m": float(model.errors(refined, target)[0]),
            "random_error_m": model.best_random(target, self.rng),
            "mahalanobis": float(model.mahalanobis(refined)[0][0]),
            "candidates": examined,
            "scores": refined.tolist(),
        }
        self.add(model, refined)
        record["n_frames"] = self.body.n_frames - record["first_frame"]
        self.steps.append(record)

    def add(self, model, scores):
        """The motion of the scores placed after the body's last frame and joined to it."""
        rig, body = self.rig, self.body
        split = model.split
        rotations, translations, _ = motion_model.frames_from_scores(model.model, scores[:split],
                                                                     scores[split:])  # fmt: skip
        positions = rig.positions(rotations[:1], translations[:1])[0]
        first = float(hip_heading(positions, rig.left_hip, rig.right_hip))
        stance = stance_side(model.swing)
        if not body.rotations:  # the first step: its pelvis above the origin, facing +Z
            anchor, at = positions[rig.pelvis][[0, 2]], np.zeros(2)
        elif stance is None:
            anchor, at = positions[rig.pelvis][[0, 2]], body.pelvis()
        else:
            anchor, at = positions[rig.ankle[stance]][[0, 2]], body.feet[stance]
        yaw = body.heading - first
        shift = at - rotate_y(anchor, yaw)
        rotations, translations = placed(rig, rotations, translations, yaw, shift)
        # the step as placed: its feet's heights and contacts (kept apart from what the seam and
        # keep_planted change, in place where a step is too short to inertialize)
        reference = rotations.copy(), translations.copy()
        if body.rotations:
            old_r, old_t = body.last_two()
            planted = rig.positions(rotations, translations)
            rotations, translations = self.seams.inertialize(old_r, old_t, rotations,
                                                             translations, self.fps)  # fmt: skip
            if stance is not None:
                foot = rig.ankle[stance]
                self.keep_planted(rotations, translations, foot, planted[:, foot])
            rotations, translations = rotations[1:], translations[1:]
            reference = reference[0][1:], reference[1][1:]
        # The hold's changes are not a seam's to carry: the body keeps the frames as joined, for
        # the next seam and the next step's placement, beside the frames shown.
        shown = rotations if self.hold is None else self.hold.feed(rotations, translations,
                                                                   reference)  # fmt: skip
        body.rotations.append(rotations)
        body.translations.append(translations)
        body.shown.append(shown)
        end = rig.positions(rotations[-1:], translations[-1:])[0]
        body.heading = float(hip_heading(end, rig.left_hip, rig.right_hip))
        body.feet = {side: end[joint][[0, 2]] for side, joint in rig.ankle.items()}
        self.mark_goals(rotations, translations)

    def keep_planted(self, rotations, translations, foot, path):
        """Moves the frames on the ground so that the foot joint follows `path` (its positions
        before the seam's offsets): the offsets bend the legs, not the foot's contact."""
        rig = self.rig
        slip = (path - rig.positions(rotations, translations)[:, foot]) * np.array([1.0, 0.0, 1.0])
        for j, parent in enumerate(rig.parents):
            if parent < 0:
                translations[:, rig.translated.index(j)] += slip

    def mark_goals(self, rotations, translations):
        """Goals the new frames reach (the pelvis within the radius on the ground), in order."""
        if self.goal >= len(self.goals):
            return
        pelvis = self.rig.positions(rotations, translations)[:, self.rig.pelvis][:, [0, 2]]
        start = self.body.n_frames - len(rotations)
        for k, p in enumerate(pelvis):
            if self.goal >= len(self.goals):
                break
            distance = float(np.linalg.norm(p - self.goals[self.goal]))
            self.closest = min(self.closest, distance)
            if distance <= self.radius:
                self.reached[self.goal] = start + k
                self.goal += 1
                self.closest = np.inf

    def finish(self, node):
        """After the last goal: the end node and then the idle node where the graph has them,
        else the last pose held."""
        types, after = self.types, self.successors
        ends = [n for n in after[node] if types[n] == "end"]
        if ends:
            self.step(ends[0], toward=None)
            self.notes.append(f'the end node "{ends[0]}" played after the last goal')
            idles = [n for n in after[ends[0]] if types[n] == "idle"]
        else:
            idles = [n for n in after[node] if types[n] == "idle"]
        while idles and self.body.n_frames < self.wanted_frames:
            self.step(idles[0], toward=None)
        if idles:
            self.notes.append(f'the idle node "{idles[0]}" played until the end')
        if self.body.n_frames < self.wanted_frames:
            self.stood_from = self.body.n_frames - 1
            r, t = self.body.last_two()
            hold = self.wanted_frames - self.body.n_frames
            self.body.rotations.append(np.repeat(r[-1:], hold, axis=0))
            self.body.translations.append(np.repeat(t[-1:], hold, axis=0))
            self.body.shown.append(np.repeat(self.body.shown[-1][-1:], hold, axis=0))
            when = f"{self.stood_from / self.fps:.2f} s"
            self.notes.append(
                f'after the end node "{ends[0]}" the character stands in its last pose from {when}'
                if ends else f'the graph has no end or idle node after "{node}": the character '
                f"finished its step and stands in that pose from {when}"
            )  # fmt: skip

    def frames(self):
        """(rotations, translations) of the strip, cut to the seconds asked for."""
        n = self.wanted_frames
        return np.concatenate(self.body.shown)[:n], np.concatenate(self.body.translations)[:n]

    def report(self):
        return {
            "fps": self.fps,
            "seconds": self.seconds,
            "goals": [g.tolist() for g in self.goals],
            "reached": {str(k + 1): v for k, v in self.reached.items()},
            "steps": self.steps,
            "stood_from_frame": self.stood_from,
            "notes": self.notes,
        }


def step_models(graph, documents, rig, interrupts=no_interrupts):
    """node name -> StepModel, from documents: model id -> (model document, its tree); nodes of
    one model share its StepModel (prepared once)."""
    prepared, out = {}, {}
    for name, node in graph["nodes"].items():
        ident = node["model_id"]
        doc, tree = documents[ident]
        if not tree:
            raise SynthesisError(f'the model of node "{name}" has no acceleration tree: '
                                 "rebuild it (modb model tree NAME)")  # fmt: skip
        if ident not in prepared:
            interrupts()
            prepared[ident] = StepModel(doc, tree, rig)
        out[name] = prepared[ident]
    return out


GRAPH = Statement(
    "SELECT data::text AS data, skeleton_id FROM modb.graphs WHERE name = $1 AND kind = 'models'",
    ("text",),
)
MODELS = Statement(
    """SELECT m.id, m.name, m.version, m.data::text AS data, (m.meta->'tree')::text AS tree,
              s.hierarchy::text AS hierarchy, s.joint_map::text AS joint_map
         FROM modb.models m JOIN modb.skeletons s ON s.id = m.skeleton_id
        WHERE m.id = ANY ($1)""",
    ("bigint[]",),
)


FOOT_HOLD = Statement("SELECT current_setting('modb.foot_hold', true) AS value")


def foot_hold_on(db):
    """The session's modb.foot_hold (on when never set; a value SET before the library was
    loaded is read as PostgreSQL reads a boolean)."""
    value = (db.run(FOOT_HOLD)[0]["value"] or "on").strip().lower()
    return value not in ("off", "of", "false", "fals", "fal", "fa", "f", "no", "n", "0")


def load(db, graph_name, interrupts=no_interrupts):
    """(graph document, node name -> StepModel, Rig) of the stored graph of models."""
    found = db.run(GRAPH, [graph_name])
    if not found:
        raise StoreError(f'no graph of models "{graph_name}"', sqlstate="P0002",
                         hint="modb model graph list names them; modb model graph NAME "
                         "--collection C builds one")  # fmt: skip
    graph = json.loads(found[0]["data"])
    ids = sorted({int(n["model_id"]) for n in graph["nodes"].values()})
    rows = {r["id"]: r for r in db.run(MODELS, [ids])}
    missing = [i for i in ids if i not in rows]
    if missing:
        raise StoreError(f'graph "{graph_name}" names motion model {missing[0]}, which is gone',
                         hint="build the graph again (modb model graph NAME --collection C)",
                         sqlstate="P0002")  # fmt: skip
    documents = {}
    for i, r in rows.items():
        doc = json.loads(r["data"])
        doc["name"], doc["version"] = r["name"], r["version"]
        documents[i] = (doc, json.loads(r["tree"]) if r["tree"] else None)
    first = rows[ids[0]]
    try:
        rig = Rig({"hierarchy": json.loads(first["hierarchy"]),
                   "joint_map": json.loads(first["joint_map"])})  # fmt: skip
        return graph, step_models(graph, documents, rig, interrupts), rig
    except ValueError as e:
        raise StoreError(f'graph "{graph_name}": {e}', sqlstate="22023") from None


def _sound_goals(goals):
    """A non-empty list of [x, z] pairs of finite numbers within MAX_COORDINATE."""
    if not goals or not all(isinstance(g, (list, tuple)) and len(g) == 2 for g in goals):
        return False
    values = [v for g in goals for v in g]
    return all(isinstance(v, (int, float)) and abs(v) <= MAX_COORDINATE for v in values)


def synthesize_stored(db, graph_name, goals, seconds, seed, radius=ARRIVAL_RADIUS_M):
    """[(fps, n_frames, rotations, translations, report)]: what modb.synthesize_from_models
    returns (its COMMENT says what)."""
    if graph_name is None:
        raise StoreError("graph is NULL: name a graph of models (modb model graph list)",
                         sqlstate="22004")  # fmt: skip
    if seed is None or seed < 0:
        raise StoreError(f"seed is {seed}: give a whole number >= 0", sqlstate="22023")
    if seconds is None or not 0 < seconds <= MAX_SECONDS:
        raise StoreError(f"seconds is {seconds}: give more than 0, at most {MAX_SECONDS:g}",
                         sqlstate="22023")  # fmt: skip
    if not _sound_goals(goals):
        raise StoreError(f"goals must be a non-empty float8[][2] of world X and Z in metres, each "
                         f"finite and at most {MAX_COORDINATE:g} from the origin, e.g. "
                         "ARRAY[[0, 6], [5, 8]]", sqlstate="22023")  # fmt: skip
    if radius is None or not 0 < radius <= MAX_ARRIVAL_RADIUS_M:
        raise StoreError(f"arrival_radius is {radius}: give metres above 0, at most "
                         f"{MAX_ARRIVAL_RADIUS_M:g}", sqlstate="22023")  # fmt: skip
    graph, models, rig = load(db, graph_name, db.check_interrupts)
    try:
        synthesis = Synthesis(graph, models, rig, goals, seconds, seed, radius,
                              db.check_interrupts, foot_hold_on(db)).run()  # fmt: skip
    except ValueError as e:
        raise StoreError(f'graph "{graph_name}": {e}', sqlstate="22023") from None
    rotations, translations = synthesis.frames()
    del models, synthesis.models  # the prepared models and the steps' frames: garbage from here
    result = [(
        synthesis.fps,
        len(rotations),
        rotations.astype(np.float32).tolist(),
        translations.astype(np.float32).tolist() if translations.shape[1] else None,
        json.dumps(synthesis.report()),
    )]  # fmt: skip
    del synthesis, rotations, translations
    memory.release()  # each call's documents and frames go back to the system, not the session
    return result
