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
from dataclasses import asdict, dataclass, field, replace

import numpy as np
import torch
from torch import nn
from torch.nn import functional

from famarl_cli.core import flat_parameters
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


@dataclass(frozen=True)
class _Tensor:
    """One of a replicate's weights or biases, in torch's layout (nn.Linear's weight (out, in), nn.Conv1d's
    (out, in, 3), nn.ConvTranspose1d's (in, out, 4)): checkpoints store them so."""

    name: str
    """Its key in the state dict."""
    shape: tuple[int, ...]
    """Its shape at the model's largest L."""
    depth: int | None = None
    """The depth whose map the tensor reads flattened or writes, channel-major (index c * S + t) along ``axis``, so
    that a replicate of a shorter L has fewer steps there; None: no map's steps."""
    axis: int = 0


def _linear_tensors(name: str, inputs: int, outputs: int, reads: int | None = None, writes: int | None = None):
    """An nn.Linear's weight and bias; ``reads`` / ``writes``: the depth whose flattened map it reads / writes."""
    weight = (
        _Tensor(f"{name}.weight", (outputs, inputs), reads, 1)
        if writes is None
        else _Tensor(f"{name}.weight", (outputs, inputs), writes, 0)
    )
    return [weight, _Tensor(f"{name}.bias", (outputs,), writes)]


def _mlp_tensors(name: str, inputs: int, hidden: int, outputs: int, writes: int | None = None) -> list[_Tensor]:
    """Linear, ReLU, Linear (state-dict keys ``name.0`` and ``name.2``, as an nn.Sequential has them)."""
    return _linear_tensors(f"{name}.0", inputs, hidden) + _linear_tensors(f"{name}.2", hidden, outputs, writes=writes)


