"""The scripted pegging expert for RobotHand Base: carry the rod from the blue basket to the red one.

Seven phases, each a straight move of the grip point or a grasp held in place:

1. approach: to HOVER_CLEARANCE above the rod's grasp height, right above the rod, fingers opening (in BaseVaried,
   where a raised basket may stand in the way, first **rise** to SAFE_CLEARANCE above the highest basket and, if
   still blocked, go **across** at that height: eight or nine phases);
2. descend: down to GRASP_ABOVE_CENTRE above the rod's centre (held above its centre of mass, the rod hangs
   upright: gravity turns it back when the carry swings it);
3. grasp: close the fingers, hand still;
4. lift: up to CARRY_HEIGHT, squeezing;
5. carry: straight to CARRY_HEIGHT above the red basket's floor, squeezing (level in Base; a slope up or down in
   BaseVaried);
6. place: down until the rod stands on the red basket's floor, squeezing;
7. release: open the fingers, hand still; the episode succeeds once the rod stands free in the red basket.

Moves "arrive" like the ContinuousWorld expert's legs: the commanded speed cruises at CRUISE and falls off
linearly within CRUISE / APPROACH_GAIN of the target. The hand's angle is held at 0 (the rod stands upright).
Each phase's factors are its displacement of the grip point and the grasp command it holds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from famarl_cli.envs.robot_hand import BASKET_WALL, ROD_SIZE, TURN_SPEED, column_tops, hand_hits

CRUISE = 0.8
"""Cruising speed as a fraction of HAND_SPEED (1.6 m/s)."""
APPROACH_GAIN = 4.0
"""Commanded speed (in action units) per metre still to go, near the target."""
ARRIVE_TOLERANCE = 0.02
"""A move ends within this distance of its target (m) ..."""
ARRIVE_SPEED = 0.1
"""... once the hand moves slower than this (m/s)."""
HOVER_CLEARANCE = 0.8
"""How far above the grasp height the approach ends (m): the open fingertips pass 0.3 m over the rod's top."""
CARRY_HEIGHT = 2.1
"""Height of the grip point above a basket's floor while carrying (m): the rod's bottom clears the rims by about a
metre."""
SAFE_CLEARANCE = 0.6
"""BaseVaried: how far above the highest basket column the grip point passes when the straight way to the rod is
blocked (m)."""
PATH_STEP = 0.05
"""Spacing (m) of the points at which a straight move is checked clear of the baskets."""
PLACE_CLEARANCE = 0.02
"""The rod is put down this far above the red basket's floor (m); gravity does the rest once it is let go."""
GRASP_STEPS = 6
"""Steps the fingers close (three reach the rod, three build up the squeeze)."""
RELEASE_STEPS = 6
ANGLE_GAIN = 5.0
"""Rotation command per radian of hand tilt (1/s, in action units times TURN_SPEED)."""

FACTOR_NAMES = ("dx", "dy", "grasp")
"""Per-phase ground-truth factors: the grip point's displacement over the phase (m) and the grasp command it holds
(-1 opening, +1 closing or squeezing)."""

GRASP_ABOVE_CENTRE = 0.3
"""How far above the rod's centre the fingers take hold of it (m)."""
GRASP_HEIGHT = BASKET_WALL + ROD_SIZE[1] / 2 + GRASP_ABOVE_CENTRE
"""Height of the grip point when it grasps a rod standing on a basket's floor (m)."""

VARIED_RANGES = {
    "hover_clearance": (0.4, 1.2),
    "grasp_above_centre": (0.1, 0.4),
    "carry_height": (1.7, 2.6),
    "align": (0.1, 0.3),
}
"""The pegging demos whose phases vary (docs/robothand.md's calibration protocol): per episode, the hover clearance,
the grasp height above the rod's centre, the carry height and the length of a level alignment leg before the
descent (either way), each drawn uniformly from its range; the same pegging task, so that a FAVAE sees "descend by
h" vary rather than one constant move."""


@dataclass(frozen=True)
class Shape:
    """The lengths that make one pegging plan: today's expert always draws the defaults."""

    hover_clearance: float = HOVER_CLEARANCE
    grasp_above_centre: float = GRASP_ABOVE_CENTRE
    carry_height: float = CARRY_HEIGHT
    align: float = 0.0
    """The approach ends this far beside the rod (m, signed) and a level move brings the hand over it."""

    @property
    def grasp_height(self) -> float:
        """Height of the grip point when it grasps a rod standing on a basket's floor (m); GRASP_HEIGHT by default."""
        return GRASP_HEIGHT - GRASP_ABOVE_CENTRE + self.grasp_above_centre

    @staticmethod
    def drawn(rng: np.random.Generator) -> Shape:
        """One episode's shape from :data:`VARIED_RANGES`."""
        low, high = zip(*VARIED_RANGES.values(), strict=True)
        hover, grasp, carry, align = rng.uniform(low, high)
        return Shape(float(hover), float(grasp), float(carry), float(align * rng.choice((-1.0, 1.0))))


@dataclass(frozen=True)
class Phase:
    name: str
    target: tuple[float, float] | None
    """Where the grip point goes (m); None for a phase that holds the hand still."""
    grasp: float
    steps: int = 0
    """How long a phase with no target lasts."""


