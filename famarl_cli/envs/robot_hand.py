"""RobotHand: a two-fingered hand in a 2-D physics world (pymunk), seen from the side with gravity.

The paper built RobotHand with Box2D; this is our own pymunk version. Every constant lives here and is
explained in ``docs/environments.md``. Coordinates are metres, ``x`` to the right and ``y`` up; the world is the
box ``[0, WIDTH] x [0, HEIGHT]`` with the floor at ``y = 0``.

The hand has four degrees of freedom, all velocity-controlled: a kinematic *control body* moves with the
commanded velocity and drags the dynamic palm along through a pivot joint and a gear joint with force limits,
so the palm is stopped by anything solid (it cannot pass through a basket wall) while staying responsive.
Two fingers hang from the palm's ends on pivot joints; a motor turns them inward or outward (the grasp action)
within a rotary limit. Objects are held only by the fingers' contact forces and friction: nothing teleports
or welds an object to the hand.

Tasks:

- **Base** (pegging): carry a rod from a blue basket to a red basket; success when the rod stands in the red
  basket and the fingers have let go. The scripted expert (:mod:`famarl_cli.experts.pegging`) acts here.
  **BaseVaried** is Base with each basket raised on a post to a height drawn per episode, so the expert's moves
  go up and down and across at every slope (pegging demos that hold what the target tasks ask for).
- **Reaching**: bring the grip point within GOAL_RADIUS of a random goal; +100 there, -1 every other step
  (``time_penalty=False`` removes the -1).
- **BallPlacing**: carry a ball from a cup (at a random place) to a fixed goal; reward ``-|b - g|`` each step,
  +200 on arrival within GOAL_RADIUS. The episode also ends, unsuccessfully, when the ball touches an edge of
  the world (floor, side walls or ceiling). **BallPlacingNoEscape** charges that end for the steps left of the time
  limit, so that knocking the ball off never pays (``TaskSpec.drop_costs_rest``). ``hand_near`` starts the hand
  near the ball instead of anywhere in the upper world.

Steps report ``info["success"]``: in BallPlacing an episode can terminate without success.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import copysign, cos, hypot, isfinite, sin

import gymnasium as gym
import numpy as np
import pymunk
from pymunk._chipmunk_cffi import lib as chipmunk

from famarl_cli.envs.render import Canvas

WIDTH, HEIGHT = 10.0, 6.0
"""Size of the world (m)."""
DT = 0.05
"""Seconds per environment step."""
SUBSTEPS = 4
"""Physics steps per environment step; contacts of a tight grasp stay stable at DT / SUBSTEPS = 12.5 ms."""
SOLVER_ITERATIONS = 20
COLLISION_SLOP = 0.005
EDGE_THICKNESS = 0.5
"""Half-thickness of the walls around the world (m): thick enough that nothing is pushed through them."""
"""Overlap (m) pymunk allows between touching shapes; its default, 0.1, is for worlds measured in pixels."""
GRAVITY = 9.81

HAND_SPEED = 2.0
"""Palm speed (m/s) at |action| = 1 on the x or y axis: 0.1 m per step."""
TURN_SPEED = 2.0
"""Palm angular speed (rad/s) at |action| = 1 on the rotation axis."""
FINGER_SPEED = 4.0
"""Finger angular speed (rad/s) at grasp action 1: fully open to fully closed in about 3 steps."""
HAND_FORCE = 3000.0
"""Force (N) with which the control body drags the palm; it bounds how hard the hand pushes on things."""
HAND_TORQUE = 3000.0
GRIP_TORQUE = 30.0
"""Finger motor torque (N m): about 60 N of squeeze at the fingertips, enough for friction to hold the rod."""
LEASH = 0.3
"""The control body is kept within this distance (m) of the palm, so a blocked hand does not wind up an
ever larger pull that would fling it when freed."""

PALM_SIZE = (0.7, 0.15)
FINGER_SIZE = (0.08, 0.5)
FINGER_X = 0.3
"""Horizontal offset of each finger's pivot from the palm's centre (m)."""
ROD_CONTACT_ANGLE = 0.3
"""Inward finger angle (rad) at which the pads meet a rod's faces."""
FINGER_OPEN, FINGER_CLOSED = -0.1, 0.65
"""Limits of each finger's inward angle relative to the palm (rad): slightly splayed to crossed tips."""
PAD_HEIGHT = 0.12
"""Length of the flat pad at each fingertip (m). The pad's inner face is vertical when the fingers close on the
rod, so the rod is held along two faces and cannot turn in the grip; bare rotating fingers would touch it at
one corner each, a pivot about which it tilts."""
GRIP_DEPTH = PALM_SIZE[1] / 2 + FINGER_SIZE[1]
"""Distance from the palm's centre to the grip point, between the fingertips of an open hand (m)."""
HAND_MASS, FINGER_MASS = 1.0, 0.2
FRICTION = 1.0

ROD_SIZE = (0.12, 1.0)
ROD_MASS = 0.5
BALL_RADIUS = 0.15
BALL_MASS = 0.3

