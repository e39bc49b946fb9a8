"""The state-conditioned prior p(z | s) and the closed-loop decoder pi(a | s, z, k / L).

Both read the state normalised by the demos' own mean and std (stored with them). The prior is a diagonal Gaussian
(two tanh layers). The decoder is deterministic: a macro's action at step k is the FAVAE's own open-loop action
a_open(z)_k plus a bounded correction, ``correction * tanh(f(s, z, k / L, a_open(z)_k))`` (two ReLU layers), from
the state the agent has reached. The bound keeps the latent in charge of the macro: an unbounded pi(a | s, z) fitted
on goal-directed demos whose states hold the goal ignores z (docs/skills.md measures it), and a policy cannot steer
what ignores its output.

The rollouts call them on one row per environment, where a torch call costs more than its arithmetic, so each
has a numpy twin (:meth:`GaussianPrior.frozen`, :meth:`ClosedLoopDecoder.frozen`); ``tests/test_prior.py`` checks
that the two agree.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np
import torch
from torch import nn

LOG_STD_MIN, LOG_STD_MAX = -5.0, 2.0
"""The prior's log std is clamped here: a demo state with one segment must not give it a zero std."""


@dataclass(frozen=True)
class PriorConfig:
    obs_size: int
    latent_size: int
    action_size: int
    length: int
    """The FAVAE's input length L: a macro's progress is k / L."""
    hidden: int = 64
    correction: float = 0.25
    """The decoder's largest correction of each open-loop action value."""

    def to_dict(self) -> dict:
        return asdict(self)

    @staticmethod
    def from_dict(values: dict) -> PriorConfig:
        return PriorConfig(**values)


def _numpy_layers(net: nn.Sequential) -> list[tuple[np.ndarray, np.ndarray]]:
    return [
        (layer.weight.detach().numpy().T.astype(np.float64), layer.bias.detach().numpy().astype(np.float64))
        for layer in net
        if isinstance(layer, nn.Linear)
    ]


class StateNetwork(nn.Module):
    """A network of the raw state, normalised by the demos' mean and std (buffers, stored with its weights)."""

    def __init__(self, config: PriorConfig) -> None:
        super().__init__()
        self.config = config
        self.register_buffer("obs_mean", torch.zeros(config.obs_size))
        self.register_buffer("obs_std", torch.ones(config.obs_size))

    def normalised(self, obs: torch.Tensor) -> torch.Tensor:
        return (obs - self.obs_mean) / self.obs_std

    def numpy_normaliser(self) -> Callable[[np.ndarray], np.ndarray]:
        """The normalisation in numpy, float64, of (B, >= O) raw states: their first O values."""
        mean, std = self.obs_mean.numpy().astype(np.float64), self.obs_std.numpy().astype(np.float64)
        return lambda obs: (np.asarray(obs[:, : len(mean)], dtype=np.float64) - mean) / std


class GaussianPrior(StateNetwork):
    def __init__(self, config: PriorConfig) -> None:
        super().__init__(config)
        h = config.hidden
        self.net = nn.Sequential(
            nn.Linear(config.obs_size, h), nn.Tanh(), nn.Linear(h, h), nn.Tanh(), nn.Linear(h, 2 * config.latent_size)
        )

    def forward(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(B, O) raw states -> the prior's mean and log std, each (B, Z)."""
        mean, log_std = self.net(self.normalised(obs)).chunk(2, dim=1)
        return mean, log_std.clamp(LOG_STD_MIN, LOG_STD_MAX)

    def frozen(self) -> FrozenPrior:
        return FrozenPrior(self)


class FrozenPrior:
    """The prior in numpy, float64: ``(mean, log_std)`` of (B, >= O) raw states (their first O values)."""

    def __init__(self, prior: GaussianPrior) -> None:
        self.normalise, self.layers = prior.numpy_normaliser(), _numpy_layers(prior.net)
        self.latent_size = prior.config.latent_size

    def __call__(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        h = self.normalise(obs)
        (w1, b1), (w2, b2), (w3, b3) = self.layers
        out = np.tanh(np.tanh(h @ w1 + b1) @ w2 + b2) @ w3 + b3
        return out[:, : self.latent_size], np.clip(out[:, self.latent_size :], LOG_STD_MIN, LOG_STD_MAX)


class ClosedLoopDecoder(StateNetwork):
    def __init__(self, config: PriorConfig) -> None:
        super().__init__(config)
        h = config.hidden
        self.net = nn.Sequential(
            nn.Linear(config.obs_size + config.latent_size + 1 + config.action_size, h),
            nn.ReLU(),
            nn.Linear(h, h),
            nn.ReLU(),
            nn.Linear(h, config.action_size),
        )

    def forward(
        self, obs: torch.Tensor, z: torch.Tensor, progress: torch.Tensor, open_loop: torch.Tensor
    ) -> torch.Tensor:
        """(B, O) raw states, (B, Z) latents, (B,) progress k / L, (B, D) the FAVAE's actions -> (B, D) actions."""
        inputs = torch.cat([self.normalised(obs), z, progress[:, None], open_loop], dim=1)
        return open_loop + self.config.correction * torch.tanh(self.net(inputs))

    def frozen(self) -> FrozenDecoder:
        return FrozenDecoder(self)


class FrozenDecoder:
    """The decoder in numpy, float64: (B, D) actions of (B, >= O) raw states (their first O values), (B, Z) latents,
    step k and (B, D) the FAVAE's open-loop actions at step k."""

    def __init__(self, decoder: ClosedLoopDecoder) -> None:
        self.normalise, self.layers = decoder.numpy_normaliser(), _numpy_layers(decoder.net)
        self.config = decoder.config

    def __call__(self, obs: np.ndarray, z: np.ndarray, step: int, open_loop: np.ndarray) -> np.ndarray:
        h = np.concatenate(
            [
                self.normalise(obs),
                z,
                np.full((len(z), 1), step / self.config.length),
                open_loop,
            ],
            axis=1,
        )
        (w1, b1), (w2, b2), (w3, b3) = self.layers
        correction = np.maximum(np.maximum(h @ w1 + b1, 0) @ w2 + b2, 0) @ w3 + b3
        return open_loop + self.config.correction * np.tanh(correction)
