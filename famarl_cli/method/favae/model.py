"""FAVAE: a ladder VAE over padded macro actions (Yamada et al. 2019, in the variational-ladder layout of Zhao,
Song & Ermon 2017), in 1-D.

Input ``x``: (B, D + 2, L), the actions of a macro action zero-padded to L steps plus the ``action_on`` /
``action_off`` channels (:mod:`famarl_cli.core.macro_actions`). ``L`` must be divisible by 2 ** ladders.

::

    x (D+2, L)
      └ conv s2 ─ h1 (c1, L/2) ──► flatten ─ MLP ─► mu1, logvar1 ─► z1   ladder 1: local detail
          └ conv s2 ─ h2 (c2, L/4) ──► flatten ─ MLP ─► mu2, logvar2 ─► z2   ladder 2
              └ conv s2 ─ h3 (c3, L/8) ──► flatten ─ MLP ─► mu3, logvar3 ─► z3   ladder 3: most abstract

    decoder "ladder" (the default):           decoder "shared" (before the ladder decoder):
      g3 = MLP(z3) as a map (c3, L/8)            t3 = MLP(z3); t2 = MLP([t3, z2]); t1 = MLP([t2, z1])
      g2 = deconv(g3) + W2 z2   (c2, L/4)        g = t1 as a map (c3, L/8)
      g1 = deconv(g2) + W1 z1   (c1, L/2)        3 x deconv ─► (D+2, L)
      deconv(g1) ─► (D+2, L)
    output: D action channels (linear) and 2 on/off logits per step

In the ladder decoder (VLAE's generative path: each latent joins at its own depth, projected to a feature map;
adding the projection is concatenation followed by the next layer's linear map), the network between z_l and the
output has l transposed convolutions: z1 reaches it through one layer and can only make simple, near-linear
changes, z3 through an MLP and three layers, so what shapes the whole sequence has to go deep. In the shared
decoder every latent reaches the output through the same stack; the shallowest ladder, with the finest feature map
and the largest head, takes the information first (docs/favae.md).

What each ladder sees: a feature at depth 1, 2, 3 sees 3, 7, 15 steps of the input (kernel 3, stride 2). With
``head="flatten"`` (the default) every head reads its whole feature map, so every ladder sees the whole macro
action, placed in time. With ``head="pool"`` a head reads its features' mean over time: a ladder then sees only
stretches as long as its receptive field, averaged.

``weights`` (one per ladder, in [0, 1]) scale each ladder's latent before it reaches the decoder: progressive
training (:mod:`famarl_cli.method.favae.training`) fades shallower ladders in with them, after the deepest has learned.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np
import torch
from torch import nn
from torch.nn import functional

from famarl_cli.core.macro_actions import cut_lengths
from famarl_cli.method.favae import DECODER, Decoder, Head, Join


@dataclass(frozen=True)
class FavaeConfig:
    """Everything needed to rebuild a FAVAE; stored in its checkpoint."""

    action_dim: int
    length: int
    latent_dims: tuple[int, ...] = (2, 2, 2)
    """Size of each ladder's latent, shallowest first; its length is the number of ladders."""
    channels: tuple[int, ...] = (32, 64, 64)
    """Convolution channels at each depth (one per ladder)."""
    hidden: int = 64
    head: str = "flatten"
    """What each ladder's head reads of its convolution features: ``flatten``, the whole map (every ladder sees
    the whole sequence, placed in time), or ``pool``, their mean over time (a ladder sees only what its
    receptive field sees, averaged: local detail for shallow ladders, longer stretches for deep ones)."""
    decoder: str = DECODER.value
    """How the latents reach the output: ``ladder``, each at its own depth of the transposed convolutions, or
    ``shared``, all through one MLP stack and the same convolutions (:class:`~famarl_cli.method.favae.Decoder`)."""
    join: str = Join.LINEAR.value
    """In the ladder decoder, how a shallower ladder's latent joins the path: ``linear`` or ``mlp``
    (:class:`~famarl_cli.method.favae.Join`)."""

    def __post_init__(self) -> None:
        if self.decoder not in tuple(Decoder):
            raise ValueError(f"decoder must be one of {tuple(map(str, Decoder))}, got {self.decoder!r}")
        if self.head not in tuple(Head):
            raise ValueError(f"head must be one of {tuple(map(str, Head))}, got {self.head!r}")
        if self.join not in tuple(Join):
            raise ValueError(f"join must be one of {tuple(map(str, Join))}, got {self.join!r}")
        if self.join != Join.LINEAR and self.decoder != Decoder.LADDER:
            raise ValueError(f"join {self.join!r} needs the ladder decoder: the {self.decoder} decoder has no joins")
        if len(self.latent_dims) != len(self.channels):
            raise ValueError(f"{len(self.latent_dims)} ladders need as many channel sizes, got {self.channels}")
        if self.length % 2 ** len(self.channels):
            raise ValueError(f"length {self.length} must be divisible by 2 ** ladders = {2 ** len(self.channels)}")

    @property
    def ladders(self) -> int:
        return len(self.latent_dims)

    @property
    def latent_size(self) -> int:
        return sum(self.latent_dims)

    def latent_index(self, ladder: int, index: int) -> int:
        """Position in the concatenated latent of variable (ladder, index), both counted from 1 as in the paper."""
        return sum(self.latent_dims[: ladder - 1]) + index - 1

    def to_dict(self) -> dict:
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @staticmethod
    def from_dict(values: dict) -> FavaeConfig:
        """A config as :meth:`to_dict` wrote it. One without ``decoder`` was written before the field existed, when
        every FAVAE had the shared decoder: it still loads, as that."""
        values = {"decoder": Decoder.SHARED.value, **values}
        return FavaeConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in values.items()})


