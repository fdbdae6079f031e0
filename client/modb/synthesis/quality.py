"""How good a synthesized strip is: seam roughness against natural steps, recombination, goal reach,
relaxation and query latency (docs/synthesis.md "Synthesis quality" defines each figure and its
aim).

Roughness of a frame-to-frame step: r = the largest, over the standard joints, of the joint's
rotation change divided by that joint's 99th percentile of change between consecutive frames of the
source clips (the pelvis measured in the world, every other joint relative to its parent), with one
more term: the change of the pelvis velocity from the previous step over its own 99th percentile.
A seam: from a snippet's last frame to the next's second, whose first stands in for the last.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np

from modb_kernel import kinematics, quaternion
from modb_kernel.joints import STANDARD_JOINTS

from .chain import Choice
from modb.motion import Motion
from .placement import ground_distance

# select_next_snippets' last relaxation level: the nearest start configuration, any ratio
LAST_LEVEL = 4
AIM_SEAM_SHARE_FACTOR = 2.0  # seams with r > 1: at most this times the share of natural steps
AIM_RECOMBINATION = 0.20
AIM_REACH_RATIO = 2.0  # time to a goal >= 5 m away / straight line at the median walking speed
REACH_MIN_DISTANCE = 5.0
AIM_LAST_LEVEL_SHARE = 0.01


def step_changes(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """Per step t (frame t to t+1): rotation change of each standard joint (steps, 19), and the
    change of the pelvis velocity from step t-1 to step t (steps,; 0 for the first step)."""
    sk = motion.skeleton
    columns = [sk.index(sk.joint_map[s]) for s in STANDARD_JOINTS]
    pelvis = sk.index(sk.joint_map["pelvis"])
    positions, orientations = kinematics.world_transforms(
        sk.parents, sk.offsets, motion.rotations, motion.translations, sk.translated
    )
    rotations = motion.rotations[:, columns].copy()
    rotations[:, STANDARD_JOINTS.index("pelvis")] = orientations[:, pelvis]
    angles = quaternion.angle_between(rotations[:-1], rotations[1:])
    velocity = np.diff(positions[:, pelvis], axis=0) * motion.fps
    velocity_change = np.zeros(len(velocity))
    velocity_change[1:] = np.linalg.norm(np.diff(velocity, axis=0), axis=-1)
    return angles, velocity_change


# A foot stands when within this of its lowest (its 2nd percentile) and rising or sinking slower
# than CONTACT_SPEED_M_S: one lifting off or landing is not standing. Contact takes no limit on the
# horizontal speed, which is what the figure measures: with one (1 or 2 m/s), less sliding moves
# frames under the limit and raises the mean (foot locking measured worse on Bandai both times). A
# toe skimming the floor mid-swing can count; it does for the sources too.
CONTACT_HEIGHT_M = 0.02
CONTACT_SPEED_M_S = 0.15
FEET = ("left_ankle", "left_toe", "right_ankle", "right_toe")


def pose_jumps(motion: Motion) -> np.ndarray:
    """Per step: the largest move of any joint relative to the pelvis's ground point (metres), so
    the travel is left out and a seam's jump in pose is what shows."""
    sk = motion.skeleton
    pelvis = sk.index(sk.joint_map["pelvis"])
    above = sk.above_pelvis()  # frames of reference, not the body
    body = [k for k in range(len(sk.joints)) if k not in above]
    positions = motion.world_positions()
    ground = positions[:, pelvis] * np.array([1.0, 0.0, 1.0])
    pose = positions[:, body] - ground[:, None, :]
    return np.linalg.norm(np.diff(pose, axis=0), axis=-1).max(axis=1)


def near_lowest(height: np.ndarray) -> np.ndarray:
    """Per frame (and joint, along the last axis): within CONTACT_HEIGHT_M of the joint's lowest
    (its 2nd percentile over the frames)."""
    return height <= np.percentile(height, 2, axis=0) + CONTACT_HEIGHT_M