BASKET_INNER = 0.36
"""Inner width of a basket (m); the rod has 0.12 m of play on each side."""
BASKET_HEIGHT = 0.35
BASKET_WALL = 0.025
"""Radius of a basket wall's segment (m)."""
CUP_HEIGHT = 1.0
"""Height of the floor of BallPlacing's cup above the world's floor (m)."""
CUP_DEPTH = 0.08
"""Height of the cup's walls (m): below the ball's centre, so the fingertips close on the ball above the rim."""

GOAL_RADIUS = 0.5
"""Reaching and BallPlacing succeed within this distance of the goal (m), as in the paper."""
EDGE_MARGIN = 0.01
"""The ball "hits an edge" when its surface comes this close to the floor, a side wall or the ceiling (m)."""

HAND_START_X, HAND_START_Y = (1.0, 9.0), (2.5, 5.0)
"""Ranges of the grip point's start position (m), drawn per episode in every task."""
BLUE_BASKET_X, RED_BASKET_X = (1.5, 3.5), (6.5, 8.5)
"""Base: ranges of the baskets' centres; which side each is on is drawn per episode too."""
VARIED_BASKET_FLOOR = (0.0, 3.0)
"""BaseVaried: range of each basket's floor height (m); the highest leaves the carried rod's hand below the
ceiling."""
HAND_HALF_WIDTH = 0.4
"""How far the open hand reaches sideways from its grip point (m): the palm's half-width, and the splayed fingers'
tips a little beyond it. A start or a path of the hand keeps this clear of the baskets."""
REACH_GOAL_X, REACH_GOAL_Y = (0.5, 9.5), (0.5, 5.5)
CUP_X = (1.5, 4.0)
"""BallPlacing: range of the cup's centre (the ball starts resting in it); the env's ``cup_x`` changes it."""
CUP_MARGIN = 1.0
"""The least distance of the cup's centre from a side wall (m): room for the hand to reach round it."""
BALL_GOAL = (7.5, 2.5)
"""BallPlacing's fixed goal (m)."""
NEAR_CLEARANCE = 0.25
"""BallPlacing with ``hand_near``: the lowest start of the grip point above the ball's centre (m), the open
fingertips 0.1 m over the ball."""
REACH_REWARD, BALL_REWARD = 100.0, 200.0
CUP_WIDTH_RANGE = (2 * BALL_RADIUS + 0.01, 2 * (CUP_MARGIN - BASKET_WALL) - 0.1)
"""BallPlacing's ``cup_width`` (m): wider than the ball, and the cup's walls at least 0.05 m in from the least
distance of its centre from a side wall."""
CUP_DEPTH_RANGE = (0.01, 1.0)
"""BallPlacing's ``cup_depth`` (m)."""
FINGER_OPEN_RANGE = (-0.8, 0.0)
"""BallPlacing's ``finger_open`` (rad): from splayed by 0.8 rad (about 46 degrees) to hanging straight down."""

CALIBRATION_GRID = {
    "cup": {"cup": {}, "bowl": {"cup_width": 1.0, "cup_depth": 0.3}, "wide-bowl": {"cup_width": 1.4, "cup_depth": 0.3}},
    "fingers": {"fingers-0.1": {}, "fingers-0.5": {"finger_open": -0.5}},
    "cups": {"cups-1.5-4": {}, "cups-5-6.5": {"cup_x": [5.0, 6.5]}},
    "hand": {"hand-anywhere": {}, "hand-near-1": {"hand_near": 1.0}},
}
"""The candidate values of BallPlacing's open constants that docs/robothand.md's calibration protocol measures
(``benchmarks/robothand_calibration.py``), each value a name and the keyword arguments it sets; every combination is
a candidate setting. The first value of each is today's (no keyword arguments: ``RobotHand-BallPlacing-v0`` as
registered). The cup: today's shallow cup (0.36 m wide, 0.08 m walls), or a bowl 1 m or 1.4 m wide with 0.3 m walls
that keeps a ball a missed grasp pushed within reach; the fingers' open limit: today's -0.1 rad or splayed to -0.5;
the cup's range: today's, 3.5-6 m left of the goal, or 1-2.5 m; the hand's start: anywhere in the upper world, or
within 1 m of the ball (``hand_near``)."""


def calibration_candidates() -> dict[str, dict]:
    """Every setting of CALIBRATION_GRID by name ("bowl+fingers-0.1+cups-5-6.5+hand-near-1"), as BallPlacing's
    keyword arguments (``gym.make("famarl/RobotHand-BallPlacing-v0", **kwargs)``); today's setting,
    "cup+fingers-0.1+cups-1.5-4+hand-anywhere", has none."""
    settings = {"": {}}
    for values in CALIBRATION_GRID.values():
        settings = {
            f"{name}+{value}".lstrip("+"): kwargs | more
            for name, kwargs in settings.items()
            for value, more in values.items()
        }
    return settings


