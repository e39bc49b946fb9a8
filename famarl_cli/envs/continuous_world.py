"""ContinuousWorld: a damped point mass in a walled 2-D map (the paper's first environment).

Every constant lives here and is explained in ``docs/environments.md``. The physics is written once, for a
batch of worlds (arrays with a leading ``n`` axis); the single gymnasium environment runs it with ``n = 1`` and
:mod:`famarl_cli.envs.batched` with ``n`` in the thousands, so the two cannot drift apart.

Coordinates are metres, ``x`` to the right and ``y`` up; the map is ``[0, width] x [0, height]``.
Internal walls are horizontal segments at fixed heights, each with one entrance (a gap) whose centre is drawn
per episode. Walls have zero thickness: a step whose straight path crosses a wall outside its entrance is
stopped just short of it, which is exact (no tunnelling) because one step moves at most
``MAX_SPEED * DT`` = 0.2 m, less than the spacing between walls.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import gymnasium as gym
import numpy as np

from famarl_cli.envs.render import Canvas

DT = 0.1
"""Seconds per environment step."""
MAX_ACCEL = 2.0
"""Acceleration (m/s^2) at |action| = 1 on an axis."""
DRAG = 1.0
"""Linear drag (1/s); with MAX_ACCEL it sets the terminal speed on one axis to 2 m/s."""
MAX_SPEED = 2.0
"""Hard cap on the speed (m/s); bounds the distance of one step, which the wall collision relies on."""
GOAL_RADIUS = 0.3
"""An episode succeeds (terminates) when the agent is closer than this to the goal (m)."""
CORNER_MARGIN = 0.2
"""Distance of the start and goal positions from the map's edges (m); below GOAL_RADIUS so that an agent
pressed against the edge of the goal's row still reaches the goal."""
WALL_CLEARANCE = 1e-3
"""How far from a wall a blocked agent is put back (m), so that it stays strictly on its side."""
ENTRANCE_WIDTH = 0.6
"""Width of the gap in each Maze wall (m)."""


@dataclass(frozen=True)
class TaskSpec:
    """What varies between ContinuousWorld tasks."""

    name: str
    size_range: tuple[float, float]
    """Side of the square map (m), drawn uniformly per episode."""
    n_walls: int
    max_episode_steps: int
    entrances_observed: bool = True
    """Whether the observation holds each wall's entrance centre; without it the agent must search for them."""


BASE = TaskSpec(name="base", size_range=(2.5, 5.0), n_walls=0, max_episode_steps=200)
MAZE = TaskSpec(name="maze", size_range=(5.0, 5.0), n_walls=4, max_episode_steps=400)
MAZE_BLIND = replace(MAZE, name="maze-blind", entrances_observed=False)
TASKS = {spec.name: spec for spec in (BASE, MAZE, MAZE_BLIND)}

ROWS = ("top", "bottom")


@dataclass(frozen=True)
class Layouts:
    """The per-episode draw of ``n`` worlds: everything about an episode that is not the agent's motion."""

    size: np.ndarray
    """(n,) side of the square map."""
    start: np.ndarray
    """(n, 2) agent start position."""
    goal: np.ndarray
    """(n, 2) goal position."""
    wall_y: np.ndarray
    """(n, n_walls) heights of the internal walls."""
    entrance_x: np.ndarray
    """(n, n_walls) centres of the walls' entrances."""

    def __len__(self) -> int:
        return len(self.size)

    @staticmethod
    def concatenate(parts: list[Layouts]) -> Layouts:
        return Layouts(*(np.concatenate([getattr(p, f) for p in parts]) for f in Layouts.__dataclass_fields__))

    def assign(self, mask: np.ndarray, other: Layouts) -> Layouts:
        """A copy with the worlds selected by ``mask`` replaced by ``other`` (one world per selected one)."""
        fields = {}
        for f in self.__dataclass_fields__:
            values = getattr(self, f).copy()
            values[mask] = getattr(other, f)
            fields[f] = values
        return replace(self, **fields)


