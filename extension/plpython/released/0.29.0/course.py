"""The planner's geometry: how far the character still has to walk to a goal when it cannot turn
more sharply than a radius, and which turn of the next step shortens that most.

The remaining length is that of the shortest path of bounded curvature to a point (Dubins): an
arc of the radius then a straight line, or an arc one way then the other. A goal inside the circle
the character would turn on is reached by first turning the other way, which widens; so a step
chosen to shorten this length never orbits a goal beside it.

Ground vectors are (x, z); a heading is radians about +Y, 0 facing +Z (forward: (sin h, cos h))."""

import numpy as np

from .step_search import rotate_y

TURNS_TRIED = 9  # evenly spread over what a step can turn
ARCS_TRIED = 91  # first turns of a turn-then-turn path, every 2 degrees up to a half circle


def turn_then_straight(positions, courses, goal, radius):
    """Per row of positions (n, 2) and courses (n,): the length of the shortest path of an arc
    of the radius (turning either way) and then a straight line to goal."""
    # in each course's frame: +Z ahead, +X to the left (rotate_y's convention)
    local = rotate_y(np.asarray(goal, dtype=np.float64) - positions, -np.asarray(courses))
    x, z = local[..., 0], local[..., 1]
    best = np.full(x.shape, np.inf)
    for side in (1.0, -1.0):  # the centre to the left (+X), then to the right
        cx = side * radius
        d = np.hypot(x - cx, z)
        # the start and the tangent point as angles about the centre in the (x, z) plane;
        # turning left moves clockwise there, turning right anticlockwise
        start = np.arctan2(0.0, -cx)
        spin = -side
        tangent = np.arctan2(z, x - cx) - spin * np.arccos(np.minimum(1.0, radius / d))
        arc = (spin * (tangent - start)) % (2 * np.pi)
        length = radius * arc + np.sqrt(np.maximum(d * d - radius * radius, 0.0))
        best = np.minimum(best, np.where(d < radius, np.inf, length))  # inside: the other way
    return best


def remaining(position, course, goal, radius, arrival=0.0):
    """The length of the shortest path from position, travelling along course, to within
    arrival of goal with turns no sharper than the radius: a turn then a straight line, or a
    turn one way and then the other (how a goal inside the turning circle is reached: the first
    turn widens)."""
    alpha = np.linspace(0.0, np.pi, ARCS_TRIED)
    positions, courses, lengths = [np.asarray(position, dtype=np.float64)[None]], [course], [0.0]
    for side in (1.0, -1.0):
        # after turning by alpha: the arc's chord, at half the turn (see after_step)
        chord = 2 * radius * np.sin(alpha / 2)
        step = np.stack([np.zeros_like(chord), chord], axis=-1)
        positions.append(position + rotate_y(rotate_y(step, side * alpha / 2), course))
        courses += list(course + side * alpha)
        lengths += list(radius * alpha)
    positions, lengths = np.concatenate(positions), np.asarray(lengths)
    total = lengths + turn_then_straight(positions, np.asarray(courses), goal, radius) - arrival
    near = np.linalg.norm(positions - goal, axis=-1) <= arrival  # an arc passing the goal
    return float(max(0.0, min(total.min(), lengths[near].min(initial=np.inf))))


def passes(start, end, goal, arrival):
    """Whether the segment from start to end comes within arrival of goal."""
    along = end - start
    t = np.clip(np.dot(goal - start, along) / max(float(np.dot(along, along)), 1e-12), 0.0, 1.0)
    return float(np.linalg.norm(start + t * along - goal)) <= arrival


def after_step(position, course, travel, turn):
    """(position, course) after a step that travels `travel` (x, z, in the frame of the course
    at its start) and turns the course by `turn`."""
    return position + rotate_y(np.asarray(travel, dtype=np.float64), course), course + turn


def left_after(position, course, goal, travel, turn, radius, arrival=0.0):
    """The remaining length after a step of travel and turn (0 where the step passes the goal)."""
    where, heading = after_step(position, course, travel, turn)
    if passes(position, where, goal, arrival):
        return 0.0
    return remaining(where, heading, goal, radius, arrival)


def best_turn(position, course, goal, travel, low, high, radius, arrival=0.0):
    """The turn from low to high (radians) for the next step, of TURNS_TRIED evenly spread, that
    leaves the least remaining length; a step's travel bends by half its turn."""
    best, chosen = np.inf, 0.0
    for turn in np.linspace(low, high, TURNS_TRIED):
        moved = rotate_y(np.asarray(travel, dtype=np.float64), turn / 2)
        left = left_after(position, course, goal, moved, turn, radius, arrival)
        if left < best - 1e-9 or (abs(left - best) <= 1e-9 and abs(turn) < abs(chosen)):
            best, chosen = left, float(turn)
    return chosen