def phases(
    grip: np.ndarray, rod_x: float, source: np.ndarray, target: np.ndarray, shape: Shape = Shape()
) -> list[Phase]:
    """The plan from the grip point's start, the rod's x and the blue (``source``) and red (``target``) baskets'
    (x, floor height), with the lengths of ``shape``."""
    rod_floor, basket_x, basket_floor = float(source[1]), float(target[0]), float(target[1])
    hover_y = rod_floor + shape.grasp_height + shape.hover_clearance
    hover = (rod_x + shape.align, hover_y)
    way = route(grip, hover, column_tops(source, target))
    names = ("rise", "across", "approach")[-len(way) :]
    align = [Phase("align", (rod_x, hover_y), -1.0)] if shape.align else []
    return [
        *(Phase(name, point, -1.0) for name, point in zip(names, way, strict=True)),
        *align,
        Phase("descend", (rod_x, rod_floor + shape.grasp_height), -1.0),
        Phase("grasp", None, 1.0, GRASP_STEPS),
        Phase("lift", (rod_x, rod_floor + shape.carry_height), 1.0),
        Phase("carry", (basket_x, basket_floor + shape.carry_height), 1.0),
        Phase("place", (basket_x, basket_floor + shape.grasp_height + PLACE_CLEARANCE), 1.0),
        Phase("release", None, -1.0, RELEASE_STEPS),
    ]


def route(start: np.ndarray, end: tuple[float, float], columns: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Waypoints from ``start`` to ``end`` along which the open hand stays clear of the basket ``columns``:
    straight there if it can; else first to SAFE_CLEARANCE above the highest column, then across at that height if
    still needed. The last way always is clear: the start is (the env draws it so), and the rest runs above every
    column."""
    safe_y = max(top for _, top in columns) + SAFE_CLEARANCE
    rise, across = (float(start[0]), safe_y), (end[0], safe_y)
    for way in ([end], [rise, end]):
        if all(_clear(a, b, columns) for a, b in zip([tuple(start), *way[:-1]], way, strict=True)):
            return way
    return [rise, across, end]


def _clear(a: tuple[float, float], b: tuple[float, float], columns: list[tuple[float, float]]) -> bool:
    points = max(2, int(np.ceil(np.hypot(b[0] - a[0], b[1] - a[1]) / PATH_STEP)) + 1)
    return not any(hand_hits(p, columns) for p in np.linspace(a, b, points))


class PhasedHand:
    """A RobotHand controller that follows a plan of :class:`Phase` moves, drawn up from the first observation by
    :meth:`plan_for`; call :meth:`reset` then :meth:`act` once per step."""

    def __init__(self) -> None:
        self.plan: list[Phase] = []
        self.phase_starts: list[int] = []
        self._factors: list[tuple[float, float, float]] = []
        self._phase_start_grip = np.zeros(2)
        self.steps = 0

    def plan_for(self, observation: np.ndarray) -> list[Phase]:
        raise NotImplementedError

    def reset(self, observation: np.ndarray) -> None:
        self.plan = self.plan_for(observation)
        self.phase_starts, self._factors, self.steps = [], [], 0
        self._begin(0, observation)

    @property
    def phase(self) -> int:
        return len(self.phase_starts) - 1

    @property
    def phase_factors(self) -> np.ndarray:
        """(phases begun so far, 3) factors; the phase in progress counts its planned displacement."""
        return np.array(self._factors, dtype=np.float64)

    def _begin(self, index: int, observation: np.ndarray) -> None:
        phase = self.plan[index]
        grip = observation[0:2].astype(np.float64)
        displacement = np.subtract(phase.target, grip) if phase.target is not None else np.zeros(2)
        self.phase_starts.append(self.steps)
        self._factors.append((float(displacement[0]), float(displacement[1]), phase.grasp))
        self._phase_start_grip = grip

    def _finished(self, phase: Phase, observation: np.ndarray) -> bool:
        if phase.target is None:
            return self.steps - self.phase_starts[-1] >= phase.steps
        remaining = np.subtract(phase.target, observation[0:2])
        return bool(np.hypot(*remaining) < ARRIVE_TOLERANCE and np.hypot(*observation[2:4]) < ARRIVE_SPEED)

    def act(self, observation: np.ndarray) -> np.ndarray:
        if self._finished(self.plan[self.phase], observation) and self.phase + 1 < len(self.plan):
            self._begin(self.phase + 1, observation)
        phase = self.plan[self.phase]
        self.steps += 1
        action = np.zeros(4, dtype=np.float32)
        target = phase.target if phase.target is not None else self._phase_start_grip
        remaining = np.subtract(target, observation[0:2].astype(np.float64))
        distance = float(np.hypot(*remaining))
        if distance > 1e-9:
            action[0:2] = remaining / distance * min(CRUISE, APPROACH_GAIN * distance)
        tilt = float(np.arctan2(observation[4], observation[5]))
        action[2] = np.clip(-ANGLE_GAIN * tilt / TURN_SPEED, -1.0, 1.0)
        action[3] = phase.grasp
        return action


class PeggingExpert(PhasedHand):
    """Acts in RobotHand Base and BaseVaried: the phases above, from the grip's start, the rod's place and the
    baskets'. With ``varied``, each episode's plan has its own :class:`Shape` (:data:`VARIED_RANGES`), drawn from a
    generator seeded by the episode's first observation, so that the same episode gets the same plan."""

    def __init__(self, varied: bool = False) -> None:
        super().__init__()
        self.varied = varied

    def plan_for(self, observation: np.ndarray) -> list[Phase]:
        obs = observation.astype(np.float64)
        shape = Shape()
        if self.varied:
            shape = Shape.drawn(np.random.default_rng(np.frombuffer(obs.tobytes(), dtype=np.uint32)))
        return phases(obs[0:2], rod_x=float(obs[8]), source=obs[16:18], target=obs[14:16], shape=shape)