@dataclass
class FavaeOutput:
    reconstruction: torch.Tensor
    """(B, D + 2, L): actions, then the on and off logits."""
    mus: list[torch.Tensor] = field(default_factory=list)
    logvars: list[torch.Tensor] = field(default_factory=list)
    samples: list[torch.Tensor] = field(default_factory=list)
    """Per ladder, the latents decoded: drawn from the posterior, or its means."""


MIN_STD = 0.1
"""The posterior's smallest standard deviation, a tenth of the prior's: a smooth floor (:func:`posterior_logvar`), not
a clamp. Latents closer than this are not macro actions the RL policy can tell apart (it searches the latent space
with a Gaussian of its own), and the information estimate's pairwise densities stay smooth: with a floor of 0.01
their gradients grew with 1 / sigma^2, and one of ten default-pipeline fits blew up late in training
(reconstruction MSE 0.28 against 0.01-0.04; docs/favae.md)."""
LOGVAR_FLOOR = 2 * math.log(MIN_STD)
LOGVAR_CEILING = 10.0
"""Log-variances above this (a std of 148 against the prior's 1) are cut: they never occur in a fit; the cut
keeps exp() finite."""
FLOOR_MARGIN = math.log(2.0)
"""A posterior variance within this (log) of the floor's, i.e. less than twice it, counts as held by the floor."""


def posterior_logvar(raw: torch.Tensor) -> torch.Tensor:
    """The encoder's raw log-variance output, floored smoothly at :data:`LOGVAR_FLOOR`: floor + softplus(raw - floor)
    is raw well above the floor and approaches the floor below it with a gradient that never dies. (A hard clamp at
    -10 let a posterior meet its capacity by growing precise: in 9 of 10 fits 38-50% of ladder 3's log-variances sat
    on the clamp, where no gradient brings them back.)"""
    return (LOGVAR_FLOOR + functional.softplus(raw - LOGVAR_FLOOR)).clamp(max=LOGVAR_CEILING)


def held_by_floor(logvar: torch.Tensor) -> torch.Tensor:
    """Where the floor holds the posterior's variance (within :data:`FLOOR_MARGIN`), elementwise."""
    return logvar < LOGVAR_FLOOR + FLOOR_MARGIN


def floor_share(logvar: torch.Tensor) -> float:
    """The share of the posteriors' variances (any shape) that the floor holds (:func:`held_by_floor`)."""
    return float(held_by_floor(logvar).float().mean())


def to_input(padded: np.ndarray) -> torch.Tensor:
    """Padded macro actions as stored, (S, L, D + 2), to the (S, D + 2, L) float tensor FAVAE reads."""
    return torch.as_tensor(np.ascontiguousarray(padded.transpose(0, 2, 1)), dtype=torch.float32)


def _mlp(inputs: int, hidden: int, outputs: int) -> nn.Sequential:
    return nn.Sequential(nn.Linear(inputs, hidden), nn.ReLU(), nn.Linear(hidden, outputs))


