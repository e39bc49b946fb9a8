"""The state-conditioned prior's guidance of the latent policy (SPiRL, Pertsch et al. 2020), in PPO's terms.

With a prior p(z | s) = N(mu_p(s), sigma_p(s)^2) (:mod:`famarl_cli.method.prior`), the policy's latent head is
written relative to it: pi(z | s) = N(mu_p(s) + m(s), (sigma_p(s) e^l)^2), m being the actor's mean output and l
its state-independent log std. The actor's mean head starts at 0 on the latent (the other weights as ever) and l
at 0, so the policy starts exactly at the prior, where SPiRL clones it by behaviour cloning (there, only as
closely as the fit gets). The loss then pays

    weight * KL(pi(z | s) || p(z | s)) = weight * sum_j [ -l_j + e^(2 l_j) / 2 + m_j^2 / (2 sigma_p,j^2) - 1/2 ],

a term of :func:`~famarl_cli.rl.ppo.ppo_loss` beside PPO's own. The weight is fixed, or tuned each
minibatch towards a target divergence (SPiRL's automatic tuning): log weight += rate * (KL - target).

The prior reads the raw state (the demos' units), not the policy's normalised one. For the hybrid, it guides the
latent branch only: the primitive outputs have base mean 0 and base log std 0.
"""

from __future__ import annotations

import math

import numpy as np

TUNING_RATE = 0.01
"""Change of log(weight) per minibatch and nat of KL above the target: about one e-fold per PPO update (80
minibatches) when the KL is a nat off."""
WEIGHT_RANGE = (1e-4, 100.0)
"""The tuned weight stays within these bounds."""


class PriorGuide:
    """The prior on the policy's outputs ``columns`` (of ``size``), its KL weight and, with ``target_kl`` > 0, the
    weight's tuning."""

    def __init__(self, prior, size: int, columns: slice, weight: float, target_kl: float = 0.0) -> None:
        self.prior, self.size, self.columns = prior, size, columns
        self.target_kl = target_kl
        self.log_weight = math.log(weight) if weight > 0 else -math.inf

    @property
    def weight(self) -> float:
        return math.exp(self.log_weight)

    @property
    def mask(self) -> np.ndarray:
        """(size,) bool: the outputs the prior guides."""
        mask = np.zeros(self.size, dtype=bool)
        mask[self.columns] = True
        return mask

    def base(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(mean, log std), each (N, size) float32: the prior on the guided outputs of raw states ``obs``, 0
        elsewhere."""
        mean, log_std = self.prior(obs)
        base_mean = np.zeros((len(obs), self.size), dtype=np.float32)
        base_log_std = np.zeros((len(obs), self.size), dtype=np.float32)
        base_mean[:, self.columns] = mean
        base_log_std[:, self.columns] = log_std
        return base_mean, base_log_std

    def tune(self, kl: float) -> None:
        """One step of the weight towards the target divergence (nothing with a fixed weight)."""
        if self.target_kl > 0:
            low, high = (math.log(bound) for bound in WEIGHT_RANGE)
            self.log_weight = min(max(self.log_weight + TUNING_RATE * (kl - self.target_kl), low), high)

    def state_dict(self) -> dict:
        return {"log_weight": self.log_weight}

    def load_state_dict(self, state: dict) -> None:
        self.log_weight = float(state["log_weight"])
