"""A decision's reward and discount, and why the form matters when decisions differ in length.

A decision that ran n environment steps collected rewards r_0 .. r_{n-1}. Two conventions (``--macro-discount``):

- ``decision`` (the paper's): R = sum_j r_j, discount gamma, whatever n;
- ``steps`` (the semi-MDP form, Sutton, Precup & Singh 1999): R = sum_j gamma^j r_j, discount gamma^n, every
  step's reward scaled before the sum (:meth:`~famarl_cli.rl.normalization.RewardScaler.scale_steps`).

Only the second values a path by its environment steps alone. Under the first, a path of T steps taken in
macros of length L is T / L decisions, so its rewards are discounted by the number of decisions: with a constant
penalty, shorter macros look better (more decisions, each discounted more), and with a terminal bonus longer
ones do (the bonus arrives after fewer decisions). :func:`path_value` measures it on :class:`ConstantPenaltyEnv`
through the same executor and reward code that training uses.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from famarl_cli.rl import MacroDiscount
from famarl_cli.rl.executor import SequenceResult, run_sequences
from famarl_cli.rl.normalization import RewardScaler


def decision_reward(
    result: SequenceResult, macro_discount: str, gamma: float, scaler: RewardScaler
) -> tuple[np.ndarray, np.ndarray]:
    """Each decision's (scaled) reward and its discount (N,) under ``macro_discount``."""
    done = result.terminated | result.truncated
    if macro_discount == MacroDiscount.STEPS:
        return scaler.scale_steps(result.rewards, result.steps, gamma, done), gamma ** result.steps.astype(float)
    discount = np.full(len(result.steps), gamma)
    return scaler(result.reward, discount, done), discount


class ConstantPenaltyEnv(gym.Env):
    """A path of ``length`` steps: every step costs ``penalty``, the last one also pays ``bonus``. Actions do
    nothing; the observation is the number of steps left."""

    def __init__(self, length: int = 100, penalty: float = 1.0, bonus: float = 0.0) -> None:
        self.length, self.penalty, self.bonus = length, penalty, bonus
        self.observation_space = gym.spaces.Box(0.0, float(length), (1,), np.float32)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)
        self.left = length

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self.left = self.length
        return np.array([self.left], np.float32), {}

    def step(self, action):
        self.left -= 1
        done = self.left == 0
        reward = -self.penalty + (self.bonus if done else 0.0)
        return np.array([self.left], np.float32), reward, done, False, {}


def path_value(
    macro_length: int, macro_discount: str, gamma: float = 0.99, length: int = 100, bonus: float = 0.0
) -> float:
    """The discounted return, from the start, of walking :class:`ConstantPenaltyEnv`'s path (unit penalty) in
    decisions of ``macro_length`` steps, as PPO's targets count it under ``macro_discount`` (unscaled)."""
    from famarl_cli.envs.vector import GymBatch

    env = GymBatch([ConstantPenaltyEnv(length, 1.0, bonus)], seed=0, autoreset=False)
    obs, value, weight = env.reset(), 0.0, 1.0
    scaler = RewardScaler(1, enabled=False)
    while True:
        result = run_sequences(env, obs, np.zeros((1, macro_length, 1)), np.array([macro_length]))
        reward, discount = decision_reward(result, macro_discount, gamma, scaler)
        value += weight * float(reward[0])
        weight *= float(discount[0])
        if result.terminated[0]:
            return value
        obs = result.obs