def calibration_kwargs(name: str) -> dict:
    """The keyword arguments of the candidate setting ``name`` (:func:`calibration_candidates`)."""
    candidates = calibration_candidates()
    if name not in candidates:
        raise ValueError(f"unknown BallPlacing setting {name!r}; expected one of {sorted(candidates)}")
    return dict(candidates[name])


OBSERVATION_NAMES = (
    "grip_x", "grip_y", "hand_vx", "hand_vy", "hand_sin", "hand_cos", "hand_omega", "closure",
    "object_x", "object_y", "object_vx", "object_vy", "object_sin", "object_cos",
    "target_x", "target_y", "source_x", "source_y",
)  # fmt: skip
"""Observation layout, the same in every task. ``closure`` is the fingers' mean inward angle scaled to 0 (open)
.. 1 (closed). The object is the rod or the ball (zeros in Reaching); the target is the red basket or the
goal; the source is the blue basket or the cup (zeros in Reaching)."""
NO_OBJECT = (0.0,) * 6
"""The object's part of the observation in Reaching, which has none."""

ACTION_SPACE = gym.spaces.Box(-1.0, 1.0, shape=(4,), dtype=np.float32)
"""(move x, move y, rotate, grasp); grasp > 0 closes the fingers, < 0 opens them, 0 holds them where they are."""


@dataclass(frozen=True)
class TaskSpec:
    name: str
    max_episode_steps: int
    time_penalty: bool = True
    min_goal_distance: float = 0.0
    """Reaching: goals are drawn at least this far from the grip's start (m)."""
    basket_floor: tuple[float, float] = (0.0, 0.0)
    """Base: range of each basket's floor height (m); a raised basket stands on a post."""
    drop_costs_rest: bool = False
    """BallPlacing: a ball that hits an edge ends the episode with ``-|b - g|`` for each step left of the task's own
    ``max_episode_steps`` at once (a limit passed to ``gym.make`` does not change it), so that knocking the ball off
    never costs less than leaving it where it fell (BallPlacingNoEscape; in BallPlacing-v0, the paper's words read
    literally, the episode's end stops the cost, and dropping the ball pays: docs/robothand.md)."""


FAR_GOAL = 2.0
"""Reaching-v1's least distance of a goal from the grip's start (m): the smallest measured that makes Reaching
sparse by our rule, random primitive actions reaching the goal in at most 2% of episodes (the paper's Reaching is
too hard for PPO; where goals may lie next to the start, random actions find them: docs/robothand.md,
benchmarks/robothand_sparsity.py)."""

TASKS = {
    "base": TaskSpec("base", 400),
    "base-varied": TaskSpec("base", 400, basket_floor=VARIED_BASKET_FLOOR),
    "reaching": TaskSpec("reaching", 200),
    "reaching-no-penalty": TaskSpec("reaching", 200, time_penalty=False),
    "reaching-far": TaskSpec("reaching", 200, min_goal_distance=FAR_GOAL),
    "reaching-far-no-penalty": TaskSpec("reaching", 200, time_penalty=False, min_goal_distance=FAR_GOAL),
    "ball-placing": TaskSpec("ball-placing", 300),
    "ball-placing-no-escape": TaskSpec("ball-placing", 300, drop_costs_rest=True),
}


