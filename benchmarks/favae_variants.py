"""FAVAE designs against each other on the default pipeline's segments: which ladder carries what, and at what cost.

    dvc repro                                   # data/maze/macros/seed*/segments.h5 and their C_last pre-runs
    python benchmarks/favae_variants.py [--seeds 0-2] [--variants baseline,pool,deepest,pool-deepest]

Per variant and seed, a FAVAE is fitted at the pipeline's settings (beta 50, 1500 epochs, 3 ladders x 2 latents)
on replicate S's segments and scored: MIG with its bootstrap interval, reconstruction MSE, length accuracy, KL per
ladder, and the traversal effect of each ladder (the largest effect among its variables, m; values -3,-1,1,3).

- ``baseline``: the design on main: every head flattens its whole feature map; C per ladder from the pre-run.
- ``pool``: every head reads its features' mean over time, so a ladder sees only its receptive field, averaged.
- ``deepest``: the pre-run's total capacity goes to the deepest ladder, C = (0, 0, sum C_last), as the FAVAE
  authors' tuned capacities for 2D Reaching (0, 0, 0.99) put it.
- ``pool-deepest``: both.
- ``half``: half of each shallower ladder's pre-run capacity moves to the deepest.
- ``deepest-224``, ``half-224``: the same with 4 latents in the deepest ladder.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch
from common import RESULTS, write_result

from famarl_cli.favae.checkpoint import read_calibration
from famarl_cli.favae.training import TrainingParams, allocate_capacity, calibrate, evaluate_fit, train_favae
from famarl_cli.stages import favae_setup
from famarl_cli.sweep.plan import parse_values
from famarl_cli.traversal import traverse, variables_of

VARIANTS = {
    "baseline": ("flatten", "measured", (2, 2, 2)),
    "pool": ("pool", "measured", (2, 2, 2)),
    "deepest": ("flatten", "deepest", (2, 2, 2)),
    "pool-deepest": ("pool", "deepest", (2, 2, 2)),
    "half": ("flatten", "half", (2, 2, 2)),
    "deepest-224": ("flatten", "deepest", (2, 2, 4)),
    "half-224": ("flatten", "half", (2, 2, 4)),
}
BETA, EPOCHS, VALUES = 50.0, 1500, [-3.0, -1.0, 1.0, 3.0]


def fit_variant(folder: Path, head: str, allocation: str, dims: tuple, seed: int, c_last_cache: dict) -> dict:
    segments, config = favae_setup(folder / "segments.h5", 3, 2)
    config = replace(config, head=head, latent_dims=dims)
    params = TrainingParams(epochs=EPOCHS, seed=seed)
    start = time.perf_counter()
    if head == "flatten" and dims == (2, 2, 2):
        c_last = read_calibration(folder / "favae.calibration.json", config)
    elif (head, dims, seed) in c_last_cache:
        c_last = c_last_cache[head, dims, seed]
    else:
        c_last = c_last_cache[head, dims, seed] = calibrate(segments.padded, config, params)[0]
    model, log = train_favae(segments.padded, config, BETA, allocate_capacity(c_last, allocation), params)
    scores = evaluate_fit(model, segments.padded, segments.length, segments.factors)
    effects = traverse(model, variables_of(model, None, None), VALUES).effects
    per_ladder = np.split(effects, np.cumsum(dims)[:-1])
    return {
        "seed": seed,
        "c_last": c_last,
        "mig": scores["mig"],
        "mig_interval": scores["mig_interval"],
        "mig_per_factor": scores["mig_per_factor"],
        "reconstruction_mse": scores["reconstruction_mse"],
        "length_accuracy": scores["length_accuracy"],
        "kl_per_ladder": scores["kl_per_ladder"],
        "effect_per_ladder": [float(e.max()) for e in per_ladder],
        "seconds": round(time.perf_counter() - start, 1),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", default="0-2")
    parser.add_argument("--variants", default=",".join(VARIANTS))
    parser.add_argument("--data", type=Path, default=Path("data/maze/macros"))
    parser.add_argument("--out", type=Path, default=RESULTS / "favae_variants.json")
    args = parser.parse_args()
    torch.set_num_threads(1)
    seeds = [int(s) for s in parse_values(args.seeds)]
    cache: dict = {}
    results = {}
    for name in parse_values(args.variants):
        head, allocation, dims = VARIANTS[name]
        runs = [fit_variant(args.data / f"seed{seed}", head, allocation, dims, seed, cache) for seed in seeds]
        results[name] = runs
        mean = {key: np.mean([r[key] for r in runs], axis=0) for key in ("mig", "reconstruction_mse",
                "length_accuracy", "kl_per_ladder", "effect_per_ladder")}  # fmt: skip
        migs = " ".join(f"{r['mig']:.2f}" for r in runs)
        print(
            f"{name:13s} MIG {mean['mig']:.3f} ({migs})  MSE {mean['reconstruction_mse']:.4f}  "
            f"length acc {mean['length_accuracy']:.2f}  KL/ladder {np.round(mean['kl_per_ladder'], 2)}  "
            f"effect/ladder (m) {np.round(mean['effect_per_ladder'], 2)}",
            flush=True,
        )
    write_result(args.out, {"seeds": seeds, "beta": BETA, "epochs": EPOCHS, "variants": results})


if __name__ == "__main__":
    main()
