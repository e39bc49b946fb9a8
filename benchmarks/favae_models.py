"""The batched FAVAE derived from the single one by torch.func against the hand-written ensemble: a training step's
forward, loss and backward per replicate at K replicates.

    python benchmarks/favae_models.py [--replicates 1,5,10] [--steps 100] [--macros data/maze/macros]
                                      [--device cpu|cuda]

``derived``: ``torch.func.stack_module_state`` of K :class:`~famarl_cli.method.favae.model.Favae` modules and
``vmap`` over ``functional_call`` of one (encode, sample with the given noise, decode) and of its loss, so the model
is defined once; ``ensemble``: :class:`~famarl_cli.method.favae.ensemble.FavaeEnsemble`, every layer written out as
a batched matmul. Both compute the same loss and gradients (checked here, at float32 tolerance, before timing). vmap
needs one shape for all replicates, so every replicate here fits segments of one L (replicate 0's, or random
segments of the same shape; the ensemble also batches unequal L, which vmap cannot). One torch thread; the median of
``--repeats`` timings of ``--steps`` steps each.
"""

from __future__ import annotations

import argparse
import copy
import statistics
import time
from pathlib import Path

import torch
from common import RESULTS, command_line, record, write_result
from favae_replicates import segments_of, wait
from torch import nn
from torch.func import functional_call, stack_module_state, vmap

from famarl_cli.method.favae.ensemble import FavaeEnsemble
from famarl_cli.method.favae.loss import replicate_loss
from famarl_cli.method.favae.model import Favae, FavaeConfig
from famarl_cli.sweep.plan import parse_values

BATCH = 64


class Sampled(nn.Module):
    """A Favae's forward with the sampling noise given (what the ensemble's forward takes)."""

    def __init__(self, favae: Favae) -> None:
        super().__init__()
        self.favae = favae

    def forward(self, x: torch.Tensor, noise: torch.Tensor, weights: torch.Tensor):
        mus, logvars = self.favae.encode(x)
        eps = torch.split(noise, list(self.favae.config.latent_dims), dim=1)
        zs = [mu + e * (0.5 * lv).exp() for mu, lv, e in zip(mus, logvars, eps, strict=True)]
        return self.favae.decode(torch.cat(zs, dim=1), list(weights.unbind(0))), mus, logvars, zs


def loss_of(reconstruction, x, mus, logvars, zs, beta, capacities, population):
    """replicate_loss of K replicates, channels last: (K, B, L, C) tensors and (K, B, z) latents."""
    return replicate_loss(reconstruction, x, mus, logvars, zs, beta, capacities, population).total


def derived_step(models: list[Favae], device: str):
    params, _ = stack_module_state([Sampled(m) for m in models])
    params = {name: value.detach().to(device).requires_grad_() for name, value in params.items()}
    base = Sampled(copy.deepcopy(models[0])).to("meta")

    def one(p, x, noise, weights, beta, capacities, population):
        reconstruction, mus, logvars, zs = functional_call(base, p, (x, noise, weights))
        total = loss_of(
            reconstruction.transpose(1, 2)[None],
            x.transpose(1, 2)[None],
            [m[None] for m in mus],
            [lv[None] for lv in logvars],
            [z[None] for z in zs],
            beta[None],
            capacities[None],
            population[None],
        )
        return total[0]

    batched = vmap(one)

    def step(x, noise, weights, beta, capacities, population):
        total = batched(params, x.transpose(2, 3), noise, weights, beta, capacities, population)
        return total, torch.autograd.grad(total.sum(), list(params.values()))

    return step


def ensemble_step(models: list[Favae], device: str):
    ensemble = FavaeEnsemble(models, device)

    def step(x, noise, weights, beta, capacities, population):
        reconstruction, mus, logvars, zs = ensemble.forward(x, noise, weights)
        total = loss_of(reconstruction, x, mus, logvars, zs, beta, capacities, population)
        return total, torch.autograd.grad(total.sum(), ensemble.parameters)

    return step


def inputs(segments, k: int, device: str):
    generator = torch.Generator().manual_seed(k)
    rows = torch.stack([torch.as_tensor(segments[torch.randperm(len(segments), generator=generator)[:BATCH]])] * k)
    latent = 6
    return (
        rows.to(device),
        torch.randn(k, BATCH, latent, generator=generator).to(device),
        torch.ones(k, 3, device=device),
        torch.full((k,), 50.0, device=device),
        torch.tensor([[0.5, 0.5, 3.0]] * k, device=device),
        torch.full((k,), float(len(segments)), device=device),
    )


def timed(step, args, steps: int, repeats: int, device: str) -> float:
    for _ in range(5):
        step(*args)
    times = []
    for _ in range(repeats):
        wait(device)
        start = time.perf_counter()
        for _ in range(steps):
            step(*args)
        wait(device)
        times.append((time.perf_counter() - start) / steps)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--replicates", default="1,5,10")
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--macros", type=Path, default=Path("data/maze/macros"))
    parser.add_argument("--device", choices=("cpu", "cuda"), default="cpu")
    parser.add_argument("--out", type=Path, default=None, help="[default: results/favae_models[_cuda].json]")
    args = parser.parse_args()
    suffix = "" if args.device == "cpu" else f"_{args.device}"
    if args.device == "cuda" and not torch.cuda.is_available():
        raise SystemExit("error: --device cuda: torch sees no CUDA GPU here")
    torch.set_num_threads(1)
    segments = segments_of(args.macros, 0)
    config = FavaeConfig(action_dim=segments.shape[2] - 2, length=segments.shape[1])
    rows = []
    for k in map(int, parse_values(args.replicates)):
        models = []
        for seed in range(k):
            torch.manual_seed(seed)
            models.append(Favae(config))
        batch = inputs(segments, k, args.device)
        derived, written = derived_step(models, args.device), ensemble_step(models, args.device)
        (total_d, _), (total_e, _) = derived(*batch), written(*batch)
        torch.testing.assert_close(total_d, total_e, rtol=1e-4, atol=1e-3)
        times = {
            name: timed(f, batch, args.steps, args.repeats, args.device)
            for name, f in (("derived", derived), ("ensemble", written))
        }
        rows.append({"replicates": k, **{f"{n}_ms": 1000 * t for n, t in times.items()}})
        print(
            f"K {k:3d}: derived {1000 * times['derived']:7.2f} ms, ensemble {1000 * times['ensemble']:7.2f} ms a step: "
            f"derived / ensemble {times['derived'] / times['ensemble']:.2f}x"
        )
    write_result(
        args.out or RESULTS / f"favae_models{suffix}.json",
        {"device": args.device, "rows": rows, "length": config.length},
    )
    where = "" if args.device == "cpu" else f" on {args.device}"
    record(
        f"favae_models{suffix}",
        what="a FAVAE step's forward, loss and backward of K replicates, the batched model derived from the single one "
        f"(torch.func vmap over functional_call) against the hand-written ensemble{where}, K = "
        + " / ".join(str(r["replicates"]) for r in rows),
        command=command_line(__file__, parser, args, shown=("macros",)),
        measured=" / ".join(
            f"{r['derived_ms']:.2f} vs {r['ensemble_ms']:.2f} ms ({r['derived_ms'] / r['ensemble_ms']:.2f}x)"
            for r in rows
        ),
        target="derived no slower, to keep one definition",
    )


if __name__ == "__main__":
    main()
