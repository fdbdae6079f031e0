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

Each step's constraints: the swing foot lands where the step, turned by what leaves the shortest
path to the current goal (course.py: the sharpest turn the graph's steps make bounds the path's
curvature, so a goal inside the turning circle is approached by widening first), would put it; the
body ends facing that way. Of the successors the graph allows (steps, turning steps), the one whose
step leaves the shortest path (plus its constraint error) plays. A goal is reached when the pelvis
comes within the arrival radius on the ground. After the last goal the graph's end node (a stop)
plays where the last step leads to one; then the character comes to rest and stands (standing.py):
from the idle node's model, else from the graph's captured "standing" frames; without either it
finishes its step and stands in that pose.
"""

import json

import numpy as np

from . import (course, foot_hold, inertialization, memory, model_actions, motion_model,
               prepared_models, standing)  # fmt: skip
from .database import Statement, StoreError
from .placement import placed
from .step_search import hip_heading, rotate_y, stance_side, wrap

MAX_SECONDS = 600.0
MAX_COORDINATE = 1e6  # metres from the origin, as the snippet chain's goals
ARRIVAL_RADIUS_M = 0.5
MAX_ARRIVAL_RADIUS_M = 10.0
IDLE_SPREAD = 0.5  # an idle sample's scores this near its mixture component's mean
MIN_TRAVEL_M = 0.2  # a primitive travelling less has no direction of travel
LEAST_TURN = np.radians(3.0)  # a model turning less than this per step is taken to turn this much


class SynthesisError(ValueError):
    pass


# an action's report record as its step's (an avatar's readout reads these)
ACTION_STEP_KEYS = ("model", "version", "first_frame", "n_frames", "candidates", "tree_error_m",
                    "error_m")  # fmt: skip


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


def travel_angle(model):
    """The angle of the model's usual travel from its heading (a step's sways with the foot it
    swings); 0 for one that hardly travels (a start, idle), whose travel has no direction."""
    if np.linalg.norm(model.usual_travel) < MIN_TRAVEL_M:
        return 0.0
    return float(np.arctan2(*model.usual_travel))


def turning_radius(models, types):
    """The radius (metres) the graph's standard steps turn on at their sharpest, the wider of
    the two ways: a stride (a step of each foot, the best of each side's models that way) travels
    its steps' travel and turns their turns that way (at least LEAST_TURN a step). Each way is
    counted over both feet: a step's own turn sways with the foot it swings."""
    standard = [m for name, m in models.items() if types.get(name) == "standard"]
    if not standard:
        return 1.0
    radii = []
    for way in (1.0, -1.0):
        travel, turn = 0.0, 0.0
        for side in ("left", "right"):
            these = [m for m in standard if m.swing in (side, None)] or standard
            best = max(these, key=lambda m: way * m.turn_range[0 if way < 0 else 1])
            travel += float(np.linalg.norm(best.usual_travel))
            turn += max(way * best.turn_range[0 if way < 0 else 1], LEAST_TURN)
        radii.append(travel / turn)
    return float(max(radii))


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

    def last_two(self, shown=False):
        """The last two frames as joined (shown: as played, the feet held)."""
        r = np.concatenate((self.shown if shown else self.rotations)[-2:])[-2:]
        t = np.concatenate(self.translations[-2:])[-2:]
        return r, t

    def pelvis(self):
        r, t = self.last_two()
        return self.rig.positions(r[-1:], t[-1:])[0, self.rig.pelvis][[0, 2]]


class Synthesis:
    def __init__(self, graph, models, rig, goals, seconds, seed, radius=ARRIVAL_RADIUS_M,
                 interrupts=no_interrupts, hold_feet=True, actions=None):  # fmt: skip
        """graph: the graph document; models: node name -> StepModel (ActionModel for its action
        nodes); goals: [(x, z)]; interrupts: called before each piece of work (a step, a
        successor's search); hold_feet: stance feet held from touchdown to lift-off (foot_hold);
        actions: model_actions's, each after the goals its "after" counts."""
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
        self.seconds, self.radius = float(seconds), float(radius)
        kinds = [n for n, t in self.types.items() if t == "action"]
        actions = model_actions.checked(actions, len(goals), kinds)
        # the course: the goals and where each action is performed, in the order walked
        walked = model_actions.course(goals, actions, models)
        self.goals = [point for point, _, _ in walked]
        self.radii = [self.radius if r is None else r for _, r, _ in walked]
        self.planned = {k: a for k, (_, _, a) in enumerate(walked) if a is not None}
        self.due = []  # course entries of actions reached, to perform
        self.actions = []  # their report records
        self.stand_after = False  # an action played: a piece of standing before walking on
        self.rng = np.random.default_rng(seed)
        self.seams = inertialization.Seams(rig.parents, rig.offsets, rig.translated, rig.pelvis)
        self.body = Body(rig)
        self.floors = stance_floors(models.values())
        self.hold = foot_hold.FootHold(rig.parents, rig.offsets, rig.translated, rig.names,
                                       rig.joint_map, self.fps, self.floors) if hold_feet else None
        self.steps, self.notes = [], []
        self.node = None  # the node of the last step
        self.walked = None  # the last standard node played (a walk resumes after it)
        self.turning_radius = turning_radius(models, self.types)
        self.spot = None  # where the character stands while it rests (standing.Spot)
        self.rested_from = None  # the frame its settle ends
        self.captured = None  # the graph's captured standing frames, once read
        self.goal = 0  # index of the current goal
        self.reached = {}  # goal index -> frame reached
        self.closest = np.inf  # metres: the pelvis's least distance to the current goal so far
        self.stood_from = None

    @property
    def wanted_frames(self):
        return int(round(self.seconds * self.fps)) + 1

    def run(self):
        """The strip: steps toward the goals until the last is reached or the time is up (each
        action performed where it is reached), then what follows the last goal (finish)."""
        self.act_without_walking()
        while self.body.n_frames < self.wanted_frames and (
                self.goal < len(self.goals) or self.due or self.stand_after):  # fmt: skip
            if not self.act_step():
                self.walk_step()
        if self.body.n_frames < self.wanted_frames:
            self.finish(self.node)
        if self.goal < len(self.goals):
            x, z = self.goals[self.goal]
            self.notes.append(f"goal {self.goal + 1} ({x:g}, {z:g}) not reached in "
                              f"{self.seconds:g} s (closest {self.closest:.2f} m)")  # fmt: skip
        left = [a["primitive"] for k, a in sorted(self.planned.items())
                if k >= self.goal or k in self.due]  # fmt: skip
        if left:
            self.notes.append(f"not performed in {self.seconds:g} s: " + ", ".join(left))
        return self

    def act_without_walking(self):
        """An action whose place the character stands at before any step is due at once."""
        if self.goal in self.planned and not self.body.rotations and float(
                np.linalg.norm(self.goals[self.goal])) <= self.radii[self.goal]:  # fmt: skip
            self.reached[self.goal] = 0
            self.due.append(self.goal)
            self.goal += 1

    def act_step(self):
        """One piece toward the action reached (the walk's stop, coming to rest, the action, a
        piece of standing after it); False when no action is due (an avatar calls this before
        walk_step)."""
        if self.stand_after and not self.due:
            self.stand_after = False
            self.rest()
            return True
        self.arrive_early()
        if not self.due:
            return False
        entry = self.due[0]
        action = self.planned[entry]
        if self.standing_source() is None:
            raise SynthesisError(f'the action "{action["primitive"]}" needs the character to '
                                 "stand: the graph has no idle node or standing frames")
        if not self.stop_walking() and self.spot is None:
            # standing from the first frame (an action where the character starts): as it starts
            face = model_actions.facing(action, self.models[action["primitive"]],
                                        self.body.pelvis()) if self.body.rotations else None
            self.rest(face=face)
        elif self.spot is not None:
            self.due.pop(0)
            record = model_actions.perform(self, action["primitive"], action)
            self.actions.append(record)
            self.steps.append({"node": action["primitive"], "action": True, "goal": entry + 1,
                               **{k: record.get(k) for k in ACTION_STEP_KEYS}})  # fmt: skip
            self.stand_after = True
        return True

    def arrive_early(self):
        """The place of an action counts as reached once the next step would take the pelvis
        past it (half a stride away): the character stops there, not a step beyond."""
        k = self.goal
        if k not in self.planned or not self.body.rotations or self.spot is not None:
            return
        near = float(np.linalg.norm(self.body.pelvis() - self.goals[k])) <= self.half_stride
        if near or self.radii[k] == np.inf:  # inf: an action performed where the character is
            self.reached[k] = self.body.n_frames - 1
            self.due.append(k)
            self.goal += 1
            self.closest = np.inf

    @property
    def half_stride(self):
        """Half the median travel of the graph's standard steps (metres)."""
        travel = [np.linalg.norm(m.usual_travel) for n, m in self.models.items()
                  if self.types[n] == "standard"]  # fmt: skip
        return 0.5 * float(np.median(travel)) if travel else 0.0

    def set_goal(self, goal):
        """The course replaced by one goal (an avatar's new goal): actions not performed are
        dropped."""
        self.goals, self.radii = [np.asarray(goal, dtype=np.float64)], [self.radius]
        self.goal, self.reached, self.planned, self.due, self.closest = 0, {}, {}, [], np.inf

    def add_goal(self, goal, action=None):
        """A goal, or the place of an action (model_actions.checked's), after the course's."""
        if action is None:
            point, radius = np.asarray(goal, dtype=np.float64), None
        else:
            came_from = (self.goals[-1] if self.goals else
                         self.body.pelvis() if self.body.rotations else np.zeros(2))  # fmt: skip
            point, radius, _ = model_actions.stand_point(action, self.models[action["primitive"]],
                                                         came_from)  # fmt: skip
        if action is not None:
            self.planned[len(self.goals)] = action
        self.goals.append(point)
        self.radii.append(self.radius if radius is None else radius)

    def walk_step(self):
        """One more step toward the current goal: from a start node first (and again after a
        rest, where the graph has one; else the step after the last walked), then from the
        graph's transitions (an avatar calls this as its queue of frames runs low)."""
        if self.node is None or (self.spot is not None and self.walked is None):
            node, search = start_node(self.graph, self.rng), None
        elif self.spot is not None:
            starts = [n for n, t in self.types.items() if t == "start"]
            node, search = ((starts[self.rng.integers(len(starts))], None) if starts
                            else self.next_node(self.walked))  # fmt: skip
        else:
            node, search = self.next_node(self.node)
        self.spot = None
        self.step(node, search=search)
        self.node = node
        if self.types[node] == "standard":
            self.walked = node

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
            model = self.models[n]
            target = self.target(model)
            found, examined = model.search(target, self.rng)
            score = float(model.errors(found, target)[0]) + self.left_after(model, target)
            searched.append((score, n, (found, examined)))
        _, best, search = min(searched, key=lambda row: row[0])
        return best, search  # the search that chose it is the step's

    def goal_now(self):
        return self.goals[self.goal] if self.goal < len(self.goals) else None

    def left_after(self, model, target):
        """The path still to walk to the current goal after the model's usual step turned as the
        target asks (0 without a goal): what the model's step is for, not how far one sample
        strides (a longer stride in the same time is a faster swing, not a better step)."""
        goal = self.goal_now()
        if goal is None:
            return 0.0
        where = self.body.pelvis() if self.body.rotations else np.zeros(2)
        heading = self.body.heading + travel_angle(model)
        turn = float(target[2] - model.usual_turn)
        travel = rotate_y(np.array([0.0, np.linalg.norm(model.usual_travel)]), turn / 2)
        return course.left_after(where, heading, goal, travel, turn, self.turning_radius,
                                 self.radius)  # fmt: skip

    def target(self, model, toward=None):
        """(landing x, z, turn) in the step's frame: the model's usual step turned toward the
        current goal (or the planner's way), within the turns its steps make."""
        if toward is None and self.goal < len(self.goals):
            toward = self.goals[self.goal]
        turn = 0.0
        if toward is not None:
            where = self.body.pelvis() if self.body.rotations else np.zeros(2)
            to_goal = toward - where
            heading = self.body.heading + travel_angle(model)  # the way it travels
            wanted = wrap(np.arctan2(to_goal[0], to_goal[1]) - heading)
            low, high = (t - model.usual_turn for t in model.turn_range)
            aimed = float(np.clip(wanted, low, high))
            travel = np.array([0.0, np.linalg.norm(model.usual_travel)])
            widened = course.best_turn(where, heading, toward, travel, low, high,
                                       self.turning_radius, self.radius)  # fmt: skip
            # straight at the goal where that is as short (it is wherever the goal lies
            # outside the turning circle), else the planner's turn
            ways = [(course.left_after(where, heading, toward, rotate_y(travel, t / 2), t,
                                       self.turning_radius, self.radius), k, t)
                    for k, t in enumerate((aimed, widened))]  # fmt: skip
            turn = min(ways)[2]
        landing = rotate_y(model.usual_landing, turn / 2)
        return np.array([landing[0], landing[1], model.usual_turn + turn])

    def step(self, node, toward=None, search=None):
        self.interrupts()
        model = self.models[node]
        target = self.target(model, toward)
        found, examined = model.search(target, self.rng) if search is None else search
        refined = model.refine(found, target)
        # a refinement beyond where the model's own draws reach (a far-out shape, a foot faster
        # than any capture's) gives way to the tree's sample
        limit = model.model["mixture"].get("max_mahalanobis2")
        if limit and float(model.mahalanobis(refined)[0][0]) ** 2 > limit:
            refined = found
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
        self.append(rotations, translations, reference)

    def append(self, rotations, translations, reference=None, hold=True):
        """New frames after the body's last, as joined; reference: the same frames as placed,
        before the seams (the hold reads its contacts there; None: these frames). hold False:
        the frames' feet are set already (standing's IK): the hold follows them, shows them."""
        rig, body = self.rig, self.body
        # The hold's changes are not a seam's to carry: the body keeps the frames as joined, for
        # the next seam and the next step's placement, beside the frames shown.
        shown = rotations if self.hold is None else self.hold.feed(rotations, translations,
                                                                   reference)  # fmt: skip
        if not hold:
            shown = rotations
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
            if distance <= self.radii[self.goal]:
                self.reached[self.goal] = start + k
                if self.goal in self.planned:
                    self.due.append(self.goal)
                self.goal += 1
                self.closest = np.inf

    def finish(self, node):
        """After the last goal: the end node where the last step leads to one (stop_walking),
        then standing until the end (rest); with nothing to stand with, the last pose held."""
        self.stop_walking()
        if self.standing_source() is not None:
            while self.body.n_frames < self.wanted_frames:
                self.rest()
            self.notes.append(f"the character comes to rest at {self.rested_from / self.fps:.2f} s"
                              f" and stands ({self.standing_words()})")  # fmt: skip
            return
        if self.body.n_frames < self.wanted_frames:
            self.stood_from = self.body.n_frames - 1
            r, t = self.body.last_two()
            hold = self.wanted_frames - self.body.n_frames
            self.body.rotations.append(np.repeat(r[-1:], hold, axis=0))
            self.body.translations.append(np.repeat(t[-1:], hold, axis=0))
            self.body.shown.append(np.repeat(self.body.shown[-1][-1:], hold, axis=0))
            when = f"{self.stood_from / self.fps:.2f} s"
            self.notes.append(
                f'after the end node "{self.node}" the character stands in its last pose from '
                f"{when}" if self.types.get(self.node) == "end" else "the graph has no idle node "
                f'or standing frames after "{node}": the character finished its step and stands '
                f"in that pose from {when}"
            )  # fmt: skip

    def stop_walking(self):
        """The end node (a stop) once, where the last step leads to one; whether it played."""
        if self.node is None or self.types.get(self.node) != "standard" or self.spot is not None:
            return False
        ends = [n for n in self.successors[self.node] if self.types[n] == "end"]
        if not ends:
            return False
        self.step(ends[0], toward=None)
        self.node = ends[0]
        self.notes.append(f'the end node "{ends[0]}" played after the last goal')
        return True

    def standing_source(self):
        """The idle node (the first of the graph's), else the graph's captured standing frames
        (standing.CapturedStanding), else None."""
        idles = [n for n, t in self.types.items() if t == "idle"]
        if idles:
            return idles[0]
        if self.captured is None and self.graph.get("standing"):
            try:
                self.captured = standing.CapturedStanding(self.graph["standing"], self.rig)
            except standing.StandingError as e:
                raise SynthesisError(str(e)) from None
        return self.captured

    def standing_words(self):
        source = self.standing_source()
        return (f'the idle node "{source}"' if isinstance(source, str)
                else "the graph's captured standing frames")  # fmt: skip

    def standing_piece(self):
        """(rotations, translations) of the next piece of standing, as the source gives them."""
        source = self.standing_source()
        self.interrupts()
        if isinstance(source, str):
            model = self.models[source].model
            split = len(model["spatial"]["components"])
            scores = self.models[source].calm_draw(self.rng, IDLE_SPREAD)
            frames = motion_model.frames_from_scores(model, scores[:split], scores[split:])
            return frames[0], frames[1]
        return source.piece(self.rng)

    def rest(self, face=None):
        """One more piece of standing: the first comes to rest from the walk (the settle), every
        piece stands on the spot the settle chose (an avatar calls this while it has no goal);
        face: a heading the settle turns to (within standing.MAX_SETTLE_TURN of the walk's)."""
        rig, body = self.rig, self.body
        rotations, translations = self.standing_piece()
        if not body.rotations:  # standing from the first frame: above the origin, facing +Z
            self.spot = standing.Spot(np.zeros(2), 0.0)
            self.spot.pelvis = np.zeros(2)
            self.spot.lift = standing.floor_lift(rig, rotations, translations, self.floors)
        if self.spot is None:
            # from the frames as played (the feet held): the settle shows its own feet
            r, t = body.last_two(shown=True)
            rotations, translations = standing.at_least(
                rotations, translations, int(round(standing.SETTLE_S * self.fps)) + 2)
            heading = standing.travel_heading(rig, body.rotations[-1], body.translations[-1],
                                              body.heading)  # fmt: skip
            if face is not None:
                turn = float(wrap(face - heading))
                heading += float(np.clip(turn, -standing.MAX_SETTLE_TURN, standing.MAX_SETTLE_TURN))
            planted = self.leading_foot(heading)
            self.spot = standing.settle_spot(rig, rotations, translations, planted,
                                             body.feet[planted], heading)  # fmt: skip
            self.spot.lift = standing.floor_lift(rig, rotations, translations, self.floors)
            piece = standing.on_spot(rig, rotations, translations, self.spot)
            self.spot.pelvis = rig.positions(piece[0][:1], piece[1][:1])[0, rig.pelvis][[0, 2]]
            *joined, self.spot.feet = standing.settle(rig, self.legs, self.seams, (r, t), piece,
                                                      planted, self.fps)  # fmt: skip
            self.rested_from = body.n_frames + min(len(piece[0]) - 1,
                                                   int(round(standing.SETTLE_S * self.fps)))
            reference = None  # the settle's own feet: the trailing one moves, then lands
        else:
            piece = standing.on_spot(rig, rotations, translations, self.spot, isinstance(
                self.standing_source(), standing.CapturedStanding))  # fmt: skip
            joined = piece
            if body.rotations:
                joined = self.seams.inertialize(*body.last_two(), *piece, self.fps)
            if self.spot.feet is None:  # standing from the start: the feet where the first has them
                self.spot.feet = standing.feet_at(rig, *piece)
            joined = (standing.pinned(self.legs, joined[0], joined[1], self.spot.feet), joined[1])
            reference = piece
        start = 1 if body.rotations else 0  # the first frame stands in for the last one played
        first = body.n_frames
        self.append(joined[0][start:], joined[1][start:],
                    None if reference is None else (reference[0][start:], reference[1][start:]),
                    hold=False)  # fmt: skip
        if self.rested_from is None:
            self.rested_from = first
        source = self.standing_source()
        self.steps.append({"node": source if isinstance(source, str) else "standing",
                           "rest": True, "first_frame": first,
                           "n_frames": body.n_frames - first})  # fmt: skip

    @property
    def legs(self):
        if not hasattr(self, "_legs"):
            try:
                self._legs = standing.Legs(self.rig)
            except standing.StandingError as e:
                raise SynthesisError(str(e)) from None
        return self._legs

    def leading_foot(self, heading):
        """The foot further along heading: the one the walk last put down (the other trails)."""
        forward = np.array([np.sin(heading), np.cos(heading)])
        return max(self.body.feet, key=lambda side: float(self.body.feet[side] @ forward))

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
            "rested_from_frame": self.rested_from,
            "actions": self.actions,
            # the course's entries that are an action's place (1-based, as "reached" counts)
            "places": {str(k + 1): a["primitive"] for k, a in self.planned.items()},
            "notes": self.notes,
        }


