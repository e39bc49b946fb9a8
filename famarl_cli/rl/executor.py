"""Execution of action sequences over a batch of environments: the one path that FaMARL's macro actions,
FiGAR's repeated actions and primitive actions (sequences of length 1) all take.

Each environment runs its own sequence for its own length; the batch steps together and an environment whose
sequence (or episode) has ended waits, inactive, for the others. A sequence stops where its episode ends: the
rest of it is dropped, and the next decision starts on the new episode.

A sequence is open-loop, its actions fixed when it starts (an array), or closed-loop, each action chosen from the
state the step starts in (a :class:`Plan`: the closed-loop macro decoder's).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Protocol

import numpy as np

from famarl_cli.envs.vector import BatchedEnv


class Plan(Protocol):
    """A closed-loop sequence: the (N, D) actions of step ``k`` of every row from the (N, obs) states reached."""

    def __call__(self, k: int, obs: np.ndarray) -> np.ndarray: ...


@dataclass
class SequenceResult:
    obs: np.ndarray
    """(N, obs) after the sequence; where an episode ended, the next episode's first observation."""
    reward: np.ndarray
    """(N,) sum of the rewards collected (the paper's r_tot)."""
    rewards: np.ndarray
    """(N, L) each step's reward; 0 after a sequence (or its episode) ended (:func:`discounted_sum`)."""
    steps: np.ndarray
    """(N,) environment steps executed; less than the sequence's length where the episode ended first."""
    terminated: np.ndarray
    truncated: np.ndarray
    success: np.ndarray
    """(N,) float: 1.0 where the episode ended in success, 0.0 where it ended otherwise or has not ended, NaN where
    it ended and success is not defined (the batch's ``info["success"]``, :mod:`famarl_cli.envs.success`)."""
    final_obs: np.ndarray
    """(N, obs) last observation of an episode that ended (meaningful where terminated | truncated)."""

    def rows(self, part: slice) -> SequenceResult:
        """The result of the environments ``part`` of the batch alone."""
        return SequenceResult(*(getattr(self, f.name)[part] for f in fields(self)))


def run_sequences(
    env: BatchedEnv,
    obs: np.ndarray,
    actions: np.ndarray | Plan,
    lengths: np.ndarray,
    on_step: Callable[[np.ndarray, np.ndarray], None] | None = None,
) -> SequenceResult:
    """Run ``actions[i, :lengths[i]]`` in environment ``i`` from current observations ``obs``; for a :class:`Plan`,
    step ``k``'s actions are ``actions(k, obs)`` of the observations reached (rows that have stopped included).

    ``on_step(active, obs)`` is called after every batch step with the observations that step reached (an
    ended episode's last one, not the next episode's first); evaluation uses it to trace paths.
    """
    n = env.n_envs
    rewards = np.zeros((n, int(lengths.max(initial=0))))
    reward = np.zeros(n)
    steps = np.zeros(n, dtype=np.int64)
    terminated = np.zeros(n, dtype=bool)
    truncated = np.zeros(n, dtype=bool)
    success = np.zeros(n)
    final_obs = obs.copy()
    for k in range(int(lengths.max(initial=0))):
        active = (k < lengths) & ~terminated & ~truncated
        if not active.any():
            break
        step = actions[:, k] if isinstance(actions, np.ndarray) else actions(k, obs)
        obs, r, term, trunc, info = env.step(step, active)
        rewards[:, k] = r
        reward += r
        steps += active
        ended = term | trunc
        if ended.any():
            final_obs[ended] = info["final_obs"][ended]
        terminated |= term
        truncated |= trunc
        if ended.any():  # a batch that says nothing of success does not define it
            success = np.where(ended, info.get("success", np.nan), success)
        if on_step is not None:
            on_step(active, np.where(ended[:, None], final_obs, obs))
    return SequenceResult(obs, reward, rewards, steps, terminated, truncated, success, final_obs)


def discounted_sum(rewards: np.ndarray, gamma: float) -> np.ndarray:
    """(N,) ``sum_k gamma ** k * r_k`` over each row of per-step rewards (N, L), such as
    :attr:`SequenceResult.rewards`: a sequence's reward in the semi-MDP form."""
    return (rewards * gamma ** np.arange(rewards.shape[1])).sum(1)