def sample_layouts(
    rng: np.random.Generator,
    n: int,
    task: TaskSpec,
    goal_rows: tuple[str, ...] = ROWS,
) -> Layouts:
    """Draw ``n`` episode layouts.

    Base: agent and goal sit at corners, each on the top or bottom row (the paper's 2 x 2 cases); ``goal_rows``
    restricts the goal's row, which is how the ``down-only`` script keeps its demos free of upward moves. The
    paper leaves the columns open; we put the agent at a random side and the goal at the other, so that demos
    hold both leftward and rightward moves, which the Maze needs.
    Maze (and Maze-blind): agent at the top centre, goal at the bottom centre, walls evenly spaced between them.
    """
    lo, hi = task.size_range
    size = rng.uniform(lo, hi, n)
    far = size - CORNER_MARGIN
    if task.n_walls:
        start = np.stack([size / 2, far], axis=1)
        goal = np.stack([size / 2, np.full(n, CORNER_MARGIN)], axis=1)
    else:
        agent_top = rng.integers(0, 2, n).astype(bool)
        goal_top = rng.choice(np.array([r == "top" for r in goal_rows]), n)
        agent_left = rng.integers(0, 2, n).astype(bool)
        start_x = np.where(agent_left, CORNER_MARGIN, far)
        goal_x = np.where(agent_left, far, CORNER_MARGIN)
        start = np.stack([start_x, np.where(agent_top, far, CORNER_MARGIN)], axis=1)
        goal = np.stack([goal_x, np.where(goal_top, far, CORNER_MARGIN)], axis=1)
    k = task.n_walls
    wall_y = size[:, None] * np.arange(k, 0, -1)[None, :] / (k + 1)
    half_gap = ENTRANCE_WIDTH / 2 + CORNER_MARGIN
    entrance_x = rng.uniform(half_gap, size[:, None] - half_gap, (n, k))
    return Layouts(size=size, start=start, goal=goal, wall_y=wall_y, entrance_x=entrance_x)


def physics_step(
    pos: np.ndarray, vel: np.ndarray, action: np.ndarray, layouts: Layouts
) -> tuple[np.ndarray, np.ndarray]:
    """Advance ``n`` point masses by one step; returns new (n, 2) positions and velocities.

    Semi-implicit Euler with linear drag, a speed cap, then collisions: internal walls (a step that would cross
    a wall outside its entrance ends just short of the wall with the vertical velocity zeroed, the horizontal
    motion kept so the agent slides along it) and the map's edges (clamped, the normal velocity zeroed).
    """
    accel = MAX_ACCEL * np.clip(action, -1.0, 1.0)
    vel = vel + (accel - DRAG * vel) * DT
    speed = np.sqrt(np.einsum("ij,ij->i", vel, vel))
    vel = vel * np.minimum(1.0, MAX_SPEED / np.maximum(speed, 1e-12))[:, None]
    new_pos = pos + vel * DT

    if layouts.wall_y.shape[1]:
        y0, y1 = pos[:, 1:2], new_pos[:, 1:2]
        was_above = y0 > layouts.wall_y
        crossed = was_above != (y1 > layouts.wall_y)
        # A crossing puts y0 and y1 on different sides, so its denominator is never 0.
        frac = (y0 - layouts.wall_y) / np.where(crossed, y0 - y1, 1.0)
        cross_x = pos[:, 0:1] + frac * (new_pos[:, 0:1] - pos[:, 0:1])
        blocked = crossed & (np.abs(cross_x - layouts.entrance_x) > ENTRANCE_WIDTH / 2)
        hit = blocked.any(axis=1)
        if hit.any():
            wall = blocked.argmax(axis=1)[hit]
            rows = np.flatnonzero(hit)
            side = np.where(was_above[rows, wall], WALL_CLEARANCE, -WALL_CLEARANCE)
            new_pos[rows, 1] = layouts.wall_y[rows, wall] + side
            vel[rows, 1] = 0.0

    upper = layouts.size[:, None]
    outside = (new_pos < 0.0) | (new_pos > upper)
    new_pos = np.clip(new_pos, 0.0, upper)
    vel = np.where(outside, 0.0, vel)
    return new_pos, vel


def distance_to_goal(pos: np.ndarray, layouts: Layouts) -> np.ndarray:
    delta = pos - layouts.goal
    return np.sqrt(np.einsum("ij,ij->i", delta, delta))


def observe(pos: np.ndarray, vel: np.ndarray, layouts: Layouts, entrances: bool = True) -> np.ndarray:
    """Observation rows: position, velocity, goal, map width and height, then (if ``entrances``) each wall's
    entrance centre."""
    size = layouts.size[:, None]
    parts = [pos, vel, layouts.goal, size, size] + ([layouts.entrance_x] if entrances else [])
    return np.concatenate(parts, axis=1).astype(np.float32)


def observation_space(task: TaskSpec) -> gym.spaces.Box:
    top = task.size_range[1]
    shown = task.n_walls if task.entrances_observed else 0
    low = [0, 0, -MAX_SPEED, -MAX_SPEED, 0, 0, 0, 0] + [0] * shown
    high = [top, top, MAX_SPEED, MAX_SPEED, top, top, top, top] + [top] * shown
    return gym.spaces.Box(np.array(low, np.float32), np.array(high, np.float32), dtype=np.float32)


ACTION_SPACE = gym.spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)


