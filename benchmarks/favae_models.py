"""The one batched FAVAE against the two hand-written models it replaced: a training step's forward, loss,
backward and gradient row (what the fit's Adam steps) of K replicates, and at K = 1 a rollout's decoding.

    python benchmarks/favae_models.py [--replicates 1,5,10] [--steps 100] [--macros data/maze/macros]
                                      [--device cpu|cuda] [--against REV]

``batched``: :class:`~famarl_cli.method.favae.model.Favae`, K replicates as one model, a single FAVAE its K = 1
case. ``ensemble`` and ``single``: revision REV's ``FavaeEnsemble`` (the batched model every fit trained) and its
``Favae`` module (Conv1d and ConvTranspose1d layers, the model every other stage loaded and decoded with), read
from git (``git show REV:famarl_cli/method/favae/...``), so the comparison needs no copy of them here. All start
from the same weights and compute the same loss (checked here, at float32 tolerance, before timing). Every
replicate fits segments of one L (replicate 0's, or random segments of the same shape). One torch thread; the
median of ``--repeats`` timings of ``--steps`` steps each.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time
import types
from pathlib import Path

import numpy as np
import torch
from common import RESULTS, ROOT, command_line, record, write_result
from favae_replicates import segments_of, wait

from famarl_cli.core.errors import UsageError
from famarl_cli.core.flat_parameters import gather
from famarl_cli.method.favae.loss import replicate_loss
from famarl_cli.method.favae.model import Favae, FavaeConfig
from famarl_cli.sweep.plan import parse_values

BATCH = 64
DECODED = 16
"""Latents a rollout step decodes at once (one per environment)."""
BEFORE = "98d71ea"
"""The last revision with the two hand-written models."""


def replaced(revision: str) -> tuple[types.ModuleType, types.ModuleType]:
    """``revision``'s favae/model.py and favae/ensemble.py, imported under names of their own."""
    modules = []
    for name in ("model", "ensemble"):
        path = f"famarl_cli/method/favae/{name}.py"
        shown = subprocess.run(["git", "show", f"{revision}:{path}"], cwd=ROOT, capture_output=True, text=True)
        if shown.returncode:
            raise SystemExit(f"error: git show {revision}:{path}: {shown.stderr.strip()}")
        module = types.ModuleType(f"replaced_favae_{name}")
        sys.modules[module.__name__] = module  # dataclasses look their module up there
        source = shown.stdout.replace("famarl_cli.method.favae.model", "replaced_favae_model")
        exec(compile(source, f"{revision}:{path}", "exec"), module.__dict__)
        modules.append(module)
    return modules[0], modules[1]


def loss_of(reconstruction, x, mus, logvars, zs, beta, capacities, population):
    """replicate_loss of K replicates, channels last: (K, B, L, C) tensors and (K, B, z) latents."""
    return replicate_loss(reconstruction, x, mus, logvars, zs, beta, capacities, population).total


def batched_step(configs: list[FavaeConfig], device: str):
    model = Favae(configs, device, seeds=list(range(len(configs))))
    gradient = torch.empty_like(model.flat)

    def step(x, noise, weights, beta, capacities, population):
        reconstruction, *latents = model.batched(x, noise, weights)
        total = loss_of(reconstruction, x, *latents, beta, capacities, population)
        return total, gather(torch.autograd.grad(total.sum(), model.parameters()), gradient)

    return step, model


def ensemble_step(old: types.ModuleType, ensemble: types.ModuleType, config: FavaeConfig, k: int, device: str):
    models = []
    for seed in range(k):
        torch.manual_seed(seed)
        models.append(old.Favae(old.FavaeConfig(**vars(config))))
    replaced_ensemble = ensemble.FavaeEnsemble(models, device)
    gradient = torch.empty_like(replaced_ensemble.flat)

    def step(x, noise, weights, beta, capacities, population):
        reconstruction, *latents = replaced_ensemble.forward(x, noise, weights)
        total = loss_of(reconstruction, x, *latents, beta, capacities, population)
        gradients = torch.autograd.grad(total.sum(), replaced_ensemble.parameters)
        return total, torch.cat([g.reshape(k, -1) for g in gradients], dim=1, out=gradient)

    return step, models[0]


def single_step(model, device: str):
    """The replaced module's step (K = 1): encode, sample with the given noise, decode, as its fits did."""
    model = model.to(device)
    parameters = list(model.parameters())
    dims = list(model.config.latent_dims)

    def step(x, noise, weights, beta, capacities, population):
        mus, logvars = model.encode(x[0].transpose(1, 2))
        eps = torch.split(noise[0], dims, dim=1)
        zs = [mu + e * (0.5 * lv).exp() for mu, lv, e in zip(mus, logvars, eps, strict=True)]
        reconstruction = model.decode(torch.cat(zs, dim=1), list(weights[0].unbind(0)))
        batched = [[t[None] for t in ts] for ts in (mus, logvars, zs)]
        total = loss_of(reconstruction.transpose(1, 2)[None], x, *batched, beta, capacities, population)
        return total, torch.autograd.grad(total.sum(), parameters)

    return step


