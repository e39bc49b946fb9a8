"""ContinuousWorld for many worlds at once, in numpy, for training.

It runs :func:`~famarl_cli.envs.continuous_world.physics_step` on all worlds in one call, so its transitions
are those of :class:`~famarl_cli.envs.continuous_world.ContinuousWorldEnv` (a test checks it). Finished
worlds reset in the same step (gymnasium's SAME_STEP autoreset): the returned observation is the new
episode's first one and the last observation of the finished episode is in ``info["final_obs"]``, which is
what a learner needs to bootstrap the value of a time-limit truncation; ``info["success"]`` says which ended
episodes reached the goal.

``step(actions, active)`` moves only the worlds selected by ``active`` (the others keep their state and get
reward 0): that is how macro actions of different lengths run side by side (:mod:`famarl_cli.rl.executor`).

``autoreset = False`` leaves an ended episode as it ended, and :meth:`reset_all` starts every world on the
episode that the single env's ``reset(seed=seed)`` starts: together they run many open-loop plans from one
reset (the action-space oracle, :mod:`famarl_cli.rl.oracle`).
"""

from __future__ import annotations

import json

import numpy as np
from gymnasium.utils import seeding

from famarl_cli.envs.continuous_world import (
    ACTION_SPACE,
    GOAL_RADIUS,
    ROWS,
    TASKS,
    Layouts,
    distance_to_goal,
    observation_space,
    observe,
    physics_step,
    sample_layouts,
)


