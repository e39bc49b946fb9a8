"""K FAVAEs as one batched model: each replicate's parameters stacked along a leading replicate axis, every layer one
batched matmul over the replicates (``torch.bmm``), so K fits pay one program's per-op overhead instead of K
(PureJaxRL's idea; the "model ensembling" of ``torch.func``, written out as batched matmuls, which measured as fast
as grouped convolutions per layer and need no layout changes between the convolutions and the heads).

The replicates are independent models: no parameter, batch statistic or gradient is shared, and a replicate
computes what its own :class:`~famarl_cli.method.favae.model.Favae` computes (tests/test_favae_ensemble.py checks
outputs and gradients against the single model). Replicates may differ in L (each replicate's longest segment): the
maps are padded to the largest L and masked, so a shorter replicate's maps are zero past its own length, the
weights that read or write there are zero and get zero gradient, and its layers see exactly its own maps.

Layout: channels last, maps (K, B, T, C). A convolution (kernel 3, stride 2, padding 1) is the map's windows
(stacked from its even and odd steps) and one bmm; a transposed convolution (kernel 4, stride 2, padding 1) is one
bmm to the four taps and two shifted adds, ``even[m] = x[m] W1 + x[m-1] W3``, ``odd[m] = x[m+1] W0 + x[m] W2``.
All parameters live in one flat (K, P) tensor, a row per replicate, so the optimiser's step is one fused pass per
replicate whatever the number of layers (:class:`~famarl_cli.core.replicate_adam.ReplicateAdam`).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass, replace

import torch
from torch.nn import functional

from famarl_cli.method.favae import Decoder, Head, Join
from famarl_cli.method.favae.model import Favae, FavaeConfig, posterior_logvar


@dataclass(frozen=True)
class _Slot:
    """Where one of a Favae's tensors lives in the flat parameters, and how its layout changes on the way."""

    name: str
    """The Favae's state-dict key."""
    shape: tuple[int, ...]
    """Its batched shape per replicate (without the replicate axis)."""
    to_batched: Callable[[torch.Tensor, int], torch.Tensor]
    """(the Favae's tensor, that replicate's map steps) -> the batched layout, padded to ``shape``."""
    to_single: Callable[[torch.Tensor, int], torch.Tensor]
    """The inverse: the batched layout cropped to the replicate's map steps, in the Favae's layout."""
    steps: int | None = None
    """The depth (0-based) whose map steps this tensor's layout depends on; None: it depends on none."""


def _pad_steps(tensor: torch.Tensor, dim: int, steps: int) -> torch.Tensor:
    """``tensor`` zero-padded along ``dim`` to ``steps``."""
    missing = steps - tensor.shape[dim]
    if missing == 0:
        return tensor
    shape = list(tensor.shape)
    shape[dim] = missing
    return torch.cat([tensor, tensor.new_zeros(shape)], dim=dim)


def _bias_slot(name: str, outputs: int) -> _Slot:
    """A bias (out,) -> (1, out), added to every row of x @ W."""
    return _Slot(f"{name}.bias", (1, outputs), lambda b, _: b[None], lambda b, _: b[0])


def _linear_slots(name: str, inputs: int, outputs: int) -> list[_Slot]:
    """nn.Linear: weight (out, in) -> (in, out) for x @ W; bias -> (1, out)."""
    return [
        _Slot(f"{name}.weight", (inputs, outputs), lambda w, _: w.T, lambda w, _: w.T),
        _bias_slot(name, outputs),
    ]


def _from_map_slots(name: str, channels: int, steps: int, outputs: int, depth: int) -> list[_Slot]:
    """nn.Linear reading a flattened (C, S) map (index c * S + t): weight rows reordered to the channels-last
    index t * C + c and padded to the largest S."""

    def batched(w, s):
        return _pad_steps(w.reshape(outputs, channels, s).permute(2, 1, 0), 0, steps).reshape(steps * channels, -1)

    def single(w, s):
        return w.reshape(steps, channels, outputs)[:s].permute(2, 1, 0).reshape(outputs, channels * s)

    return [
        _Slot(f"{name}.weight", (steps * channels, outputs), batched, single, depth),
        _bias_slot(name, outputs),
    ]


