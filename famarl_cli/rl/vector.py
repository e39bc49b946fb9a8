"""Batched environments: many episodes stepped together, with an ``active`` mask so that open-loop sequences
of different lengths can run side by side.

Every batch follows gymnasium's SAME_STEP autoreset: an episode that ends is restarted in the same step, the
returned observation is the new episode's first one and the finished episode's last observation is in
``info["final_obs"]``. Where an environment can end an episode without success (RobotHand BallPlacing), the
batch reports ``info["success"]``; elsewhere success is termination.

ContinuousWorld has a numpy batch that steps all worlds in one call; any other gymnasium id with Box spaces
(RobotHand included) runs as a Python loop over ``gymnasium.make`` copies.
"""

from __future__ import annotations

from typing import Protocol

import gymnasium as gym
import numpy as np

from famarl_cli.envs import CONTINUOUS_WORLD_IDS
from famarl_cli.envs.batched import ContinuousWorldBatch
from famarl_cli.errors import UsageError


class BatchedEnv(Protocol):
    n_envs: int

    @property
    def observation_size(self) -> int: ...

    @property
    def action_bounds(self) -> tuple[np.ndarray, np.ndarray]: ...

    def reset(self) -> np.ndarray: ...

    def step(self, actions: np.ndarray, active: np.ndarray | None = None) -> tuple: ...

    def state_dict(self) -> dict | None:
        """The state to resume from exactly, or None when the environment cannot be snapshotted."""

    def load_state_dict(self, state: dict) -> np.ndarray: ...


class GymBatch:
    """``n_envs`` copies of a gymnasium environment stepped in a loop; only active ones move."""

    def __init__(self, env_id: str, n_envs: int, seed: int, **make_kwargs) -> None:
        self.envs = [gym.make(env_id, **make_kwargs) for _ in range(n_envs)]
        space = self.envs[0].action_space
        obs_space = self.envs[0].observation_space
        if not isinstance(space, gym.spaces.Box) or not isinstance(obs_space, gym.spaces.Box):
            raise UsageError(f"{env_id}: famarl trains on Box observation and action spaces only")
        self.n_envs = n_envs
        self.seed = seed
        self.observation_size = int(np.prod(obs_space.shape))
        self.action_bounds = (space.low.astype(np.float64), space.high.astype(np.float64))
        self.obs = np.zeros((n_envs, self.observation_size), np.float32)

    def reset(self) -> np.ndarray:
        for i, env in enumerate(self.envs):
            self.obs[i] = np.ravel(env.reset(seed=self.seed + i)[0])
        return self.obs.copy()

    def step(self, actions: np.ndarray, active: np.ndarray | None = None):
        active = np.ones(self.n_envs, dtype=bool) if active is None else active
        rewards = np.zeros(self.n_envs)
        terminated = np.zeros(self.n_envs, dtype=bool)
        truncated = np.zeros(self.n_envs, dtype=bool)
        success = np.zeros(self.n_envs, dtype=bool)
        final_obs = self.obs.copy()
        for i in np.flatnonzero(active):
            obs, rewards[i], terminated[i], truncated[i], step_info = self.envs[i].step(actions[i])
            success[i] = step_info.get("success", terminated[i])
            if terminated[i] or truncated[i]:
                final_obs[i] = np.ravel(obs)
                obs, _ = self.envs[i].reset()
            self.obs[i] = np.ravel(obs)
        info = {"final_obs": final_obs, "success": success} if (terminated | truncated).any() else {}
        return self.obs.copy(), rewards, terminated, truncated, info

    def state_dict(self) -> None:
        return None  # gymnasium has no general snapshot; a resume starts fresh episodes

    def load_state_dict(self, state: dict) -> np.ndarray:
        raise NotImplementedError


CONTINUOUS_WORLD_TASKS = {env_id: task for task, env_id in CONTINUOUS_WORLD_IDS.items()}


def make_batch(env_id: str, n_envs: int, seed: int) -> BatchedEnv:
    """The fastest batch for ``env_id``; an unknown id is a usage error that lists ours."""
    if env_id in CONTINUOUS_WORLD_TASKS:
        return ContinuousWorldBatch(CONTINUOUS_WORLD_TASKS[env_id], n_envs=n_envs, seed=seed)
    try:
        return GymBatch(env_id, n_envs, seed)
    except gym.error.Error as exc:
        known = ", ".join(sorted(CONTINUOUS_WORLD_TASKS))
        raise UsageError(f"unknown environment {env_id!r} ({exc}); famarl's own: {known}") from exc