class ContinuousWorldBatch:
    """``n_envs`` ContinuousWorld episodes stepped together; actions are (n_envs, 2) arrays. An episode succeeds
    when it terminates: only reaching the goal does."""

    success_rule = "reaching the goal (famarl's ContinuousWorld reports it)"
    autoreset = True
    """Whether an ended episode restarts in the step it ends (module doc); False leaves it as it ended."""

    def __init__(
        self,
        task: str = "maze",
        n_envs: int = 64,
        seed: int = 0,
        goal_rows: tuple[str, ...] = ROWS,
        max_episode_steps: int | None = None,
    ) -> None:
        if n_envs < 1:
            raise ValueError(f"n_envs must be >= 1, got {n_envs}")
        self.task = TASKS[task]
        self.n_envs = n_envs
        self.goal_rows = tuple(goal_rows)
        self.max_episode_steps = max_episode_steps or self.task.max_episode_steps
        self.rng = np.random.default_rng(seed)
        self.groups = [(slice(0, n_envs), self.rng)]
        """Runs of worlds and the generator that draws their episodes: one here, one per part when joined."""
        self.parts: list[ContinuousWorldBatch] = []
        self.load(sample_layouts(self.rng, n_envs, self.task, self.goal_rows))

    @staticmethod
    def join(parts: list[ContinuousWorldBatch]) -> ContinuousWorldBatch:
        """One batch of the worlds of ``parts`` (same task, goal rows and time limit), stepped in one call: each
        part's worlds draw their next episodes from the part's own generator, so every world goes exactly as in its
        part alone. :meth:`write_back` puts the worlds' state back into the parts."""
        first = parts[0]
        settings = {(p.task, p.goal_rows, p.max_episode_steps) for p in parts}
        if len(settings) > 1:
            raise ValueError("only batches of one task, goal rows and time limit can be joined")
        joined = object.__new__(ContinuousWorldBatch)
        joined.task, joined.goal_rows, joined.max_episode_steps = first.task, first.goal_rows, first.max_episode_steps
        joined.n_envs, joined.rng, joined.parts = sum(p.n_envs for p in parts), None, list(parts)
        starts = np.cumsum([0, *[p.n_envs for p in parts]])
        joined.groups = [(slice(int(a), int(b)), p.rng) for a, b, p in zip(starts[:-1], starts[1:], parts, strict=True)]
        joined.layouts = Layouts.concatenate([p.layouts for p in parts])
        joined.pos, joined.vel = (np.concatenate([getattr(p, f) for p in parts]) for f in ("pos", "vel"))
        joined.elapsed = np.concatenate([p.elapsed for p in parts])
        return joined

    def write_back(self) -> None:
        """Copy the joined worlds' state into the parts (their state dicts then describe them)."""
        for (part, _), batch in zip(self.groups, self.parts, strict=True):
            batch.layouts = Layouts(*(getattr(self.layouts, f)[part].copy() for f in Layouts.__dataclass_fields__))
            batch.pos, batch.vel = self.pos[part].copy(), self.vel[part].copy()
            batch.elapsed = self.elapsed[part].copy()

    def _draw(self, done: np.ndarray) -> Layouts:
        """Fresh layouts for the worlds ``done``, in their order, each from its group's generator."""
        return Layouts.concatenate(
            [
                sample_layouts(rng, int(done[part].sum()), self.task, self.goal_rows)
                for part, rng in self.groups
                if done[part].any()
            ]
        )

    def load(self, layouts: Layouts) -> np.ndarray:
        """Start a fresh episode in every world from the given layouts; returns the observations."""
        if len(layouts) != self.n_envs:
            raise ValueError(f"expected {self.n_envs} layouts, got {len(layouts)}")
        self.layouts = layouts
        self.pos = layouts.start.copy()
        self.vel = np.zeros_like(self.pos)
        self.elapsed = np.zeros(self.n_envs, dtype=np.int64)
        return observe(self.pos, self.vel, self.layouts, self.task.entrances_observed)

    def reset(self) -> np.ndarray:
        return self.load(self._draw(np.ones(self.n_envs, dtype=bool)))

    def reset_all(self, seed: int) -> np.ndarray:
        """Start every world on the episode that :class:`~famarl_cli.envs.continuous_world.ContinuousWorldEnv`'s
        ``reset(seed=seed)`` starts (its layout, drawn from gymnasium's generator of ``seed`` as the env draws it);
        returns the observations."""
        one = sample_layouts(seeding.np_random(seed)[0], 1, self.task, self.goal_rows)
        return self.load(Layouts.concatenate([one] * self.n_envs))

    @property
    def observation_size(self) -> int:
        return observation_space(self.task).shape[0]

    @property
    def action_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return ACTION_SPACE.low.astype(np.float64), ACTION_SPACE.high.astype(np.float64)

    def step(self, actions: np.ndarray, active: np.ndarray | None = None):
        """Returns observations, rewards, terminations, truncations and an info dict (see module doc)."""
        pos, vel = physics_step(self.pos, self.vel, np.asarray(actions, np.float64), self.layouts)
        if active is None:
            active = np.ones(self.n_envs, dtype=bool)
            self.pos, self.vel = pos, vel
        else:
            self.pos = np.where(active[:, None], pos, self.pos)
            self.vel = np.where(active[:, None], vel, self.vel)
        self.elapsed += active
        dist = distance_to_goal(self.pos, self.layouts)
        terminated = active & (dist < GOAL_RADIUS)
        truncated = active & ~terminated & (self.elapsed >= self.max_episode_steps)
        obs = observe(self.pos, self.vel, self.layouts, self.task.entrances_observed)
        info = {}
        done = terminated | truncated
        if done.any():
            info["final_obs"] = obs.copy()
            info["success"] = terminated.astype(np.float64)
            if self.autoreset:
                fresh = self._draw(done)
                self.layouts = self.layouts.assign(done, fresh)
                self.pos[done] = fresh.start
                self.vel[done] = 0.0
                self.elapsed[done] = 0
                obs[done] = observe(self.pos[done], self.vel[done], fresh, self.task.entrances_observed)
        return obs, np.where(active, -dist, 0.0), terminated, truncated, info

    def state_dict(self) -> dict:
        """Everything that decides what happens next (worlds, clocks, random generator), for exact resumes."""
        return {
            "rng": json.dumps(self.rng.bit_generator.state),
            "pos": self.pos.copy(),
            "vel": self.vel.copy(),
            "elapsed": self.elapsed.copy(),
            **{f"layouts.{f}": getattr(self.layouts, f).copy() for f in Layouts.__dataclass_fields__},
        }

    def load_state_dict(self, state: dict) -> np.ndarray:
        """Restore a :meth:`state_dict`; returns the current observations."""
        self.rng.bit_generator.state = json.loads(state["rng"])
        self.layouts = Layouts(**{f: np.asarray(state[f"layouts.{f}"]) for f in Layouts.__dataclass_fields__})
        self.pos, self.vel = np.asarray(state["pos"]), np.asarray(state["vel"])
        self.elapsed = np.asarray(state["elapsed"])
        return observe(self.pos, self.vel, self.layouts, self.task.entrances_observed)