def _rotate(vector: tuple[float, float], angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([c * vector[0] - s * vector[1], s * vector[0] + c * vector[1]])


# chipmunk's own accessors, which a step calls some twenty times: pymunk's Body and Constraint properties wrap each
# in Python (a Vec2d built per read, an assert per write) that costs several times the call. They take the handles
# pymunk keeps as _body, _constraint and _space, its private cffi layer (pyproject pins pymunk 7; a release that moved
# them would fail every RobotHand test at once).
_position, _velocity = chipmunk.cpBodyGetPosition, chipmunk.cpBodyGetVelocity
_angle, _angular_velocity = chipmunk.cpBodyGetAngle, chipmunk.cpBodyGetAngularVelocity
_set_position, _set_angle = chipmunk.cpBodySetPosition, chipmunk.cpBodySetAngle
_set_velocity, _set_angular_velocity = chipmunk.cpBodySetVelocity, chipmunk.cpBodySetAngularVelocity
_set_rate, _space_step = chipmunk.cpSimpleMotorSetRate, chipmunk.cpSpaceStep


class Hand:
    """Palm, two fingers and the kinematic control body that drags them, added to ``space``."""

    def __init__(self, space: pymunk.Space, grip: tuple[float, float], finger_open: float = FINGER_OPEN) -> None:
        """``finger_open``: the fingers' open limit (inward angle, rad); FINGER_OPEN unless a BallPlacing setting
        opens them wider (a wider grasp window: docs/robothand.md's calibration)."""
        self.finger_open = finger_open
        palm_xy = (grip[0], grip[1] + GRIP_DEPTH)
        self.control = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        self.control.position = palm_xy
        self.palm = pymunk.Body(HAND_MASS, pymunk.moment_for_box(HAND_MASS, PALM_SIZE))
        self.palm.position = palm_xy
        hand_only = pymunk.ShapeFilter(group=1)
        palm_shape = pymunk.Poly.create_box(self.palm, PALM_SIZE)
        shapes = [palm_shape]
        pull = pymunk.PivotJoint(self.control, self.palm, (0, 0), (0, 0))
        pull.max_force, pull.max_bias = HAND_FORCE, 4 * HAND_SPEED
        turn = pymunk.GearJoint(self.control, self.palm, 0.0, 1.0)
        turn.max_force, turn.max_bias = HAND_TORQUE, 4 * TURN_SPEED
        constraints = [pull, turn]
        self.fingers, self.motors = [], []
        for side in (-1.0, 1.0):
            finger = pymunk.Body(FINGER_MASS, pymunk.moment_for_box(FINGER_MASS, FINGER_SIZE))
            pivot = (side * FINGER_X, -PALM_SIZE[1] / 2)
            finger.position = (palm_xy[0] + pivot[0], palm_xy[1] + pivot[1] - FINGER_SIZE[1] / 2)
            shapes += [pymunk.Poly.create_box(finger, FINGER_SIZE), pymunk.Poly(finger, PAD_VERTICES[side])]
            hinge = pymunk.PivotJoint(self.palm, finger, pivot, (0, FINGER_SIZE[1] / 2))
            # The left finger (side -1) closes by turning counter-clockwise, the right one clockwise.
            low, high = (finger_open, FINGER_CLOSED) if side < 0 else (-FINGER_CLOSED, -finger_open)
            limit = pymunk.RotaryLimitJoint(self.palm, finger, low, high)
            motor = pymunk.SimpleMotor(self.palm, finger, 0.0)
            motor.max_force = GRIP_TORQUE
            constraints += [hinge, limit, motor]
            self.fingers.append(finger)
            self.motors.append(motor)
        for shape in shapes:
            shape.filter, shape.friction = hand_only, FRICTION
        space.add(self.control, self.palm, *self.fingers, *shapes, *constraints)
        # chipmunk's handles of the bodies and motors, for its accessors
        self._control, self._palm = self.control._body, self.palm._body
        self._fingers = tuple(finger._body for finger in self.fingers)
        self._motors = tuple(motor._constraint for motor in self.motors)

    def step(self, space: pymunk.Space, action) -> list[float]:
        """One environment step of ``space`` with the hand driven by ``action``'s four numbers (clipped to the action
        bounds); the hand's part of the observation after it (:meth:`observe`)."""
        x, y, turn, grasp = [-1.0 if a < -1.0 else 1.0 if a > 1.0 else float(a) for a in action]
        _set_velocity(self._control, (x * HAND_SPEED, y * HAND_SPEED))
        _set_angular_velocity(self._control, turn * TURN_SPEED)
        # SimpleMotor drives (finger - palm) angular velocity to minus its rate.
        _set_rate(self._motors[0], -grasp * FINGER_SPEED)
        _set_rate(self._motors[1], grasp * FINGER_SPEED)
        # chipmunk's step without pymunk's Space.step around it, whose bookkeeping (bodies just added checked;
        # additions, removals and callbacks queued during a step) RobotHand never needs.
        handle, dt = space._space, DT / SUBSTEPS
        for _ in range(SUBSTEPS):
            _space_step(handle, dt)
        # the palm read once: the leash moves only the control body
        at, angle = _position(self._palm), _angle(self._palm)
        self._keep_on_leash(at, angle)
        return self._observed(at, angle)

    def _keep_on_leash(self, at, palm_angle: float) -> None:
        """Bring the control body back within LEASH of the palm (at ``at``, turned by ``palm_angle``), in position and
        in angle, and into the world."""
        control = self._control
        pull = _position(control)
        x, y = pull.x, pull.y
        # never pull the palm out of the world
        dx = (0.0 if x < 0.0 else WIDTH if x > WIDTH else x) - at.x
        dy = (0.0 if y < 0.0 else HEIGHT if y > HEIGHT else y) - at.y
        # abs(complex) is the C library's hypot, which np.hypot called before this step was rewritten in floats;
        # math.hypot rounds differently in the last bit, and the leash feeds back into the physics.
        distance = abs(complex(dx, dy))
        scale = LEASH / distance if distance > LEASH else 1.0
        _set_position(control, (at.x + dx * scale, at.y + dy * scale))
        turn = _angle(control) - palm_angle
        if abs(turn) > LEASH:
            _set_angle(control, palm_angle + copysign(LEASH, turn))

    @property
    def grip(self) -> np.ndarray:
        return np.array(_grip(_position(self._palm), _angle(self._palm)))

    def observe(self) -> list[float]:
        """The hand's part of the observation (OBSERVATION_NAMES' first eight), in double precision."""
        return self._observed(_position(self._palm), _angle(self._palm))

    def _observed(self, at, angle: float) -> list[float]:
        """:meth:`observe` of a palm at ``at`` turned by ``angle``, read already: the grip point, the palm's velocity,
        the sine and cosine of its angle and its angular velocity, and the fingers' closure (0 open .. 1 closed)."""
        palm, (left, right) = self._palm, self._fingers
        velocity = _velocity(palm)
        inward = (_angle(left) - angle) - (_angle(right) - angle)
        return [
            *_grip(at, angle),
            velocity.x,
            velocity.y,
            sin(angle),
            cos(angle),
            _angular_velocity(palm),
            # scaled by this hand's own open limit, so that 0 is open whatever the setting
            (inward / 2 - self.finger_open) / (FINGER_CLOSED - self.finger_open),
        ]


def _grip(palm, angle: float) -> tuple[float, float]:
    """The grip point (between the tips of the open fingers) of a palm at ``palm`` (a position, with x and y) turned
    by ``angle``."""
    return palm.x + sin(angle) * GRIP_DEPTH, palm.y - cos(angle) * GRIP_DEPTH


def _pad_vertices(side: float) -> list[tuple[float, float]]:
    """The fingertip pad of the finger on ``side`` (-1 left, +1 right), in the finger's own frame.

    It is laid out in the palm's frame with the finger turned to the angle at which its tip meets the rod's
    face, and then carried into the finger's frame, so that at that angle it fills the gap to the rod exactly.
    """
    pivot = np.array([side * FINGER_X, -PALM_SIZE[1] / 2])
    reach = FINGER_X - FINGER_SIZE[1] * np.sin(ROD_CONTACT_ANGLE)  # |x| of the finger's axis at the tip
    inward = -side * ROD_CONTACT_ANGLE
    tip_y = pivot[1] - FINGER_SIZE[1] * np.cos(ROD_CONTACT_ANGLE)
    outer, inner = side * reach, side * ROD_SIZE[0] / 2
    corners = [(outer, tip_y), (inner, tip_y), (inner, tip_y + PAD_HEIGHT), (outer, tip_y + PAD_HEIGHT)]
    centre = pivot + _rotate((0.0, -FINGER_SIZE[1] / 2), inward)
    return [tuple(_rotate(np.subtract(c, centre), -inward)) for c in corners]


PAD_VERTICES = {side: _pad_vertices(side) for side in (-1.0, 1.0)}
"""The pads' vertices by side, laid out once: every reset builds a hand."""


def _add_basket(
    space: pymunk.Space, x: float, floor_y: float, depth: float = BASKET_HEIGHT, inner: float = BASKET_INNER
) -> list[pymunk.Segment]:
    """A basket (or cup) of inner width ``inner`` with its floor at ``floor_y``, on a post down to the world's floor
    when raised; returns the basket's own segments (the ones drawn in its colour)."""
    half = inner / 2 + BASKET_WALL
    body = space.static_body
    segments = [
        pymunk.Segment(body, (x - half, floor_y), (x + half, floor_y), BASKET_WALL),
        pymunk.Segment(body, (x - half, floor_y), (x - half, floor_y + depth), BASKET_WALL),
        pymunk.Segment(body, (x + half, floor_y), (x + half, floor_y + depth), BASKET_WALL),
    ]
    for segment in segments:
        segment.friction = FRICTION
    space.add(*segments)
    if floor_y > 0:
        space.add(pymunk.Segment(body, (x, 0.0), (x, floor_y), BASKET_WALL))
    return segments


def column_tops(source: np.ndarray, target: np.ndarray) -> list[tuple[float, float]]:
    """Base: (x, top) of the two baskets' columns (post, basket and, in the blue one, the rod standing in it), from
    the baskets' (x, floor height) at reset: what a hand must not start in nor pass through."""
    return [
        (float(source[0]), float(source[1]) + BASKET_WALL + ROD_SIZE[1]),
        (float(target[0]), float(target[1]) + BASKET_HEIGHT),
    ]


def hand_hits(grip: np.ndarray, columns: list[tuple[float, float]], margin: float = 0.1) -> bool:
    """Whether an open hand with its grip point at ``grip`` comes within ``margin`` of any column (x, top) that
    stands from the world's floor up to its top."""
    reach = HAND_HALF_WIDTH + BASKET_INNER / 2 + BASKET_WALL + margin
    return any(abs(grip[0] - x) < reach and grip[1] < top + margin for x, top in columns)


def empty_world() -> pymunk.Space:
    """A space with gravity and the world's four edges, nothing else."""
    space = pymunk.Space()
    space.gravity = (0.0, -GRAVITY)
    space.iterations = SOLVER_ITERATIONS
    space.collision_slop = COLLISION_SLOP
    # Thick walls just outside the world: a hand pressed on a zero-width edge with HAND_FORCE went through it.
    r = EDGE_THICKNESS
    corners = [(-r, -r), (WIDTH + r, -r), (WIDTH + r, HEIGHT + r), (-r, HEIGHT + r)]
    ends = zip(corners, corners[1:] + corners[:1], strict=True)
    edges = [pymunk.Segment(space.static_body, a, b, r) for a, b in ends]
    for edge in edges:
        edge.friction = FRICTION
    space.add(*edges)
    return space


@dataclass
class Layout:
    """What is drawn at reset: where the hand starts and where the task's things are."""

    grip: np.ndarray
    target: np.ndarray
    source: np.ndarray


class RobotHandEnv(gym.Env):
    """One RobotHand episode (pymunk world rebuilt at every reset, which is cheaper than copying a space)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": int(round(1 / DT))}

    def __init__(
        self,
        task: str = "base",
        time_penalty: bool = True,
        render_mode: str | None = None,
        cup_x: tuple[float, float] = CUP_X,
        ball_reward: float = BALL_REWARD,
        hand_near: float | None = None,
        cup_width: float = BASKET_INNER,
        cup_depth: float = CUP_DEPTH,
        finger_open: float = FINGER_OPEN,
    ) -> None:
        """``cup_x``: BallPlacing's range of the cup's centre, where the ball starts (the paper does not say; the
        sensitivity pipeline varies it). ``ball_reward``: BallPlacing's reward on arrival (the paper's +200), weighed
        against ``-|b - g|`` a step, whose scale the paper's unstated world size sets. ``hand_near``: BallPlacing's
        grip starts within this distance (m) sideways of the cup's centre and up to this far above NEAR_CLEARANCE
        over the ball's centre (within the start box's x range and under its top), not anywhere in the start box:
        where the hand starts is not in the paper, and it decides how often random actions touch the ball.
        ``cup_width``, ``cup_depth``: the inner width and wall height of BallPlacing's cup (m); a wide deep cup (a
        bowl) keeps a ball that a missed grasp pushed within reach, where today's shallow cup lets it fall to the floor,
        an edge, and ends the episode. ``finger_open``: the open fingers' inward angle (rad; negative splays them),
        the calibration's lever on how far off the ball's centre a grasp still takes it. The defaults are the setting
        every run so far used (docs/robothand.md's calibration protocol lists the candidates, CALIBRATION_GRID)."""
        if task not in TASKS:
            raise ValueError(f"unknown RobotHand task {task!r}; expected one of {sorted(TASKS)}")
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"unsupported render_mode {render_mode!r}")
        try:
            low, high = (float(x) for x in cup_x)
        except (TypeError, ValueError):
            raise ValueError(f"cup_x must be two numbers (low, high), got {cup_x!r}") from None
        if not CUP_MARGIN <= low <= high <= WIDTH - CUP_MARGIN:
            raise ValueError(f"cup_x must satisfy {CUP_MARGIN} <= low <= high <= {WIDTH - CUP_MARGIN}, got {cup_x!r}")
        self.cup_x = (low, high)
        # a bool is an int to Python; True as a reward is a mistake, not 1.0
        if isinstance(ball_reward, bool) or not (
            isinstance(ball_reward, int | float) and np.isfinite(ball_reward) and ball_reward >= 0
        ):
            raise ValueError(f"ball_reward must be a finite number >= 0, got {ball_reward!r}")
        self.ball_reward = float(ball_reward)
        self.task = TASKS[task]
        if hand_near is not None and (
            isinstance(hand_near, bool) or not isinstance(hand_near, int | float) or not 0 < hand_near < WIDTH
        ):
            raise ValueError(f"hand_near must be a distance in (0, {WIDTH:g}) m, got {hand_near!r}")
        if hand_near is not None and self.task.name != "ball-placing":
            raise ValueError(f"hand_near is BallPlacing's; the task is {task!r}")
        self.hand_near = None if hand_near is None else float(hand_near)
        self.cup_width = _ball_placing_number("cup_width", cup_width, task, BASKET_INNER, CUP_WIDTH_RANGE)
        self.cup_depth = _ball_placing_number("cup_depth", cup_depth, task, CUP_DEPTH, CUP_DEPTH_RANGE)
        self.finger_open = _ball_placing_number("finger_open", finger_open, task, FINGER_OPEN, FINGER_OPEN_RANGE)
        self.time_penalty = time_penalty and self.task.time_penalty
        self.render_mode = render_mode
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(len(OBSERVATION_NAMES),), dtype=np.float32)
        self.action_space = ACTION_SPACE
        self.space: pymunk.Space | None = None
        self.steps = 0
        """Steps since reset: BallPlacingNoEscape charges a dropped ball for the steps left."""
        self.hand: Hand | None = None
        self.object: pymunk.Body | None = None
        self.layout: Layout | None = None

    # -- building ---------------------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        rng = self.np_random
        self.space = empty_world()
        grip = np.array([rng.uniform(*HAND_START_X), rng.uniform(*HAND_START_Y)])
        self.object = None
        self.colours: dict[pymunk.Shape, tuple[int, int, int]] = {}
        if self.task.name == "base":
            blue, red = rng.uniform(*BLUE_BASKET_X), rng.uniform(*RED_BASKET_X)
            if rng.random() < 0.5:  # mirror the layout so that rods are carried both ways
                blue, red = WIDTH - blue, WIDTH - red
            floors = (0.0, 0.0)
            if self.task.basket_floor != (0.0, 0.0):  # drawn only here, so Base's episodes stay as they were
                floors = (rng.uniform(*self.task.basket_floor), rng.uniform(*self.task.basket_floor))
            source, target = np.array([blue, floors[0]]), np.array([red, floors[1]])
            # A start in a raised basket's column is drawn again, not moved: the start stays uniform where it is free.
            while hand_hits(grip, column_tops(source, target)):
                grip = np.array([rng.uniform(*HAND_START_X), rng.uniform(*HAND_START_Y)])
            self.colours.update(dict.fromkeys(_add_basket(self.space, blue, floors[0]), COLOURS["blue"]))
            self.colours.update(dict.fromkeys(_add_basket(self.space, red, floors[1]), COLOURS["red"]))
            self.object = self._add_rod(blue, floors[0])
        elif self.task.name == "reaching":
            source = np.zeros(2)
            target = np.array([rng.uniform(*REACH_GOAL_X), rng.uniform(*REACH_GOAL_Y)])
            while np.linalg.norm(target - grip) < self.task.min_goal_distance:  # drawn again, not moved: uniform
                target = np.array([rng.uniform(*REACH_GOAL_X), rng.uniform(*REACH_GOAL_Y)])
        else:
            cup = rng.uniform(*self.cup_x)
            source, target = np.array([cup, CUP_HEIGHT]), np.array(BALL_GOAL)
            self._add_cup(cup)
            self.object = self._add_ball(cup)
            if self.hand_near is not None:  # drawn only here, so the default's episodes stay as they were
                ball_y = self.object.position.y
                x = np.clip(cup + rng.uniform(-self.hand_near, self.hand_near), *HAND_START_X)
                grip = np.array([x, min(ball_y + NEAR_CLEARANCE + rng.uniform(0, self.hand_near), HAND_START_Y[1])])
        self.layout = Layout(grip=grip, target=target, source=source)
        self.hand = Hand(self.space, tuple(grip), self.finger_open)
        self.steps = 0
        return self._observe(), {"success": False}

    def _add_rod(self, x: float, floor_y: float) -> pymunk.Body:
        rod = pymunk.Body(ROD_MASS, pymunk.moment_for_box(ROD_MASS, ROD_SIZE))
        rod.position = (x, floor_y + BASKET_WALL + ROD_SIZE[1] / 2)
        shape = pymunk.Poly.create_box(rod, ROD_SIZE)
        shape.friction = FRICTION
        self.space.add(rod, shape)
        return rod

    def _add_cup(self, x: float) -> None:
        cup = _add_basket(self.space, x, CUP_HEIGHT, self.cup_depth, self.cup_width)
        self.colours.update(dict.fromkeys(cup, COLOURS["blue"]))

    def _add_ball(self, x: float) -> pymunk.Body:
        ball = pymunk.Body(BALL_MASS, pymunk.moment_for_circle(BALL_MASS, 0, BALL_RADIUS))
        ball.position = (x, CUP_HEIGHT + BASKET_WALL + BALL_RADIUS)
        shape = pymunk.Circle(ball, BALL_RADIUS)
        shape.friction = FRICTION
        self.space.add(ball, shape)
        return ball

    # -- stepping ---------------------------------------------------------------------------------------------
    def step(self, action):
        if self.space is None:
            raise RuntimeError("call reset() before step()")
        values = np.asarray(action).reshape(4).tolist()
        if not all(map(isfinite, values)):
            raise ValueError(f"action must be finite, got {np.asarray(values)}")
        self.steps += 1
        state = self._state(self.hand.step(self.space, values))
        reward, terminated, success = self._outcome(state)
        return np.array(state, dtype=np.float32), reward, terminated, False, {"success": success}

    # A step reads the world once, into Python floats: numpy's arrays of two cost more to make than the arithmetic.
    def _state(self, hand: list[float] | None = None) -> list[float]:
        """The observation's values (OBSERVATION_NAMES), in double precision, after the hand's own (its
        :meth:`Hand.observe`, where read already)."""
        state = hand or self.hand.observe()
        if self.object is None:
            state += NO_OBJECT
        else:
            body = self.object._body
            at, velocity, angle = _position(body), _velocity(body), _angle(body)
            state += (at.x, at.y, velocity.x, velocity.y, sin(angle), cos(angle))
        state += self.layout.target.tolist()
        state += self.layout.source.tolist()
        return state

    def _outcome(self, state: list[float] | None = None) -> tuple[float, bool, bool]:
        """(reward, terminated, success) of the state just reached (``state``: its :meth:`_state`, where read)."""
        # OBSERVATION_NAMES' order
        grip_x, grip_y, _, _, _, _, _, closure, x, y, _, vy, _, _, target_x, target_y, _, _ = state or self._state()
        if self.task.name == "reaching":
            success = hypot(grip_x - target_x, grip_y - target_y) < GOAL_RADIUS
            return (REACH_REWARD if success else -1.0 if self.time_penalty else 0.0), success, success
        distance = hypot(x - target_x, y - target_y)
        if self.task.name == "base":
            success = rod_in_basket(x, y, _angle(self.object._body), vy, target_x, target_y) and closure < 0.5
            return -distance, success, success
        success = distance < GOAL_RADIUS
        dropped = not success and ball_hits_edge((x, y))
        rest = max(self.task.max_episode_steps - self.steps, 0) if dropped and self.task.drop_costs_rest else 0
        reward = -distance * (1 + rest) + (self.ball_reward if success else 0.0)
        return reward, success or dropped, success

    def _observe(self) -> np.ndarray:
        return np.array(self._state(), dtype=np.float32)

    # -- drawing ----------------------------------------------------------------------------------------------
    def render(self):
        if self.render_mode != "rgb_array" or self.space is None:
            return None
        return render_scene(self)


