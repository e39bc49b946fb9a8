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
from famarl_cli.envs.external import episode_success, make_env
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
    """Gymnasium environments stepped in a loop; only active ones move.

    Observations are flattened with ``gymnasium.spaces.flatten`` (a Dict observation becomes its entries'
    flattened values, in the space's key order), so any observation space with a flat form trains. The last raw
    observation of each environment stays in ``raw_obs`` for callers that hand it on unflattened.

    ``autoreset=False`` leaves an ended episode as it is (the caller resets): the single-environment form under
    :class:`~famarl_cli.wrappers.MacroActionWrapper`.
    """

    def __init__(self, envs: list[gym.Env], seed: int, autoreset: bool = True) -> None:
        space, obs_space = envs[0].action_space, envs[0].observation_space
        name = envs[0].spec.id if envs[0].spec is not None else type(envs[0].unwrapped).__name__
        if not isinstance(space, gym.spaces.Box):
            raise UsageError(f"{name}: famarl needs a Box action space, not {space}")
        try:
            self.observation_size = int(gym.spaces.flatdim(obs_space))
        except ValueError as exc:
            raise UsageError(f"{name}: its observation space {obs_space} has no flat form ({exc})") from exc
        self.envs, self.n_envs, self.seed, self.autoreset = envs, len(envs), seed, autoreset
        self.observation_space = obs_space
        self.action_bounds = (space.low.astype(np.float64), space.high.astype(np.float64))
        self.obs = np.zeros((self.n_envs, self.observation_size), np.float32)
        self.raw_obs: list = [None] * self.n_envs
        self.last_info: list[dict] = [{} for _ in envs]

    @staticmethod
    def make(env_id: str, n_envs: int, seed: int, env_kwargs: dict | None = None, **make_kwargs) -> GymBatch:
        return GymBatch([make_env(env_id, env_kwargs, **make_kwargs) for _ in range(n_envs)], seed)

    def _observe(self, i: int, obs) -> None:
        self.raw_obs[i] = obs
        self.obs[i] = gym.spaces.flatten(self.observation_space, obs)

    def reset_one(self, i: int, **reset_kwargs) -> tuple:
        """Reset environment ``i`` with gymnasium's own arguments; its raw observation and info."""
        obs, info = self.envs[i].reset(**reset_kwargs)
        self._observe(i, obs)
        return obs, info

    def reset(self) -> np.ndarray:
        for i in range(self.n_envs):
            self.reset_one(i, seed=self.seed + i)
        return self.obs.copy()

    def step(self, actions: np.ndarray, active: np.ndarray | None = None):
        active = np.ones(self.n_envs, dtype=bool) if active is None else active
        rewards = np.zeros(self.n_envs)
        terminated = np.zeros(self.n_envs, dtype=bool)
        truncated = np.zeros(self.n_envs, dtype=bool)
        success = np.zeros(self.n_envs, dtype=bool)
        final_obs = self.obs.copy()
        for i in np.flatnonzero(active):
            obs, rewards[i], terminated[i], truncated[i], self.last_info[i] = self.envs[i].step(actions[i])
            success[i] = episode_success(self.last_info[i], terminated[i])
            self._observe(i, obs)
            if terminated[i] or truncated[i]:
                final_obs[i] = self.obs[i]
                if self.autoreset:
                    self.reset_one(i)
        info = {"final_obs": final_obs, "success": success} if (terminated | truncated).any() else {}
        return self.obs.copy(), rewards, terminated, truncated, info

    def state_dict(self) -> None:
        return None  # gymnasium has no general snapshot; a resume starts fresh episodes

    def load_state_dict(self, state: dict) -> np.ndarray:
        raise NotImplementedError


CONTINUOUS_WORLD_TASKS = {env_id: task for task, env_id in CONTINUOUS_WORLD_IDS.items()}


def make_batch(env_id: str, n_envs: int, seed: int, env_kwargs: dict | None = None) -> BatchedEnv:
    """The fastest batch for ``env_id`` (made with ``env_kwargs``); bad ids are one-line errors
    (:func:`~famarl_cli.envs.external.make_env`)."""
    if env_id in CONTINUOUS_WORLD_TASKS and not env_kwargs:
        return ContinuousWorldBatch(CONTINUOUS_WORLD_TASKS[env_id], n_envs=n_envs, seed=seed)
    return GymBatch.make(env_id, n_envs, seed, env_kwargs)
