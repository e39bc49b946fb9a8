"""Scripted experts for ContinuousWorld Base (the paper's four scripts), and the ground truth each one knows
about its own demos.

An expert moves in *legs*: a horizontal leg to the goal's column, then, if the goal's row is still far, a
vertical leg to it. Each leg is one phase: its first step is a
true segment boundary and its factors (direction, distance, push, map size) are the true factors of that
macro action. Only evaluation metrics may read them.

Along its leg's axis the expert "arrives": it tracks a speed that cruises at CRUISE_SPEED and falls off as
``sqrt(2 * BRAKE * remaining distance)``, then linearly near the target, so it brakes smoothly and stops there.
Across the axis the plain scripts hold zero velocity; the *pushed* scripts instead accelerate at PUSH toward the
goal's row all the while (the paper: "the agent always accelerates upward or downward, according to the goal
position"), so their horizontal legs bend towards the goal's row and end pressed against the edge.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from famarl_cli.envs.continuous_world import DRAG, MAX_ACCEL
from famarl_cli.experts.scripts import Script

CRUISE_SPEED = 1.5
"""Cruising speed along a leg (m/s), below the 2 m/s terminal speed so the controller has authority left."""
BRAKE = 1.0
"""Deceleration the arrival profile plans with (m/s^2), half of MAX_ACCEL, so braking never saturates."""
GAIN = 5.0
"""Speed-tracking gain (1/s): the speed error closes with a time constant of two steps."""
APPROACH_GAIN = 2.0
"""Near the target (within 2 * BRAKE / APPROACH_GAIN^2 = 0.5 m) the desired speed falls linearly with this slope
(1/s) instead of as a square root, whose infinite slope at the target makes the stepped controller chatter."""
PUSH = 0.5
"""The pushed scripts' constant cross-axis action toward the goal's row (in action units)."""
ARRIVE_TOLERANCE = 0.05
"""A leg ends when the agent is this close to the leg's target (m) ..."""
ARRIVE_SPEED = 0.2
"""... and slower than this along the leg's axis (m/s)."""
MIN_VERTICAL_LEG = 1.2
"""A vertical leg is started only if the goal's row is farther than this (m), which leaves at least ~8 steps
before the goal radius is reached; see :func:`vertical_leg`."""

FACTOR_NAMES = ("direction_x", "direction_y", "distance", "push", "map_size")
"""Per-phase ground-truth factors: unit direction of the leg (-1/0/+1 on each axis), its length (m), the
cross-axis push (-1 down, 0 none, +1 up) and the side of the map (m)."""


@dataclass(frozen=True)
class Leg:
    axis: int
    """0 for a horizontal leg, 1 for a vertical one."""
    target: float
    """Coordinate along ``axis`` where the leg ends."""
    push: float
    """Cross-axis action held during the leg; 0 means the expert holds zero cross-axis velocity instead."""
    factors: tuple[float, ...]


def horizontal_leg(script: Script, position: np.ndarray, goal: np.ndarray, map_size: float) -> Leg:
    """The first leg: to the goal's column, pushed toward the goal's row if the script pushes."""
    push = (1.0 if goal[1] > map_size / 2 else -1.0) if script.pushed else 0.0
    dx = float(goal[0] - position[0])
    return Leg(0, float(goal[0]), PUSH * push, (np.sign(dx), 0.0, abs(dx), push, map_size))


def vertical_leg(position: np.ndarray, goal: np.ndarray, map_size: float) -> Leg | None:
    """The second leg, to the goal's row, if more than MIN_VERTICAL_LEG of it remains.

    Deciding this when the first leg ends (not at reset) keeps a pushed leg that has almost reached the goal's
    row going, instead of starting a phase a few steps long that no segmentation window could see.
    """
    dy = float(goal[1] - position[1])
    if abs(dy) <= MIN_VERTICAL_LEG:
        return None
    return Leg(1, float(goal[1]), 0.0, (0.0, np.sign(dy), abs(dy), 0.0, map_size))


def _track_speed(desired: np.ndarray | float, speed: np.ndarray | float) -> np.ndarray:
    """Action that drives ``speed`` to ``desired`` (drag compensated), clipped to the action bounds."""
    return np.clip((GAIN * (desired - speed) + DRAG * speed) / MAX_ACCEL, -1.0, 1.0)


class ContinuousWorldExpert:
    """Acts in ContinuousWorld Base from observations alone and records where its phases begin.

    Call :meth:`reset` with the episode's first observation, then :meth:`act` once per step.
    """

    def __init__(self, script: Script) -> None:
        self.script = Script(script)
        self.legs: list[Leg] = []
        self.phase_starts: list[int] = []
        self.steps = 0

    def reset(self, observation: np.ndarray) -> None:
        position, self._goal, self._map_size = _position(observation), _goal(observation), float(observation[6])
        self.legs = [horizontal_leg(self.script, position, self._goal, self._map_size)]
        self.phase_starts = [0]
        self.steps = 0

    @property
    def phase_factors(self) -> np.ndarray:
        """(phases begun so far, len(FACTOR_NAMES)) factors of each phase, in order."""
        return np.array([leg.factors for leg in self.legs], dtype=np.float64)

    def act(self, observation: np.ndarray) -> np.ndarray:
        position, velocity = _position(observation), observation[2:4].astype(np.float64)
        leg = self.legs[-1]
        remaining = leg.target - position[leg.axis]
        arrived = abs(remaining) < ARRIVE_TOLERANCE and abs(velocity[leg.axis]) < ARRIVE_SPEED
        if arrived and leg.axis == 0 and (second := vertical_leg(position, self._goal, self._map_size)):
            self.legs.append(second)
            self.phase_starts.append(self.steps)
            leg = second
            remaining = leg.target - position[leg.axis]
        self.steps += 1

        distance = abs(remaining)
        desired = np.sign(remaining) * min(CRUISE_SPEED, np.sqrt(2 * BRAKE * distance), APPROACH_GAIN * distance)
        action = np.empty(2, dtype=np.float32)
        action[leg.axis] = _track_speed(desired, velocity[leg.axis])
        cross = 1 - leg.axis
        action[cross] = leg.push if leg.push else _track_speed(0.0, velocity[cross])
        return action


def _position(observation: np.ndarray) -> np.ndarray:
    return observation[0:2].astype(np.float64)


def _goal(observation: np.ndarray) -> np.ndarray:
    return observation[4:6].astype(np.float64)