def foot_skating(motion: Motion) -> tuple[float, int]:
    """The mean horizontal speed (m/s) of the ankles and toes while they stand (within
    CONTACT_HEIGHT_M of their lowest, rising or sinking slower than CONTACT_SPEED_M_S), and in how
    many frames they stood."""
    sk = motion.skeleton
    positions = motion.world_positions()[:, [sk.index(sk.joint_map[f]) for f in FEET]]
    if len(positions) < 3:
        return 0.0, 0
    height = positions[..., 1]
    low = near_lowest(height)
    ground = positions[..., [0, 2]]
    speed = np.linalg.norm(ground[2:] - ground[:-2], axis=-1) * motion.fps / 2  # central
    rising = np.abs(height[2:] - height[:-2]) * motion.fps / 2
    standing = low[1:-1] & (rising < CONTACT_SPEED_M_S)
    return (float(speed[standing].mean()) if standing.any() else 0.0), int(standing.sum())


@dataclass(frozen=True)
class NaturalSteps:
    """The scale of roughness, from every frame-to-frame step of the source clips."""

    joint_p99: np.ndarray  # (19,) radians per step
    velocity_change_p99: float  # m/s, change of the pelvis velocity from one step to the next
    share_over_one: float  # natural steps with r > 1
    r_p999: float
    steps: int
    pose_jump_p999: float = 0.0  # metres per step (pose_jumps)
    foot_skating: float = 0.0  # m/s (foot_skating, over every standing frame of the sources)

    @classmethod
    def of(cls, motions: Sequence[Motion]) -> NaturalSteps:
        changes = [step_changes(m) for m in motions if m.n_frames > 2]
        if not changes:
            raise ValueError(
                "no source clip of three frames or more to measure natural steps against"
            )
        angles = np.concatenate([a for a, _ in changes])
        # A clip's first step has no predecessor.
        velocity = np.concatenate([v[1:] for _, v in changes])
        joint_p99 = np.maximum(np.percentile(angles, 99, axis=0), 1e-9)
        velocity_p99 = max(float(np.percentile(velocity, 99)), 1e-9)
        r = np.concatenate([roughness(a[1:], v[1:], joint_p99, velocity_p99) for a, v in changes])
        used = [m for m in motions if m.n_frames > 2]
        jumps = np.concatenate([pose_jumps(m) for m in used])
        skating = [foot_skating(m) for m in used]
        standing = sum(n for _, n in skating)
        return cls(
            joint_p99,
            velocity_p99,
            float(np.mean(r > 1.0)),
            float(np.percentile(r, 99.9)),
            len(r),
            float(np.percentile(jumps, 99.9)),
            sum(v * n for v, n in skating) / standing if standing else 0.0,
        )


def roughness(
    angles: np.ndarray, velocity_change: np.ndarray, joint_p99: np.ndarray, velocity_p99: float
) -> np.ndarray:
    return np.maximum(np.max(angles / joint_p99, axis=-1), velocity_change / velocity_p99)


def seam_steps(chain: Sequence[Choice]) -> list[int]:
    """Strip step index of each seam: a snippet's last frame to the next's first played frame."""
    return [c.end_frame for c in chain[:-1]]


def recombined(chain: Sequence[Choice], window_seconds: float = 2.0) -> list[bool]:
    """Per seam: does it go to another clip, or jump within the same clip without replaying?

    A jump within the clip skips at least one snippet and replays no frame played in the last
    window_seconds; playing on from where the previous snippet ended is not recombination. A clip's
    mirror image is the same clip here: its frames are the same capture.
    """
    out = []
    for k in range(1, len(chain)):
        a, b = chain[k - 1], chain[k]
        if (a.clip_id, a.version) != (b.clip_id, b.version):
            out.append(True)
            continue
        jump = abs(b.first_frame - (a.first_frame + a.n_frames - 1))
        recent = [
            c
            for c in chain[:k]
            if (c.clip_id, c.version) == (b.clip_id, b.version)
            and (a.end_frame - c.end_frame) < window_seconds * a.fps
        ]
        overlaps = any(
            c.first_frame + 1 <= b.first_frame + b.n_frames - 1
            and b.first_frame + 1 <= c.first_frame + c.n_frames - 1
            for c in recent
        )
        out.append(jump >= a.n_frames - 1 and not overlaps)
    return out