def render_layout(layout: Layouts, pos: np.ndarray | None = None, pixels: int = 256) -> np.ndarray:
    """An RGB picture of one world (``layout`` holding one episode), the agent drawn at ``pos`` if given."""
    size = float(layout.size[0])
    canvas = Canvas(size, size, pixels)
    thickness = 0.04 * size
    for y, x in zip(layout.wall_y[0], layout.entrance_x[0], strict=True):
        half = ENTRANCE_WIDTH / 2
        canvas.rect(0.0, y - thickness / 2, x - half, y + thickness / 2, (60, 60, 60))
        canvas.rect(x + half, y - thickness / 2, size, y + thickness / 2, (60, 60, 60))
    canvas.disc(*layout.goal[0], GOAL_RADIUS, (220, 40, 40))
    if pos is not None:
        canvas.disc(*pos, 0.1, (30, 80, 220))
    return canvas.image


class ContinuousWorldEnv(gym.Env):
    """One ContinuousWorld episode at a time, for gymnasium users, demos and evaluation.

    Reward: minus the distance to the goal, every step. Terminates when the agent is within GOAL_RADIUS of the
    goal; the time limit is added by gymnasium's registration (``TaskSpec.max_episode_steps``).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": int(round(1 / DT))}

    def __init__(self, task: str = "base", goal_rows: tuple[str, ...] = ROWS, render_mode: str | None = None) -> None:
        if task not in TASKS:
            raise ValueError(f"unknown ContinuousWorld task {task!r}; expected one of {sorted(TASKS)}")
        unknown = set(goal_rows) - set(ROWS)
        if not goal_rows or unknown:
            raise ValueError(f"goal_rows must be a non-empty subset of {ROWS}, got {goal_rows!r}")
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"unsupported render_mode {render_mode!r}")
        self.task = TASKS[task]
        self.goal_rows = tuple(goal_rows)
        self.render_mode = render_mode
        self.observation_space = observation_space(self.task)
        self.action_space = ACTION_SPACE
        self.layout: Layouts | None = None
        self._pos = np.zeros((1, 2))
        self._vel = np.zeros((1, 2))

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self.layout = sample_layouts(self.np_random, 1, self.task, self.goal_rows)
        self._pos = self.layout.start.copy()
        self._vel = np.zeros((1, 2))
        return observe(self._pos, self._vel, self.layout, self.task.entrances_observed)[0], self._info()

    def step(self, action):
        if self.layout is None:
            raise RuntimeError("call reset() before step()")
        action = np.asarray(action, dtype=np.float64).reshape(1, 2)
        if not np.isfinite(action).all():
            raise ValueError(f"action must be finite, got {action[0]}")
        self._pos, self._vel = physics_step(self._pos, self._vel, action, self.layout)
        dist = distance_to_goal(self._pos, self.layout)[0]
        obs = observe(self._pos, self._vel, self.layout, self.task.entrances_observed)[0]
        reached = bool(dist < GOAL_RADIUS)
        return obs, -float(dist), reached, False, {**self._info(), "success": reached}

    def _info(self) -> dict:
        return {"position": self._pos[0].copy(), "map_size": float(self.layout.size[0])}

    def render(self):
        if self.render_mode == "rgb_array" and self.layout is not None:
            return render_layout(self.layout, self._pos[0])
        return None


def simulate_open_loop(
    actions: np.ndarray, lengths: np.ndarray, start: tuple[float, float], map_size: float
) -> np.ndarray:
    """Positions of macro actions run open-loop from rest at ``start`` in an empty square map.

    ``actions`` is (n, L, 2) and ``lengths`` (n,); returns (n, L + 1, 2) positions, each macro action's path
    held at its last position after its own length, so paths of different lengths stack.
    """
    n, steps = actions.shape[:2]
    layouts = Layouts(
        size=np.full(n, float(map_size)),
        start=np.tile(np.asarray(start, dtype=float), (n, 1)),
        goal=np.tile(np.asarray(start, dtype=float), (n, 1)),
        wall_y=np.zeros((n, 0)),
        entrance_x=np.zeros((n, 0)),
    )
    pos, vel = layouts.start.copy(), np.zeros((n, 2))
    path = np.empty((n, steps + 1, 2))
    path[:, 0] = pos
    for t in range(steps):
        moved, moved_vel = physics_step(pos, vel, actions[:, t].astype(np.float64), layouts)
        running = (t < lengths)[:, None]
        pos, vel = np.where(running, moved, pos), np.where(running, moved_vel, vel)
        path[:, t + 1] = pos
    return path


TRAVERSAL_MAP_SIZE = 10.0
"""Side (m) of the empty map latent traversals run in: twice Base's largest map."""


def traversal_paths(actions: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """(n, L + 1, 2) paths of (n, L, 2) macro actions run open-loop from rest at the centre of an empty
    TRAVERSAL_MAP_SIZE map, so that a macro action as long as the demos' longest legs never reaches an edge."""
    centre = (TRAVERSAL_MAP_SIZE / 2, TRAVERSAL_MAP_SIZE / 2)
    return simulate_open_loop(actions, lengths, centre, TRAVERSAL_MAP_SIZE)