GRAPH = Statement(
    "SELECT data::text AS data, skeleton_id FROM modb.graphs WHERE name = $1 AND kind = 'models'",
    ("text",),
)
FOOT_HOLD = Statement("SELECT current_setting('modb.foot_hold', true) AS value")


def foot_hold_on(db):
    """The session's modb.foot_hold (on when never set; a value SET before the library was
    loaded is read as PostgreSQL reads a boolean)."""
    value = (db.run(FOOT_HOLD)[0]["value"] or "on").strip().lower()
    return value not in ("off", "of", "false", "fals", "fal", "fa", "f", "no", "n", "0")


def load(db, graph_name, interrupts=no_interrupts):
    """(graph document, node name -> StepModel, Rig) of the stored graph of models: the graph read,
    its models prepared once per process (prepared_models: read again only when changed)."""
    found = db.run(GRAPH, [graph_name])
    if not found:
        raise StoreError(f'no graph of models "{graph_name}"', sqlstate="P0002",
                         hint="modb model graph list names them; modb model graph NAME "
                         "--collection C builds one")  # fmt: skip
    graph = json.loads(found[0]["data"])
    ids = sorted({int(n["model_id"]) for n in graph["nodes"].values()})
    keys = {r["id"]: r for r in db.run(prepared_models.KEYS, [ids])}
    _refuse_gone(graph_name, ids, keys)
    for name, node in graph["nodes"].items():
        if not keys[int(node["model_id"])]["has_tree"]:
            raise StoreError(f'graph "{graph_name}": the model of node "{name}" has no '
                             "acceleration tree: rebuild it (modb model tree NAME)",
                             sqlstate="22023")  # fmt: skip
    try:
        models = prepared_models.PREPARED.step_models(db, keys, interrupts)
    except ValueError as e:
        raise StoreError(f'graph "{graph_name}": {e}', sqlstate="22023") from None
    _refuse_gone(graph_name, ids, models)  # one deleted since its key was read
    nodes = {}
    for name, node in graph["nodes"].items():
        model = models[int(node["model_id"])]
        if node.get("type") == "action":
            try:
                model = prepared_models.action_model(model)
            except ValueError as e:
                raise StoreError(f'graph "{graph_name}": action "{name}": {e}',
                                 sqlstate="22023") from None  # fmt: skip
        nodes[name] = model
    return graph, nodes, models[ids[0]].rig