def _to_map_slots(name: str, inputs: int, channels: int, steps: int, depth: int) -> list[_Slot]:
    """nn.Linear writing a (C, S) map (index c * S + t): columns reordered to t * C + c and padded."""

    def batched(w, s):
        return _pad_steps(w.reshape(channels, s, inputs).permute(2, 1, 0), 1, steps).reshape(inputs, -1)

    def single(w, s):
        return w.reshape(inputs, steps, channels)[:, :s].permute(2, 1, 0).reshape(channels * s, inputs)

    def batched_bias(b, s):
        return _pad_steps(b.reshape(channels, s).T, 0, steps).reshape(1, -1)

    def single_bias(b, s):
        return b.reshape(steps, channels)[:s].T.reshape(-1)

    return [
        _Slot(f"{name}.weight", (inputs, steps * channels), batched, single, depth),
        _Slot(f"{name}.bias", (1, steps * channels), batched_bias, single_bias, depth),
    ]


def _conv_slots(name: str, inputs: int, outputs: int) -> list[_Slot]:
    """nn.Conv1d, kernel 3: weight (out, in, 3) -> (in * 3, out), index c * 3 + j as the windows."""
    return [
        _Slot(
            f"{name}.weight",
            (inputs * 3, outputs),
            lambda w, _: w.permute(1, 2, 0).reshape(inputs * 3, outputs),
            lambda w, _: w.reshape(inputs, 3, outputs).permute(2, 0, 1),
        ),
        _bias_slot(name, outputs),
    ]


def _deconv_slots(name: str, inputs: int, outputs: int) -> list[_Slot]:
    """nn.ConvTranspose1d, kernel 4: weight (in, out, 4) -> (in, 4 * out), index k * out + o."""
    return [
        _Slot(
            f"{name}.weight",
            (inputs, 4 * outputs),
            lambda w, _: w.permute(0, 2, 1).reshape(inputs, 4 * outputs),
            lambda w, _: w.reshape(inputs, 4, outputs).permute(0, 2, 1),
        ),
        _bias_slot(name, outputs),
    ]