def _ball_placing_number(name: str, value, task: str, default: float, bounds: tuple[float, float]) -> float:
    """``value`` of BallPlacing's setting ``name`` as a float, checked within ``bounds`` (inclusive); a value other
    than ``default`` only in a BallPlacing task. One clear error line otherwise."""
    low, high = bounds
    # a bool is an int to Python; True as a width is a mistake, not 1.0
    if isinstance(value, bool) or not isinstance(value, int | float) or not low <= value <= high:
        raise ValueError(f"{name} must be a number in [{low:g}, {high:g}], got {value!r}")
    if value != default and TASKS[task].name != "ball-placing":
        raise ValueError(f"{name} is BallPlacing's; the task is {task!r}")
    return float(value)


def rod_in_basket(x: float, y: float, angle: float, vertical_speed: float, basket_x: float, floor_y: float) -> bool:
    """Whether the rod, its centre at (``x``, ``y``), stands upright inside the basket centred at ``basket_x`` with
    its floor at ``floor_y`` (resting on its floor, slowly)."""
    bottom = y - floor_y - ROD_SIZE[1] / 2 * cos(angle)
    inside = abs(x - basket_x) < BASKET_INNER / 2
    return inside and bottom < BASKET_HEIGHT / 2 and abs(angle) < 0.3 and abs(vertical_speed) < 0.5