def _refuse_gone(graph_name, ids, found):
    missing = [i for i in ids if i not in found]
    if missing:
        raise StoreError(f'graph "{graph_name}" names motion model {missing[0]}, which is gone',
                         hint="build the graph again (modb model graph NAME --collection C)",
                         sqlstate="P0002")  # fmt: skip


def _sound_goals(goals):
    """A non-empty list of [x, z] pairs of finite numbers within MAX_COORDINATE."""
    if not goals or not all(isinstance(g, (list, tuple)) and len(g) == 2 for g in goals):
        return False
    values = [v for g in goals for v in g]
    return all(isinstance(v, (int, float)) and abs(v) <= MAX_COORDINATE for v in values)


def synthesize_stored(db, graph_name, goals, seconds, seed, radius=ARRIVAL_RADIUS_M,
                      actions=None):  # fmt: skip
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
    if actions is not None:
        try:
            actions = json.loads(actions)
        except (TypeError, ValueError):
            raise StoreError("actions must be a JSON list of actions", sqlstate="22023") from None
    if not (_sound_goals(goals) or (actions and goals in (None, []))):
        raise StoreError(f"goals must be a non-empty float8[][2] of world X and Z in metres, each "
                         f"finite and at most {MAX_COORDINATE:g} from the origin, e.g. "
                         "ARRAY[[0, 6], [5, 8]]", sqlstate="22023")  # fmt: skip
    if radius is None or not 0 < radius <= MAX_ARRIVAL_RADIUS_M:
        raise StoreError(f"arrival_radius is {radius}: give metres above 0, at most "
                         f"{MAX_ARRIVAL_RADIUS_M:g}", sqlstate="22023")  # fmt: skip
    graph, models, rig = load(db, graph_name, db.check_interrupts)
    try:
        synthesis = Synthesis(graph, models, rig, goals or [], seconds, seed, radius,
                              db.check_interrupts, foot_hold_on(db), actions).run()  # fmt: skip
    except ValueError as e:
        raise StoreError(f'graph "{graph_name}": {e}', sqlstate="22023") from None
    rotations, translations = synthesis.frames()
    del models, synthesis.models  # the call's hold on the models (prepared_models keeps them)
    result = [(
        synthesis.fps,
        len(rotations),
        rotations.astype(np.float32).tolist(),
        translations.astype(np.float32).tolist() if translations.shape[1] else None,
        json.dumps(synthesis.report()),
    )]  # fmt: skip
    del synthesis, rotations, translations
    memory.release()  # each call's frames go back to the system, not the session
    return result