@dataclass(frozen=True)
class GoalReach:
    goal: int
    target: tuple[float, ...]
    distance_m: float  # from where the avatar stood when the goal became current
    behind: bool  # more than 90 degrees from the avatar's heading then
    reached: bool
    seconds: float | None
    straight_seconds: float  # the straight line at the median walking speed
    ratio: float | None
    # how long it was the current goal (to the strip's end when not reached)
    current_seconds: float = 0.0
    became_current: bool = True

    @property
    def pending(self) -> bool:
        """Current when the strip ended, not reached, and not yet for its 2x straight line: the
        strip's end cut it short, so it is neither reached nor missed."""
        return (
            self.became_current
            and not self.reached
            and self.current_seconds < AIM_REACH_RATIO * self.straight_seconds
        )

    @property
    def counts_for_aim(self) -> bool:
        """Whether the reach aim's time limit covers this goal: at least 5 m away and not behind.

        The time to other goals is only reported. A goal still unreached when the strip ended
        counts only once it has had its 2x straight line.
        """
        return self.distance_m >= REACH_MIN_DISTANCE and not self.behind and not self.pending


REACHED, MISSED, NOT_JUDGED = "reached", "missed", "not judged"
REACH_AIM = "goals >= 5 m reached within 2x straight line"


def goal_outcomes(goals: Sequence[GoalReach]) -> list[str]:
    """Each goal of the course against the reach aim: REACHED (within 2x where the limit covers
    it), MISSED, or NOT_JUDGED.

    A goal not reached is missed, unless it was still pending when the strip ended. A goal that
    never became current is missed when the one before it was (the course stalled there), and not
    judged when the strip simply ended first.
    """
    out: list[str] = []
    for g in goals:
        if not g.became_current:
            out.append(MISSED if out and out[-1] == MISSED else NOT_JUDGED)
        elif g.pending:
            out.append(NOT_JUDGED)
        elif not g.reached or (g.counts_for_aim and g.ratio > AIM_REACH_RATIO):
            out.append(MISSED)
        else:
            out.append(REACHED)
    return out


def goal_reach(
    chain: Sequence[Choice], goals: Sequence[tuple[float, ...]], walking_speed: float
) -> list[GoalReach]:
    """Every goal of the course.

    One that never became current is reported as not reached, measured from where the strip ended.
    """
    out = []
    for goal, target in enumerate(goals, start=1):
        served = [c for c in chain if c.goal == goal]
        if not served:
            end = chain[-1].end
            distance = ground_distance(end.position, target)
            out.append(
                GoalReach(
                    goal,
                    tuple(target),
                    distance,
                    False,
                    False,
                    None,
                    distance / walking_speed,
                    None,
                    became_current=False,
                )
            )
            continue
        first = served[0]
        done = next((c for c in served if c.reached), None)
        distance = ground_distance(first.placement.position, first.target)
        dx, dz = (
            first.target[0] - first.placement.position[0],
            first.target[-1] - first.placement.position[2],
        )
        facing = (math.sin(first.placement.heading), math.cos(first.placement.heading))
        behind = dx * facing[0] + dz * facing[1] < 0
        seconds = None if done is None else (done.end_frame - first.start_frame) / first.fps
        current = (served[-1].end_frame - first.start_frame) / first.fps
        straight = distance / walking_speed
        out.append(
            GoalReach(
                goal,
                first.target,
                distance,
                behind,
                done is not None,
                seconds,
                straight,
                None if seconds is None or straight == 0 else seconds / straight,
                current,
            )
        )
    return out