class Favae(nn.Module):
    def __init__(self, config: FavaeConfig) -> None:
        super().__init__()
        self.config = config
        channels_in = config.action_dim + 2
        widths = [channels_in, *config.channels]
        self.convs = nn.ModuleList(
            nn.Sequential(nn.Conv1d(a, b, kernel_size=3, stride=2, padding=1), nn.ReLU())
            for a, b in zip(widths[:-1], widths[1:], strict=True)
        )
        steps = [config.length // 2 ** (depth + 1) for depth in range(config.ladders)]
        self.maps = list(zip(config.channels, steps, strict=True))  # (channels, steps) at each depth
        pooled = config.head == Head.POOL
        self.heads = nn.ModuleList(
            _mlp(c if pooled else c * s, config.hidden, 2 * z)
            for c, s, z in zip(config.channels, steps, config.latent_dims, strict=True)
        )
        top, *rest = reversed(config.latent_dims)
        deepest = config.channels[-1] * steps[-1]
        if config.decoder == Decoder.LADDER:
            self.top = _mlp(top, config.hidden, deepest)
            # ladder l < deepest joins the path as a projected map at depth l
            self.joins = nn.ModuleList(
                nn.Linear(z, c * s) if config.join == Join.LINEAR else _mlp(z, config.hidden, c * s)
                for z, (c, s) in zip(config.latent_dims[:-1], self.maps[:-1], strict=True)
            )
        else:
            # Top-down MLPs: the deepest ladder starts alone; each shallower one joins the path by concatenation.
            self.top_down = nn.ModuleList([_mlp(top, config.hidden, config.hidden)])
            self.top_down.extend(_mlp(config.hidden + z, config.hidden, config.hidden) for z in rest)
            self.to_features = nn.Linear(config.hidden, deepest)
        back = list(reversed(widths))
        self.deconvs = nn.ModuleList(
            nn.ConvTranspose1d(a, b, kernel_size=4, stride=2, padding=1)
            for a, b in zip(back[:-1], back[1:], strict=True)
        )

    def encode(self, x: torch.Tensor) -> tuple[list[torch.Tensor], list[torch.Tensor]]:
        """Per ladder (shallowest first), the posterior means and log-variances."""
        mus, logvars = [], []
        h = x
        for conv, head in zip(self.convs, self.heads, strict=True):
            h = conv(h)
            features = h.mean(dim=2) if self.config.head == Head.POOL else h.flatten(1)
            mu, logvar = head(features).chunk(2, dim=1)
            mus.append(mu)
            logvars.append(posterior_logvar(logvar))
        return mus, logvars

    def decode(self, z: torch.Tensor, weights: list[float] | None = None) -> torch.Tensor:
        """(B, latent_size) -> (B, D + 2, L). ``z`` is the ladders' latents concatenated, shallowest first;
        ``weights`` scale each ladder's part (progressive training fades ladders in with them)."""
        parts = list(torch.split(z, list(self.config.latent_dims), dim=1))
        if weights is not None:
            parts = [part * w for part, w in zip(parts, weights, strict=True)]
        if self.config.decoder == Decoder.LADDER:
            h = self.top(parts[-1]).view(-1, *self.maps[-1])
            for depth, deconv in zip(range(self.config.ladders - 2, -2, -1), self.deconvs, strict=True):
                h = deconv(torch.relu(h))
                if depth >= 0:
                    h = h + self.joins[depth](parts[depth]).view(-1, *self.maps[depth])
            return h
        t = self.top_down[0](parts[-1])
        for layer, part in zip(self.top_down[1:], reversed(parts[:-1]), strict=True):
            t = layer(torch.cat([torch.relu(t), part], dim=1))
        h = self.to_features(torch.relu(t)).view(-1, *self.maps[-1])
        for i, deconv in enumerate(self.deconvs):
            h = deconv(h)
            if i < len(self.deconvs) - 1:
                h = torch.relu(h)
        return h

    def forward(self, x: torch.Tensor, sample: bool = True, weights: list[float] | None = None) -> FavaeOutput:
        mus, logvars = self.encode(x)
        if sample:
            zs = [mu + torch.randn_like(mu) * (0.5 * lv).exp() for mu, lv in zip(mus, logvars, strict=True)]
        else:
            zs = mus
        return FavaeOutput(self.decode(torch.cat(zs, dim=1), weights), mus, logvars, zs)

    @torch.no_grad()
    def decode_macro_actions(self, z: np.ndarray | torch.Tensor) -> tuple[np.ndarray, np.ndarray]:
        """Batch decoding for the RL stage: (B, latent_size) latents -> actions (B, L, D) and lengths (B,).

        Each macro action is cut at the first step where ``action_off`` wins the softmax (at least one step);
        actions past a macro's length are padding and must not be executed.
        """
        decoded = self.decode(torch.as_tensor(z, dtype=torch.float32)).numpy().transpose(0, 2, 1)
        return decoded[..., :-2], cut_lengths(decoded[..., -2:])

    def checkpoint_config(self) -> dict:
        return self.config.to_dict()