def inputs(segments, k: int, device: str, latent: int):
    generator = torch.Generator().manual_seed(k)
    rows = torch.stack([torch.as_tensor(segments[torch.randperm(len(segments), generator=generator)[:BATCH]])] * k)
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
    parser.add_argument("--against", default=BEFORE, help="The git revision of the replaced models.")
    parser.add_argument("--out", type=Path, default=None, help="[default: results/favae_models[_cuda].json]")
    args = parser.parse_args()
    try:
        replicates = [int(k) for k in parse_values(args.replicates)]
    except (UsageError, ValueError) as exc:
        raise SystemExit(f"error: --replicates {args.replicates!r}: {exc}") from None
    if min(replicates) < 1 or args.steps < 1 or args.repeats < 1:
        raise SystemExit("error: --replicates, --steps and --repeats must be at least 1")
    suffix = "" if args.device == "cpu" else f"_{args.device}"
    if args.device == "cuda" and not torch.cuda.is_available():
        raise SystemExit("error: --device cuda: torch sees no CUDA GPU here")
    old, ensemble = replaced(args.against)
    torch.set_num_threads(1)
    segments = segments_of(args.macros, 0)
    config = FavaeConfig(action_dim=segments.shape[2] - 2, length=segments.shape[1])
    rows = []
    for k in replicates:
        batch = inputs(segments, k, args.device, config.latent_size)
        steps = {"batched": batched_step([config] * k, args.device)[0]}
        steps["ensemble"], first = ensemble_step(old, ensemble, config, k, args.device)
        if k == 1:
            steps["single"] = single_step(first, args.device)
        totals = {name: step(*batch)[0] for name, step in steps.items()}
        for name, total in totals.items():
            torch.testing.assert_close(total, totals["batched"], rtol=1e-4, atol=1e-3, msg=name)
        times = {name: timed(step, batch, args.steps, args.repeats, args.device) for name, step in steps.items()}
        row = {"replicates": k, **{f"{name}_ms": 1000 * t for name, t in times.items()}}
        print(
            f"K {k:3d}: batched {1000 * times['batched']:7.2f} ms a step, "
            + ", ".join(
                f"{n} {1000 * t:7.2f} ms ({times['batched'] / t:.2f}x)" for n, t in times.items() if n != "batched"
            )
        )
        if k == 1 and args.device == "cpu":  # decoding runs where the rollouts run
            _, model = batched_step([config], args.device)
            latents = np.random.default_rng(0).standard_normal((DECODED, config.latent_size)).astype(np.float32)
            decodes = {"batched": model, "single": first.eval()}
            for a, b in zip(*(m.decode_macro_actions(latents) for m in decodes.values()), strict=True):
                np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-4)
            decoding = {
                name: timed(lambda m=m, z=latents: m.decode_macro_actions(z), (), args.steps, args.repeats, args.device)
                for name, m in decodes.items()
            }
            row.update({f"{name}_decode_ms": 1000 * t for name, t in decoding.items()})
            print(
                f"      decoding {DECODED} latents: batched {1000 * decoding['batched']:.3f} ms, single "
                f"{1000 * decoding['single']:.3f} ms ({decoding['batched'] / decoding['single']:.2f}x)"
            )
        rows.append(row)
    write_result(
        args.out or RESULTS / f"favae_models{suffix}.json",
        {"device": args.device, "against": args.against, "rows": rows, "length": config.length},
    )
    where = "" if args.device == "cpu" else f" on {args.device}"

    def measured(row: dict) -> str:
        text = f"{row['batched_ms']:.2f} vs {row['ensemble_ms']:.2f} ms ({row['batched_ms'] / row['ensemble_ms']:.2f}x)"
        if "single_ms" in row:
            text += f", single {row['single_ms']:.2f} ms ({row['batched_ms'] / row['single_ms']:.2f}x)"
        if "single_decode_ms" in row:
            decode = row["batched_decode_ms"] / row["single_decode_ms"]
            text += f", decoding {row['batched_decode_ms']:.3f} vs {row['single_decode_ms']:.3f} ms ({decode:.2f}x)"
        return text

    def numbers(row: dict) -> dict[str, float]:
        k = f"k{row['replicates']}"
        kept = {name.removesuffix("_ms"): ms for name, ms in row.items() if name.endswith("_ms")}
        return {
            **{f"{k}_{name}": ms for name, ms in kept.items()},
            f"{k}_over_ensemble": row["batched_ms"] / row["ensemble_ms"],
        }

    values = {name: v for row in rows for name, v in numbers(row).items()}
    record(
        f"favae_models{suffix}",
        what=f"a FAVAE step's forward, loss and backward of K replicates{where}, the one batched model against the "
        f"hand-written ensemble it replaced ({args.against}), at K = 1 also against that revision's single module "
        f"(and its decoding of {DECODED} latents), K = " + " / ".join(str(r["replicates"]) for r in rows),
        command=command_line(__file__, parser, args, shown=("macros",)),
        measured=" / ".join(map(measured, rows)),
        target="the one definition at most 1.2x slower than what it replaced",
        values=values,
        unit={name: "x" if name.endswith("_over_ensemble") else "ms" for name in values},
        better="lower",
    )


if __name__ == "__main__":
    main()
