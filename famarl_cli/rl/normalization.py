"""Running statistics for observation normalisation and reward scaling.

Both are part of the trained agent: they are saved in its checkpoint and frozen at evaluation, so that the
policy sees at test time the inputs it was trained on.
"""

from __future__ import annotations

import numpy as np

from famarl_cli.rl.executor import discounted_sum

CLIP = 10.0
EPSILON = 1e-8


class RunningMeanStd:
    """Mean and variance over every row seen so far (Chan et al.'s parallel update)."""

    def __init__(self, shape: tuple[int, ...] = ()) -> None:
        self.mean = np.zeros(shape)
        self.var = np.ones(shape)
        self.count = EPSILON

    def update(self, batch: np.ndarray) -> None:
        # np.mean and np.var by hand: their wrappers cost more than the arithmetic on a rollout step's rows.
        n = batch.shape[0]
        batch_mean = np.add.reduce(batch, axis=0, dtype=np.float64) / n
        batch_var = np.add.reduce(np.square(batch - batch_mean), axis=0) / n
        total = self.count + n
        delta = batch_mean - self.mean
        self.mean = self.mean + delta * n / total
        self.var = (self.var * self.count + batch_var * n + delta**2 * self.count * n / total) / total
        self.count = total

    def state_dict(self) -> dict:
        return {"mean": self.mean.copy(), "var": self.var.copy(), "count": float(self.count)}

    def load_state_dict(self, state: dict) -> None:
        self.mean, self.var, self.count = np.asarray(state["mean"]), np.asarray(state["var"]), float(state["count"])


class ObservationNormalizer(RunningMeanStd):
    """``enabled=False`` passes observations through unchanged (for ablations)."""

    def __init__(self, shape: tuple[int, ...], enabled: bool = True) -> None:
        super().__init__(shape)
        self.enabled = enabled

    def __call__(self, obs: np.ndarray, update: bool) -> np.ndarray:
        if not self.enabled:
            return obs.astype(np.float32)
        if update:
            self.update(obs)
        normalized = (obs - self.mean) / np.sqrt(self.var + EPSILON)
        return np.minimum(np.maximum(normalized, -CLIP), CLIP).astype(np.float32)


class RewardScaler:
    """Divides rewards by the running standard deviation of the discounted return, so that the value targets
    stay near unit scale whatever the task's reward units (ContinuousWorld's macro rewards reach -100s).

    Calling it scales a decision's summed reward, with the return discounted per decision (the paper's
    convention). :meth:`scale_steps` scales every environment step's reward before the decision sums them,
    with the return discounted per step (the semi-MDP form): the statistics are then those of primitive-action
    PPO whatever the decisions' lengths.
    """

    def __init__(self, n_envs: int, enabled: bool = True) -> None:
        self.returns = np.zeros(n_envs)
        self.stats = RunningMeanStd()
        self.enabled = enabled

    def __call__(self, reward: np.ndarray, discount: np.ndarray, done: np.ndarray) -> np.ndarray:
        if not self.enabled:
            return reward
        self.returns = self.returns * discount + reward
        self.stats.update(self.returns)
        self.returns[done] = 0.0
        return np.minimum(np.maximum(reward / np.sqrt(self.stats.var + EPSILON), -CLIP), CLIP)

    def scale_steps(self, rewards: np.ndarray, steps: np.ndarray, gamma: float, done: np.ndarray) -> np.ndarray:
        """``sum_k gamma ** k * scaled(r_k)`` over each decision's ``steps`` (N,) first rewards (N, L)."""
        if not self.enabled:
            return discounted_sum(rewards, gamma)
        total = np.zeros(len(steps))
        for k in range(int(steps.max(initial=0))):
            active = k < steps
            self.returns[active] = self.returns[active] * gamma + rewards[active, k]
            self.stats.update(self.returns[active])
            scaled = np.minimum(np.maximum(rewards[active, k] / np.sqrt(self.stats.var + EPSILON), -CLIP), CLIP)
            total[active] += gamma**k * scaled
        self.returns[done] = 0.0
        return total

    def state_dict(self) -> dict:
        return {"returns": self.returns.copy(), **self.stats.state_dict()}

    def load_state_dict(self, state: dict) -> None:
        self.returns = np.asarray(state["returns"])
        self.stats.load_state_dict(state)