def _tensors(config: FavaeConfig) -> list[_Tensor]:
    """A replicate's tensors at the largest L, weight then bias of each layer, in the order its initial weights are
    drawn (and in which they lie in its row)."""
    widths = [config.action_dim + 2, *config.channels]
    steps = [config.length // 2 ** (depth + 1) for depth in range(config.ladders)]
    deepest = config.ladders - 1
    tensors = []
    for depth, (a, b) in enumerate(zip(widths[:-1], widths[1:], strict=True)):
        tensors += [_Tensor(f"convs.{depth}.0.weight", (b, a, 3)), _Tensor(f"convs.{depth}.0.bias", (b,))]
    for depth, (c, s, z) in enumerate(zip(config.channels, steps, config.latent_dims, strict=True)):
        if config.head == Head.POOL:
            tensors += _linear_tensors(f"heads.{depth}.0", c, config.hidden)
        else:
            tensors += _linear_tensors(f"heads.{depth}.0", c * s, config.hidden, reads=depth)
        tensors += _linear_tensors(f"heads.{depth}.2", config.hidden, 2 * z)
    top, *rest = reversed(config.latent_dims)
    if config.decoder == Decoder.LADDER:
        tensors += _mlp_tensors("top", top, config.hidden, config.channels[-1] * steps[-1], writes=deepest)
        # ladder l < deepest joins the path as a projected map at depth l
        for depth, (z, c, s) in enumerate(zip(config.latent_dims[:-1], config.channels[:-1], steps[:-1], strict=True)):
            if config.join == Join.LINEAR:
                tensors += _linear_tensors(f"joins.{depth}", z, c * s, writes=depth)
            else:
                tensors += _mlp_tensors(f"joins.{depth}", z, config.hidden, c * s, writes=depth)
    else:
        # top-down MLPs: the deepest ladder starts alone; each shallower one joins the path by concatenation
        tensors += _mlp_tensors("top_down.0", top, config.hidden, config.hidden)
        for i, z in enumerate(rest, start=1):
            tensors += _mlp_tensors(f"top_down.{i}", config.hidden + z, config.hidden, config.hidden)
        tensors += _linear_tensors("to_features", config.hidden, config.channels[-1] * steps[-1], writes=deepest)
    back = list(reversed(widths))
    for i, (a, b) in enumerate(zip(back[:-1], back[1:], strict=True)):
        tensors += [_Tensor(f"deconvs.{i}.weight", (a, b, 4)), _Tensor(f"deconvs.{i}.bias", (b,))]
    return tensors


def _shifted(h: torch.Tensor, by: int) -> torch.Tensor:
    """(K, B, S, C) maps moved ``by`` steps along S (1: ``out[m] = h[m - 1]``), zero where nothing moves in. A roll
    and a mask instead of a slice and a pad: their backward passes copy, where a slice's fills a zero map first."""
    steps = h.shape[2]
    place = torch.arange(steps, device=h.device)
    kept = place >= by if by > 0 else place < steps + by
    return torch.roll(h, by, dims=2) * kept.to(h.dtype)[:, None]


class Favae:
    """K FAVAEs of one config but for L (``configs``; one config: K = 1) as one batched model on ``device``, and a
    single FAVAE as its K = 1 case: every layer is one batched matmul over the replicates (``torch.bmm``), so K fits
    pay one program's per-op overhead instead of K (PureJaxRL's idea).

    The replicates are independent: no parameter or gradient is shared, and a replicate computes what it computes
    alone (tests/test_favae_ensemble.py). All parameters live in one flat (K, P) tensor, :attr:`flat`, a row per
    replicate (what :class:`~famarl_cli.core.replicate_adam.ReplicateAdam` steps), each a (K, *shape) view of it in
    torch's layout (:attr:`named`, keyed as a checkpoint's state dict). Replicates may differ in L (each
    replicate's longest segment): the maps are padded to the largest L and masked, so a shorter replicate's maps
    are zero past its own length, the weights that read or write there are zero and get zero gradient, and its
    layers see exactly its own maps.

    Replicate k's initial weights are drawn, on the CPU, as torch's layers draw theirs, after
    ``torch.manual_seed(seeds[k])`` (without ``seeds``, one after the other from the global generator).

    Layout: channels last, maps (K, B, T, C). A convolution (kernel 3, stride 2, padding 1) is the map's windows
    (stacked from its even and odd steps) and one bmm; a transposed convolution (kernel 4, stride 2, padding 1) is
    one bmm to the four taps and two shifted adds, ``even[m] = x[m] W1 + x[m-1] W3``, ``odd[m] = x[m+1] W0 + x[m]
    W2``. :meth:`batched` is the K replicates' forward; :meth:`encode`, :meth:`decode`, :meth:`__call__` and
    :meth:`decode_macro_actions` are a single FAVAE's, on (B, D + 2, L) inputs.
    """

    def __init__(
        self,
        configs: FavaeConfig | list[FavaeConfig],
        device: torch.device | str = "cpu",
        seeds: list[int] | None = None,
    ) -> None:
        self.configs = [configs] if isinstance(configs, FavaeConfig) else list(configs)
        if not self.configs:
            raise ValueError("a batched FAVAE needs at least one replicate")
        longest = max(c.length for c in self.configs)
        shared = {replace(c, length=longest) for c in self.configs}
        if len(shared) > 1:
            raise ValueError("replicates batched together must have the same FAVAE config but for L")
        self.config = shared.pop()
        """The replicates' config, at the largest L."""
        self.replicates = len(self.configs)
        self.tensors = _tensors(self.config)
        self.shapes = {t.name: t.shape for t in self.tensors}
        depths = range(-1, self.config.ladders)
        # map steps per depth (-1: the output), largest and each replicate's
        self.steps = {d: longest // 2 ** (d + 1) for d in depths}
        self.own_steps = {d: [c.length // 2 ** (d + 1) for c in self.configs] for d in depths}
        flat = torch.zeros(self.replicates, flat_parameters.size(self.shapes))
        named = flat_parameters.views(flat, self.shapes)
        for k in range(self.replicates):
            if seeds is not None:
                torch.manual_seed(seeds[k])
            self._initialise(named, k)
        self.flat = flat.to(device)
        """(K, P): row k is replicate k's parameters."""
        self.named = {n: v.requires_grad_() for n, v in flat_parameters.views(self.flat, self.shapes).items()}
        """Each tensor's (K, *shape) view of :attr:`flat`: the leaves autograd differentiates."""
        self.masks = {
            d: None
            if len(set(self.own_steps[d])) == 1
            else (torch.arange(self.steps[d])[None, :] < torch.tensor(self.own_steps[d])[:, None])
            .float()
            .to(device)[:, None, :, None]
            for d in depths
        }
        """Per depth, (K, 1, T, 1): 1 where a replicate's map has a step; None where every replicate has all."""
        self.pool_steps = [
            torch.tensor(self.own_steps[d], dtype=torch.float32).to(device)[:, None, None]
            for d in range(self.config.ladders)
        ]
        """Per depth, (K, 1, 1): each replicate's own map steps, what a pooled head's mean divides by (made here, since
        a step that copies from the host cannot be a CUDA graph)."""

    # -- each replicate's own tensors ---------------------------------------------------------------------------

    def _own(self, view: torch.Tensor, tensor: _Tensor, k: int) -> torch.Tensor:
        """Replicate k's part of a tensor's (K, *shape) view: all of it, but where the tensor holds a map's steps only
        the replicate's own (that axis split in two, channels and steps)."""
        if tensor.depth is None:
            return view[k]
        own = self.own_steps[tensor.depth][k]
        return view[k].unflatten(tensor.axis, (-1, self.steps[tensor.depth])).narrow(tensor.axis + 1, 0, own)

    def _own_shape(self, tensor: _Tensor, k: int) -> tuple[int, ...]:
        """The tensor's shape in replicate k's own model (of its own L)."""
        if tensor.depth is None:
            return tensor.shape
        shape = list(tensor.shape)
        shape[tensor.axis] = shape[tensor.axis] // self.steps[tensor.depth] * self.own_steps[tensor.depth][k]
        return tuple(shape)

    def _initialise(self, named: dict[str, torch.Tensor], k: int) -> None:
        """Draw replicate k's initial weights as torch's Linear, Conv1d and ConvTranspose1d draw theirs: weight and
        bias uniform in +-1 / sqrt(fan_in) (kaiming_uniform_ with a = sqrt(5)), drawn in the replicate's own shapes,
        layer by layer."""
        for weight, bias in zip(self.tensors[::2], self.tensors[1::2], strict=True):
            shape = self._own_shape(weight, k)
            drawn = nn.init.kaiming_uniform_(torch.empty(shape), a=math.sqrt(5))
            bound = 1 / math.sqrt(math.prod(shape[1:]))
            for tensor, value in (
                (weight, drawn),
                (bias, torch.empty(self._own_shape(bias, k)).uniform_(-bound, bound)),
            ):
                own = self._own(named[tensor.name], tensor, k)
                own.copy_(value.view(own.shape))

    def state_dict(self, replicate: int = 0) -> dict[str, torch.Tensor]:
        """Replicate ``replicate``'s tensors, each its own copy in its own model's shapes (what a checkpoint stores)."""
        return {
            t.name: self._own(view.detach(), t, replicate).reshape(self._own_shape(t, replicate)).clone()
            for t, view in zip(self.tensors, self.named.values(), strict=True)
        }

    @torch.no_grad()
    def load_state_dict(self, state: dict[str, torch.Tensor], replicate: int = 0) -> None:
        """Set replicate ``replicate``'s tensors from :meth:`state_dict`'s (a ValueError names what does not fit)."""
        if set(state) != set(self.shapes):
            missing, unexpected = sorted(set(self.shapes) - set(state)), sorted(set(state) - set(self.shapes))
            raise ValueError(f"missing keys {missing}, unexpected keys {unexpected}")
        for t in self.tensors:
            shape = self._own_shape(t, replicate)
            if tuple(state[t.name].shape) != shape:
                raise ValueError(f"{t.name} is {tuple(state[t.name].shape)}, this model's is {shape}")
            own = self._own(self.named[t.name], t, replicate)
            own.copy_(state[t.name].view(own.shape))

    def models(self) -> list[Favae]:
        """Each replicate as a FAVAE of its own (K = 1, on the CPU), read from the device in one copy."""
        here = flat_parameters.views(self.flat.detach().cpu(), self.shapes)
        result = []
        for k, config in enumerate(self.configs):
            model = Favae(config)
            model.load_state_dict(
                {t.name: self._own(here[t.name], t, k).reshape(self._own_shape(t, k)) for t in self.tensors}
            )
            result.append(model)
        return result

    def parameters(self) -> list[torch.Tensor]:
        return list(self.named.values())

    @property
    def step_mask(self) -> torch.Tensor | None:
        """(K, L): 1 on each replicate's own steps of the output; None where all have the largest L."""
        mask = self.masks[-1]
        return None if mask is None else mask[:, 0, :, 0]

    # -- the forward pass, channels last ------------------------------------------------------------------------

    def _linear(self, name: str, x: torch.Tensor) -> torch.Tensor:
        """A layer's x W^T + b on (K, B, in) inputs; a convolution's weight reads its windows (index c * 3 + j)."""
        weight = self.named[f"{name}.weight"].flatten(2)
        return torch.baddbmm(self.named[f"{name}.bias"][:, None], x, weight.transpose(1, 2))

    def _mlp(self, name: str, x: torch.Tensor) -> torch.Tensor:
        return self._linear(f"{name}.2", torch.relu(self._linear(f"{name}.0", x)))

    def _mask(self, h: torch.Tensor, depth: int) -> torch.Tensor:
        mask = self.masks[depth]
        return h if mask is None else h * mask

    def _map(self, values: torch.Tensor, depth: int) -> torch.Tensor:
        """(K, B, C * S) values, channel-major as torch flattens a (C, S) map, as a (K, B, S, C) map (contiguous: the
        ReLUs and adds that follow run several times slower on a transposed view)."""
        k, b, _ = values.shape
        return values.view(k, b, -1, self.steps[depth]).transpose(2, 3).contiguous()

    def _conv(self, depth: int, h: torch.Tensor) -> torch.Tensor:
        """Conv1d(kernel 3, stride 2, padding 1) + ReLU on (K, B, T, C) maps -> (K, B, T / 2, C')."""
        k, b, t, c = h.shape
        # window m is x[2m - 1], x[2m], x[2m + 1]: the odd steps shifted, the even and the odd steps of a free view
        # (unfold's backward costs about as much as the matmul's here; this one's only copies, to the same sums)
        pairs = h.reshape(k, b, t // 2, 2, c)
        even, odd = pairs[:, :, :, 0], pairs[:, :, :, 1]
        windows = torch.stack([functional.pad(odd, (0, 0, 1, 0))[:, :, :-1], even, odd], dim=-1)  # c * 3 + j
        out = self._linear(f"convs.{depth}.0", windows.reshape(k, b * (t // 2), c * 3))
        return self._mask(torch.relu(out).view(k, b, t // 2, -1), depth)

    def _deconv(self, i: int, h: torch.Tensor) -> torch.Tensor:
        """ConvTranspose1d(kernel 4, stride 2, padding 1) on (K, B, S, C) maps -> (K, B, 2 S, C')."""
        k, b, s, c = h.shape
        # (K, C, 4 * C'), index tap * C' + o: a copy of the weights, so that each tap's map is contiguous (the
        # shifts and adds below run several times slower on maps strided by the taps)
        weight = self.named[f"deconvs.{i}.weight"].transpose(2, 3).reshape(k, c, -1)
        t0, t1, t2, t3 = torch.bmm(h.reshape(k, b * s, c), weight).view(k, b, s, 4, -1).unbind(3)
        out = torch.stack([t1 + _shifted(t3, 1), t2 + _shifted(t0, -1)], dim=3).view(k, b, 2 * s, -1)
        return out + self.named[f"deconvs.{i}.bias"][:, None, None]

    def posteriors(self, x: torch.Tensor) -> tuple[list[torch.Tensor], list[torch.Tensor]]:
        """(K, B, L, D + 2) inputs -> per ladder, (K, B, z) posterior means and log-variances."""
        mus, logvars = [], []
        h = x
        for depth in range(self.config.ladders):
            h = self._conv(depth, h)
            k, b, t, c = h.shape
            if self.config.head == Head.POOL:
                features = h.sum(dim=2) / self.pool_steps[depth]
            else:
                features = h.transpose(2, 3).reshape(k, b, c * t)  # channel-major, as torch flattens (C, T)
            mu, logvar = self._mlp(f"heads.{depth}", features).chunk(2, dim=2)
            mus.append(mu)
            logvars.append(posterior_logvar(logvar))
        return mus, logvars

    def reconstruct(self, parts: list[torch.Tensor]) -> torch.Tensor:
        """Per ladder (K, B, z) latents -> (K, B, L, D + 2) reconstructions, zero past each replicate's L."""
        deepest = self.config.ladders - 1
        if self.config.decoder == Decoder.LADDER:
            h = self._mask(self._map(self._mlp("top", parts[-1]), deepest), deepest)
            for i, depth in enumerate(range(deepest - 1, -2, -1)):
                h = self._deconv(i, torch.relu(h))
                if depth >= 0:
                    joined = (
                        self._linear(f"joins.{depth}", parts[depth])
                        if self.config.join == Join.LINEAR
                        else self._mlp(f"joins.{depth}", parts[depth])
                    )
                    h = h + self._map(joined, depth)
                h = self._mask(h, depth)
            return h
        t = self._mlp("top_down.0", parts[-1])
        for i, part in enumerate(reversed(parts[:-1]), start=1):
            t = self._mlp(f"top_down.{i}", torch.cat([torch.relu(t), part], dim=2))
        h = self._mask(self._map(self._linear("to_features", torch.relu(t)), deepest), deepest)
        for i, depth in enumerate(range(deepest - 1, -2, -1)):
            h = self._deconv(i, h)
            h = self._mask(torch.relu(h) if depth >= 0 else h, depth)  # no ReLU on the output
        return h

    def batched(
        self, x: torch.Tensor, noise: torch.Tensor | None, weights: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, list[torch.Tensor], list[torch.Tensor], list[torch.Tensor]]:
        """(K, B, L, D + 2) inputs -> reconstructions (K, B, L, D + 2) and per ladder the posteriors' means,
        log-variances and the latents decoded. ``noise`` (K, B, latent_size) samples z = mu + noise * sigma (None:
        decode the means); ``weights`` (K, ladders) scale each ladder's latent (progressive training)."""
        mus, logvars = self.posteriors(x)
        if noise is None:
            samples = list(mus)
        else:
            eps = torch.split(noise, list(self.config.latent_dims), dim=2)
            samples = [mu + e * (0.5 * lv).exp() for mu, lv, e in zip(mus, logvars, eps, strict=True)]
        parts = samples
        if weights is not None:
            parts = [part * weights[:, ladder, None, None] for ladder, part in enumerate(samples)]
        return self.reconstruct(parts), mus, logvars, samples

    # -- a single FAVAE (K = 1), channels first -----------------------------------------------------------------

    def encode(self, x: torch.Tensor) -> tuple[list[torch.Tensor], list[torch.Tensor]]:
        """(B, D + 2, L) inputs -> per ladder (shallowest first), the posterior means and log-variances (B, z)."""
        mus, logvars = self.posteriors(x.transpose(1, 2)[None])
        return [mu[0] for mu in mus], [lv[0] for lv in logvars]

    def decode(self, z: torch.Tensor, weights: list[float] | None = None) -> torch.Tensor:
        """(B, latent_size) -> (B, D + 2, L). ``z`` is the ladders' latents concatenated, shallowest first;
        ``weights`` scale each ladder's part (progressive training fades ladders in with them)."""
        parts = list(torch.split(z[None], list(self.config.latent_dims), dim=2))
        if weights is not None:
            parts = [part * w for part, w in zip(parts, weights, strict=True)]
        return self.reconstruct(parts)[0].transpose(1, 2)

    def __call__(self, x: torch.Tensor, sample: bool = True, weights: list[float] | None = None) -> FavaeOutput:
        """(B, D + 2, L) inputs -> their reconstructions, each ladder's latent drawn from its posterior (``sample``)
        or its mean."""
        noise = torch.randn(1, len(x), self.config.latent_size, device=x.device) if sample else None
        scale = None if weights is None else torch.tensor([weights], dtype=x.dtype, device=x.device)
        reconstruction, mus, logvars, samples = self.batched(x.transpose(1, 2)[None], noise, scale)
        return FavaeOutput(
            reconstruction[0].transpose(1, 2), [m[0] for m in mus], [lv[0] for lv in logvars], [s[0] for s in samples]
        )

    @torch.no_grad()
    def decode_macro_actions(self, z: np.ndarray | torch.Tensor) -> tuple[np.ndarray, np.ndarray]:
        """Batch decoding for the RL stage: (B, latent_size) latents -> actions (B, L, D) and lengths (B,).

        Each macro action is cut at the first step where ``action_off`` wins the softmax (at least one step);
        actions past a macro's length are padding and must not be executed.
        """
        parts = torch.split(torch.as_tensor(z, dtype=torch.float32)[None], list(self.config.latent_dims), dim=2)
        decoded = self.reconstruct(list(parts))[0].numpy()
        return decoded[..., :-2], cut_lengths(decoded[..., -2:])