def _slots(config: FavaeConfig) -> list[_Slot]:
    """Every tensor of a Favae of ``config`` (its largest L), in the order they sit in the flat parameters."""
    widths = [config.action_dim + 2, *config.channels]
    steps = [config.length // 2 ** (depth + 1) for depth in range(config.ladders)]
    slots = []
    for depth, (a, b) in enumerate(zip(widths[:-1], widths[1:], strict=True)):
        slots += _conv_slots(f"convs.{depth}.0", a, b)
    for depth, (c, s, z) in enumerate(zip(config.channels, steps, config.latent_dims, strict=True)):
        if config.head == Head.POOL:
            slots += _linear_slots(f"heads.{depth}.0", c, config.hidden)
        else:
            slots += _from_map_slots(f"heads.{depth}.0", c, s, config.hidden, depth)
        slots += _linear_slots(f"heads.{depth}.2", config.hidden, 2 * z)
    top, *rest = reversed(config.latent_dims)
    deepest = config.ladders - 1
    if config.decoder == Decoder.LADDER:
        slots += _linear_slots("top.0", top, config.hidden)
        slots += _to_map_slots("top.2", config.hidden, config.channels[-1], steps[-1], deepest)
        for depth, z in enumerate(config.latent_dims[:-1]):
            if config.join == Join.LINEAR:
                slots += _to_map_slots(f"joins.{depth}", z, config.channels[depth], steps[depth], depth)
            else:
                slots += _linear_slots(f"joins.{depth}.0", z, config.hidden)
                slots += _to_map_slots(f"joins.{depth}.2", config.hidden, config.channels[depth], steps[depth], depth)
    else:
        slots += _linear_slots("top_down.0.0", top, config.hidden)
        slots += _linear_slots("top_down.0.2", config.hidden, config.hidden)
        for i, z in enumerate(rest, start=1):
            slots += _linear_slots(f"top_down.{i}.0", config.hidden + z, config.hidden)
            slots += _linear_slots(f"top_down.{i}.2", config.hidden, config.hidden)
        slots += _to_map_slots("to_features", config.hidden, config.channels[-1], steps[-1], deepest)
    back = list(reversed(widths))
    for i, (a, b) in enumerate(zip(back[:-1], back[1:], strict=True)):
        slots += _deconv_slots(f"deconvs.{i}", a, b)
    return slots


def _shifted(h: torch.Tensor, by: int) -> torch.Tensor:
    """(K, B, S, C) maps moved ``by`` steps along S (1: ``out[m] = h[m - 1]``), zero where nothing moves in. A roll
    and a mask instead of a slice and a pad: their backward passes copy, where a slice's fills a zero map first."""
    steps = h.shape[2]
    place = torch.arange(steps, device=h.device)
    kept = place >= by if by > 0 else place < steps + by
    return torch.roll(h, by, dims=2) * kept.to(h.dtype)[:, None]


def _same_but_length(configs: list[FavaeConfig]) -> FavaeConfig:
    """The config of the padded model: the replicates' shared config with the largest L."""
    longest = max(c.length for c in configs)
    padded = {replace(c, length=longest) for c in configs}
    if len(padded) > 1:
        raise ValueError("replicates batched together must have the same FAVAE config but for L")
    return padded.pop()


class FavaeEnsemble:
    """K Favaes (all of one config but for L) as one batched model on ``device``; :meth:`models` gives them back
    (on the CPU)."""

    def __init__(self, models: list[Favae], device: torch.device | str = "cpu") -> None:
        if not models:
            raise ValueError("an ensemble needs at least one model")
        self.configs = [m.config for m in models]
        self.config = _same_but_length(self.configs)
        self.slots = _slots(self.config)
        self.replicates = len(models)
        depths = range(-1, self.config.ladders)
        # map steps per depth (-1: the output), largest and each replicate's
        self.steps = {d: self.config.length // 2 ** (d + 1) for d in depths}
        self.own_steps = {d: [c.length // 2 ** (d + 1) for c in self.configs] for d in depths}
        self.sizes = [int(torch.Size(slot.shape).numel()) for slot in self.slots]
        # filled on the CPU and moved in one copy (a copy per tensor and replicate costs K x 32 transfers on a GPU)
        flat = torch.zeros(self.replicates, sum(self.sizes))
        states = [model.state_dict() for model in models]
        for slot, view in zip(self.slots, self._views(flat), strict=True):
            for k, state in enumerate(states):
                view[k] = slot.to_batched(state[slot.name].detach(), self._own(slot, k))
        self.flat = flat.to(device)
        self.parameters: list[torch.Tensor] = [view.requires_grad_() for view in self._views(self.flat)]
        self.named = dict(zip((s.name for s in self.slots), self.parameters, strict=True))
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

    def _own(self, slot: _Slot, k: int) -> int:
        return self.own_steps[slot.steps][k] if slot.steps is not None else 0

    def _views(self, flat: torch.Tensor) -> list[torch.Tensor]:
        """Each slot's (K, *shape) view of a flat (K, P) tensor."""
        offsets = [0, *itertools.accumulate(self.sizes)]
        return [
            flat[:, a:b].view(self.replicates, *slot.shape)
            for slot, a, b in zip(self.slots, offsets[:-1], offsets[1:], strict=True)
        ]

    @property
    def step_mask(self) -> torch.Tensor | None:
        """(K, L): 1 on each replicate's own steps of the output; None where all have the largest L."""
        mask = self.masks[-1]
        return None if mask is None else mask[:, 0, :, 0]

    def models(self) -> list[Favae]:
        """Each replicate as its own Favae (in eval mode, on the CPU), with the ensemble's current weights (read
        from the device in one copy)."""
        views = self._views(self.flat.detach().cpu())
        result = []
        for k, config in enumerate(self.configs):
            model = Favae(config)
            state = {
                slot.name: slot.to_single(view[k], self._own(slot, k)).contiguous()
                for slot, view in zip(self.slots, views, strict=True)
            }
            model.load_state_dict(state)
            result.append(model.eval())
        return result

    # -- the forward pass, channels last -----------------------------------------------------------------------

    def _linear(self, name: str, x: torch.Tensor) -> torch.Tensor:
        return torch.baddbmm(self.named[f"{name}.bias"], x, self.named[f"{name}.weight"])

    def _mlp(self, name: str, x: torch.Tensor) -> torch.Tensor:
        return self._linear(f"{name}.2", torch.relu(self._linear(f"{name}.0", x)))

    def _mask(self, h: torch.Tensor, depth: int) -> torch.Tensor:
        mask = self.masks[depth]
        return h if mask is None else h * mask

    def _conv(self, depth: int, h: torch.Tensor) -> torch.Tensor:
        """Conv1d(kernel 3, stride 2, padding 1) + ReLU on (K, B, T, C) maps -> (K, B, T / 2, C')."""
        k, b, t, c = h.shape
        # window m is x[2m - 1], x[2m], x[2m + 1]: the odd steps shifted, the even and the odd steps of a free view
        # (unfold's backward costs about as much as the matmul's here; this one's only copies, to the same sums)
        pairs = h.view(k, b, t // 2, 2, c)
        even, odd = pairs[:, :, :, 0], pairs[:, :, :, 1]
        windows = torch.stack([functional.pad(odd, (0, 0, 1, 0))[:, :, :-1], even, odd], dim=-1)  # c * 3 + j
        out = self._linear(f"convs.{depth}.0", windows.reshape(k, b * (t // 2), c * 3))
        return self._mask(torch.relu(out).view(k, b, t // 2, -1), depth)

    def _deconv(self, i: int, h: torch.Tensor) -> torch.Tensor:
        """ConvTranspose1d(kernel 4, stride 2, padding 1) on (K, B, S, C) maps -> (K, B, 2 S, C')."""
        k, b, s, c = h.shape
        weight = self.named[f"deconvs.{i}.weight"]
        t0, t1, t2, t3 = torch.bmm(h.reshape(k, b * s, c), weight).view(k, b, s, 4, -1).unbind(3)
        out = torch.stack([t1 + _shifted(t3, 1), t2 + _shifted(t0, -1)], dim=3).view(k, b, 2 * s, -1)
        return out + self.named[f"deconvs.{i}.bias"][:, None]

    def _to_map(self, name: str, x: torch.Tensor, depth: int) -> torch.Tensor:
        k, b, _ = x.shape
        return self._mask(self._linear(name, x).view(k, b, self.steps[depth], -1), depth)

    def encode(self, x: torch.Tensor) -> tuple[list[torch.Tensor], list[torch.Tensor]]:
        """(K, B, L, D + 2) inputs -> per ladder, (K, B, z) posterior means and log-variances."""
        mus, logvars = [], []
        h = x
        for depth in range(self.config.ladders):
            h = self._conv(depth, h)
            k, b, t, c = h.shape
            if self.config.head == Head.POOL:
                features = h.sum(dim=2) / self.pool_steps[depth]
            else:
                features = h.reshape(k, b, t * c)
            mu, logvar = self._mlp(f"heads.{depth}", features).chunk(2, dim=2)
            mus.append(mu)
            logvars.append(posterior_logvar(logvar))
        return mus, logvars

    def decode(self, parts: list[torch.Tensor]) -> torch.Tensor:
        """Per ladder (K, B, z) latents -> (K, B, L, D + 2) reconstructions, zero past each replicate's L."""
        deepest = self.config.ladders - 1
        if self.config.decoder == Decoder.LADDER:
            h = self._to_map("top.2", torch.relu(self._linear("top.0", parts[-1])), deepest)
            for i, depth in enumerate(range(deepest - 1, -2, -1)):
                h = self._deconv(i, torch.relu(h))
                if depth >= 0:
                    k, b, s, _ = h.shape
                    joined = (
                        self._linear(f"joins.{depth}", parts[depth])
                        if self.config.join == Join.LINEAR
                        else self._mlp(f"joins.{depth}", parts[depth])
                    )
                    h = h + joined.view(k, b, s, -1)
                h = self._mask(h, depth)
            return h
        t = self._mlp("top_down.0", parts[-1])
        for i, part in enumerate(reversed(parts[:-1]), start=1):
            t = self._mlp(f"top_down.{i}", torch.cat([torch.relu(t), part], dim=2))
        h = self._to_map("to_features", torch.relu(t), deepest)
        for i, depth in enumerate(range(deepest - 1, -2, -1)):
            h = self._deconv(i, h)
            h = self._mask(torch.relu(h) if depth >= 0 else h, depth)  # no ReLU on the output
        return h

    def forward(
        self, x: torch.Tensor, noise: torch.Tensor | None, weights: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, list[torch.Tensor], list[torch.Tensor], list[torch.Tensor]]:
        """(K, B, L, D + 2) inputs -> reconstructions (K, B, L, D + 2) and per ladder the posteriors' means,
        log-variances and the latents decoded. ``noise`` (K, B, latent_size) samples z = mu + noise * sigma (None:
        decode the means); ``weights`` (K, ladders) scale each ladder's latent (progressive training)."""
        mus, logvars = self.encode(x)
        if noise is None:
            samples = list(mus)
        else:
            eps = torch.split(noise, list(self.config.latent_dims), dim=2)
            samples = [mu + e * (0.5 * lv).exp() for mu, lv, e in zip(mus, logvars, eps, strict=True)]
        parts = samples
        if weights is not None:
            parts = [part * weights[:, ladder, None, None] for ladder, part in enumerate(samples)]
        return self.decode(parts), mus, logvars, samples