@dataclass
class Report:
    seconds: float
    snippets: int
    natural_steps: int
    natural_share_over_one: float
    natural_r_p999: float
    seams: int
    seam_share_over_one: float
    seam_r_p99: float
    recombination: float
    levels: dict[int, int]
    last_level_share: float
    latency_ms_p50: float | None
    latency_ms_p99: float | None
    walking_speed: float
    goals: list[GoalReach]
    pose_jump_max: float = 0.0  # metres per step, the strip's largest (pose_jumps)
    natural_pose_jump_p999: float = 0.0
    foot_skating: float = 0.0  # m/s while standing (foot_skating)
    natural_foot_skating: float = 0.0
    # the walk's slowest selection query, and its first and last (every choice that ran one)
    latency_ms_max: float | None = None
    latency_ms_first: float | None = None
    latency_ms_last: float | None = None

    @property
    def aims(self) -> dict[str, bool | None]:
        """Which aims are met. Reach: every goal judged was reached, those the time limit covers
        within 2x (goal_outcomes); None when no goal could be judged (nothing to measure)."""
        outcomes = goal_outcomes(self.goals)
        judged = [o for o in outcomes if o != NOT_JUDGED]
        return {
            "seam share r>1 <= 2x natural": self.seam_share_over_one
            <= AIM_SEAM_SHARE_FACTOR * self.natural_share_over_one,
            "seam r p99 <= natural r p99.9": self.seam_r_p99 <= self.natural_r_p999,
            "recombination >= 20%": self.recombination >= AIM_RECOMBINATION,
            REACH_AIM: all(o == REACHED for o in judged) if judged else None,
            "last relaxation level < 1%": self.last_level_share < AIM_LAST_LEVEL_SHARE,
        }

    def as_json(self) -> dict:
        out = asdict(self)
        out["aims"] = self.aims
        out["goal_outcomes"] = goal_outcomes(self.goals)
        return out


def measure(
    strip: Motion,
    chain: Sequence[Choice],
    goals: Sequence[tuple[float, ...]],
    natural: NaturalSteps,
    walking_speed: float,
) -> Report:
    angles, velocity_change = step_changes(strip)
    r = roughness(angles, velocity_change, natural.joint_p99, natural.velocity_change_p99)
    at = np.array(seam_steps(chain), dtype=int)
    after = np.minimum(at + 1, len(r) - 1)
    seams = (
        np.maximum(r[at], velocity_change[after] / natural.velocity_change_p99)
        if len(at)
        else np.zeros(0)
    )
    levels: dict[int, int] = {}
    for c in chain:
        if c.relax_level is not None:
            levels[c.relax_level] = levels.get(c.relax_level, 0) + 1
    latencies = [c.latency_ms for c in chain if c.latency_ms is not None]
    mixes = recombined(chain)
    return Report(
        seconds=(strip.n_frames - 1) / strip.fps,
        snippets=len(chain),
        natural_steps=natural.steps,
        natural_share_over_one=natural.share_over_one,
        natural_r_p999=natural.r_p999,
        seams=len(seams),
        seam_share_over_one=float(np.mean(seams > 1.0)) if len(seams) else 0.0,
        seam_r_p99=float(np.percentile(seams, 99)) if len(seams) else 0.0,
        recombination=float(np.mean(mixes)) if mixes else 0.0,
        levels=dict(sorted(levels.items())),
        last_level_share=levels.get(LAST_LEVEL, 0) / max(sum(levels.values()), 1),
        latency_ms_p50=float(np.median(latencies)) if latencies else None,
        latency_ms_p99=float(np.percentile(latencies, 99)) if latencies else None,
        walking_speed=walking_speed,
        goals=goal_reach(chain, goals, walking_speed),
        pose_jump_max=float(pose_jumps(strip).max()) if strip.n_frames > 1 else 0.0,
        natural_pose_jump_p999=natural.pose_jump_p999,
        foot_skating=foot_skating(strip)[0],
        natural_foot_skating=natural.foot_skating,
        **selection_extremes(latencies),
    )


def selection_extremes(latencies: Sequence[float]) -> dict[str, float | None]:
    """Report's latency_ms_max, _first and _last over a walk's selection times (ms, in order,
    the first selection's included: its session's first call)."""
    if not latencies:
        return dict.fromkeys(("latency_ms_max", "latency_ms_first", "latency_ms_last"))
    return {
        "latency_ms_max": float(max(latencies)),
        "latency_ms_first": float(latencies[0]),
        "latency_ms_last": float(latencies[-1]),
    }
