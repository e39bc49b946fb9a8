"""Batched environments: many episodes stepped together, with an ``active`` mask so that open-loop sequences
of different lengths can run side by side.

Every batch follows gymnasium's SAME_STEP autoreset: an episode that ends is restarted in the same step, the
returned observation is the new episode's first one and the finished episode's last observation is in
``info["final_obs"]``; an episode ends terminated or truncated, never both (a step that terminates at the time
limit is terminated), and ``info["success"]`` (N,) is each ended episode's success by
:mod:`famarl_cli.envs.success`: 1.0, 0.0, or NaN where success is not defined. ``success_rule`` says, in words,
which rule judged the episodes that ended so far (None before any has).

ContinuousWorld has a numpy batch that steps all worlds in one call; any other gymnasium id with Box spaces
(RobotHand included) runs as a Python loop over ``gymnasium.make`` copies.
"""

from __future__ import annotations

from functools import partial
from typing import Protocol

import gymnasium as gym
import numpy as np

from famarl_cli.core.errors import FamarlError, ForeignError, UsageError, foreign, one_line
from famarl_cli.envs import CONTINUOUS_WORLD_IDS
from famarl_cli.envs.batched import ContinuousWorldBatch
from famarl_cli.envs.external import make_env
from famarl_cli.envs.success import SuccessRule, success_rule


class BatchedEnv(Protocol):
    n_envs: int
    success_rule: str | None

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

    def __init__(
        self, envs: list[gym.Env], seed: int, autoreset: bool = True, success_return: float | None = None
    ) -> None:
        space, obs_space = envs[0].action_space, envs[0].observation_space
        name = envs[0].spec.id if envs[0].spec is not None else type(envs[0].unwrapped).__name__
        self.name = name
        if not isinstance(space, gym.spaces.Box):
            raise UsageError(f"{name}: famarl needs a Box action space, not {space}")
        try:
            self.observation_size = int(gym.spaces.flatdim(obs_space))
        except ValueError as exc:
            raise UsageError(f"{name}: its observation space {obs_space} has no flat form ({exc})") from exc
        self.envs, self.n_envs, self.seed, self.autoreset = envs, len(envs), seed, autoreset
        self.observation_space = obs_space
        # A Box's flat form is its values cast to the space's dtype: gymnasium's flatten does that cast behind a
        # dispatch that costs as much as the cast, once per env step.
        self._flatten = (
            partial(np.asarray, dtype=obs_space.dtype)
            if isinstance(obs_space, gym.spaces.Box)
            else partial(gym.spaces.flatten, obs_space)
        )
        self.action_bounds = (space.low.astype(np.float64), space.high.astype(np.float64))
        self.obs = np.zeros((self.n_envs, self.observation_size), np.float32)
        self.raw_obs: list = [None] * self.n_envs
        self.last_info: list[dict] = [{} for _ in envs]
        self.rule: SuccessRule = success_rule(envs[0].spec, success_return)
        self.success_rule: str | None = None
        self.returns = [0.0] * self.n_envs
        """Each env's episode return so far."""

    @staticmethod
    def make(
        env_id: str,
        n_envs: int,
        seed: int,
        env_kwargs: dict | None = None,
        success_return: float | None = None,
        **make_kwargs,
    ) -> GymBatch:
        envs = [make_env(env_id, env_kwargs, **make_kwargs) for _ in range(n_envs)]
        return GymBatch(envs, seed, success_return=success_return)

    def _observe(self, i: int, obs) -> None:
        self.raw_obs[i] = obs
        self.obs[i] = self._flatten(obs).reshape(-1)

    def reset_one(self, i: int, **reset_kwargs) -> tuple:
        """Reset environment ``i`` with gymnasium's own arguments; its raw observation and info."""
        with foreign(f"env {self.name} reset"):
            obs, info = self.envs[i].reset(**reset_kwargs)
            self._observe(i, obs)
        self.returns[i] = 0.0
        return obs, info

    def reset(self) -> np.ndarray:
        for i in range(self.n_envs):
            self.reset_one(i, seed=self.seed + i)
        return self.obs.copy()

    def reset_all(self, seed: int) -> np.ndarray:
        """Reset every environment with ``reset(seed=seed)``, so that all start the same episode (the oracle's
        plans, :mod:`famarl_cli.rl.oracle`); returns the observations."""
        for i in range(self.n_envs):
            self.reset_one(i, seed=seed)
        return self.obs.copy()

    @property
    def max_episode_steps(self) -> int | None:
        """The environments' time limit (gymnasium's ``TimeLimit``), None where they have none."""
        spec = self.envs[0].spec
        return spec.max_episode_steps if spec is not None else None

    def step(self, actions: np.ndarray, active: np.ndarray | None = None):
        n = self.n_envs
        # The rewards in a Python list, made an array once: a numpy scalar written per env step costs more than the
        # step's own bookkeeping. The ends, rare, are written into their arrays as they come.
        rewards = [0.0] * n
        terminated, truncated, success = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool), np.zeros(n)
        final_obs, any_end = self.obs.copy(), False
        for i in range(n) if active is None else active.nonzero()[0].tolist():
            # The env's own code, which may fail on a value its constructor took (a keyword of the wrong type). Not
            # famarl_cli.core.errors.foreign: a context manager per step costs more than the try, which costs nothing.
            try:
                obs, reward, ended, cut, self.last_info[i] = self.envs[i].step(actions[i])
                self._observe(i, obs)
            except FamarlError:
                raise
            except Exception as exc:
                raise ForeignError(f"env {self.name} step raised {one_line(exc)}") from exc
            try:
                rewards[i] = reward = float(reward)
            except (TypeError, ValueError):
                no_number = f"env {self.name}: its step returned a reward that is no number, {reward!r}"
                raise ForeignError(no_number) from None
            self.returns[i] += reward
            if ended or cut:
                # gymnasium's TimeLimit sets truncated on a step that also terminates: terminated wins, so that no
                # learner bootstraps a value through a terminal state
                terminated[i], truncated[i], any_end = bool(ended), not ended, True
                success[i] = self.rule.judge(self.last_info[i], self.returns[i])
                self.success_rule = self.success_rule or self.rule.describe(self.last_info[i])
                final_obs[i] = self.obs[i]
                if self.autoreset:
                    self.reset_one(i)
        info = {"final_obs": final_obs, "success": success} if any_end else {}
        return self.obs.copy(), np.array(rewards), terminated, truncated, info

    def state_dict(self) -> None:
        return None  # gymnasium has no general snapshot; a resume starts fresh episodes

    def load_state_dict(self, state: dict) -> np.ndarray:
        raise NotImplementedError


CONTINUOUS_WORLD_TASKS = {env_id: task for task, env_id in CONTINUOUS_WORLD_IDS.items()}


def make_batch(
    env_id: str, n_envs: int, seed: int, env_kwargs: dict | None = None, success_return: float | None = None
) -> BatchedEnv:
    """The fastest batch for ``env_id`` (made with ``env_kwargs``, success judged by :mod:`famarl_cli.envs.success`
    with the user's ``success_return``); bad ids are one-line errors (:func:`~famarl_cli.envs.external.make_env`)."""
    if env_id in CONTINUOUS_WORLD_TASKS and not env_kwargs and success_return is None:
        return ContinuousWorldBatch(CONTINUOUS_WORLD_TASKS[env_id], n_envs=n_envs, seed=seed)
    return GymBatch.make(env_id, n_envs, seed, env_kwargs, success_return)
