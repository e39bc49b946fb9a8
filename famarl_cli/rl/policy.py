"""The actor-critic: separate 64-64 tanh networks, orthogonal initialisation, a state-independent log std,
and for FiGAR a categorical head over repeat counts on the actor's features (CleanRL's layout).
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn
from torch.distributions import Categorical, Normal


def _init(layer: nn.Linear, gain: float) -> nn.Linear:
    nn.init.orthogonal_(layer.weight, gain)
    nn.init.zeros_(layer.bias)
    return layer


def _trunk(inputs: int, hidden: int) -> nn.Sequential:
    gain = float(np.sqrt(2))
    return nn.Sequential(
        _init(nn.Linear(inputs, hidden), gain), nn.Tanh(), _init(nn.Linear(hidden, hidden), gain), nn.Tanh()
    )


class PolicyDistribution:
    """A diagonal Gaussian over the continuous output, times a categorical over repeat counts when there is one.

    Log-probabilities and entropies are of the joint distribution: the two parts are independent given the
    state, so they add.
    """

    def __init__(self, normal: Normal, repeat: Categorical | None) -> None:
        self.normal, self.repeat = normal, repeat

    def sample(self) -> tuple[torch.Tensor, torch.Tensor]:
        u = self.normal.sample()
        index = self.repeat.sample() if self.repeat is not None else torch.zeros(len(u), dtype=torch.long)
        return u, index

    def mode(self) -> tuple[torch.Tensor, torch.Tensor]:
        mean = self.normal.mean
        index = self.repeat.probs.argmax(dim=1) if self.repeat is not None else torch.zeros(len(mean), dtype=torch.long)
        return mean, index

    def log_prob(self, u: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
        logp = self.normal.log_prob(u).sum(dim=1)
        return logp + self.repeat.log_prob(index) if self.repeat is not None else logp

    def entropy(self) -> torch.Tensor:
        entropy = self.normal.entropy().sum(dim=1)
        return entropy + self.repeat.entropy() if self.repeat is not None else entropy


class ActorCritic(nn.Module):
    def __init__(self, obs_size: int, action_size: int, repeat_choices: int = 0, hidden: int = 64) -> None:
        super().__init__()
        self.critic = nn.Sequential(_trunk(obs_size, hidden), _init(nn.Linear(hidden, 1), 1.0))
        self.actor = _trunk(obs_size, hidden)
        # Small output gains start the policy near its mean of 0 with std 1: for FaMARL, the FAVAE prior.
        self.mean = _init(nn.Linear(hidden, action_size), 0.01)
        self.log_std = nn.Parameter(torch.zeros(action_size))
        self.repeat_logits = _init(nn.Linear(hidden, repeat_choices), 0.01) if repeat_choices else None

    def value(self, obs: torch.Tensor) -> torch.Tensor:
        return self.critic(obs).squeeze(1)

    def distribution(self, obs: torch.Tensor) -> PolicyDistribution:
        features = self.actor(obs)
        # Argument validation costs a third of a distribution's construction; our arguments are valid by design.
        normal = Normal(self.mean(features), self.log_std.exp().expand(len(obs), -1), validate_args=False)
        repeat = (
            Categorical(logits=self.repeat_logits(features), validate_args=False)
            if self.repeat_logits is not None
            else None
        )
        return PolicyDistribution(normal, repeat)