def ball_hits_edge(position: tuple[float, float]) -> bool:
    reach = BALL_RADIUS + EDGE_MARGIN
    x, y = position
    return bool(x < reach or x > WIDTH - reach or y < reach or y > HEIGHT - reach)


COLOURS = {
    "hand": (90, 90, 100),
    "finger": (50, 50, 60),
    "rod": (200, 150, 60),
    "ball": (40, 90, 220),
    "blue": (60, 110, 230),
    "red": (220, 50, 50),
    "static": (120, 120, 120),
}


def render_scene(env: RobotHandEnv, pixels: int = 320) -> np.ndarray:
    """An RGB frame of the world: the source basket or cup blue, the target basket red, the goal a red disc."""
    canvas = Canvas(WIDTH, HEIGHT, pixels, background=(245, 245, 240))
    if env.task.name != "base":
        canvas.disc(*env.layout.target, GOAL_RADIUS, (250, 200, 200))
        canvas.disc(*env.layout.target, 0.08, COLOURS["red"])
    for shape in env.space.static_body.shapes:
        canvas.segment(shape.a, shape.b, max(shape.radius, 0.03), env.colours.get(shape, COLOURS["static"]))
    for body in env.space.bodies:
        for shape in body.shapes:
            if isinstance(shape, pymunk.Circle):
                canvas.disc(*body.position, shape.radius, COLOURS["ball"])
                continue
            colour = COLOURS["rod"] if body is env.object else COLOURS["finger"] if body in env.hand.fingers else None
            canvas.polygon([body.local_to_world(v) for v in shape.get_vertices()], colour or COLOURS["hand"])
    return canvas.image


def simulate_open_loop(actions: np.ndarray, lengths: np.ndarray, start: tuple[float, float]) -> np.ndarray:
    """Grip-point paths of macro actions run open-loop by a hand alone in the world, from rest at ``start``.

    ``actions`` is (n, L, 4) and ``lengths`` (n,); returns (n, L + 1, 2) positions, each path held at its last
    position after its own length, so paths of different lengths stack.
    """
    n, steps = actions.shape[:2]
    paths = np.empty((n, steps + 1, 2))
    for i in range(n):
        space = empty_world()
        hand = Hand(space, start)
        paths[i, 0] = hand.grip
        for t in range(steps):
            if t < lengths[i]:
                hand.step(space, actions[i, t])
            paths[i, t + 1] = hand.grip
    return paths


def traversal_paths(actions: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """(n, L + 1, 2) grip-point paths of (n, L, 4) macro actions run open-loop from the centre, the hand alone (no
    objects): the world latent traversals run in."""
    return simulate_open_loop(actions, lengths, (WIDTH / 2, HEIGHT / 2))
