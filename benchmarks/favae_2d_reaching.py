"""Our FAVAE on the FAVAE authors' own data with known factors: 2D Reaching (../shared/data/favae-2d-reaching).

    python benchmarks/favae_2d_reaching.py [--steps 100] [--betas 0.2,0.6,1,1.4] [--seeds 0-2]

The 20 sequences are imported as ``famarl sequences`` does (one macro action each, standardised; ``--raw``
leaves them as they are) and a FAVAE (3 ladders x 2 latents, 1500 epochs, the C_last pre-run) is fitted per beta,
capacity allocation and seed. Reported per fit: MIG and each factor's score (goal, curve in/out, curvature) with
bootstrap intervals over the 20 sequences, KL per ladder, reconstruction MSE, and each ladder's traversal effect
with the sequences drawn as paths (values -3,-1,1,3). The authors searched beta over 0-1.4 for the 100-step set
and report C = 0, 0, 0.99 per ladder.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch
from common import RESULTS, write_result

from famarl_cli.favae.model import FavaeConfig
from famarl_cli.favae.training import TrainingParams, allocate_capacity, calibrate, evaluate_fit, train_favae
from famarl_cli.sequences import load_arrays, to_segments
from famarl_cli.sweep.plan import parse_values
from famarl_cli.traversal import traverse, variables_of

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "favae-2d-reaching"
VALUES = [-3.0, -1.0, 1.0, 3.0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, choices=(100, 1000), default=100)
    parser.add_argument("--betas", default="0.2,0.6,1,1.4")
    parser.add_argument("--allocations", default="measured,deepest")
    parser.add_argument("--seeds", default="0-2")
    parser.add_argument("--epochs", type=int, default=1500)
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--raw", action="store_true", help="Do not standardise the sequences.")
    args = parser.parse_args()
    torch.set_num_threads(1)
    source = DATA / f"2d_reaching_{args.steps}.npz"
    segments = to_segments(load_arrays(source), source, None, 8, {}, standardize=not args.raw)
    names = list(segments.factor_names)
    base = FavaeConfig(action_dim=2, length=segments.max_length)
    fits = []
    for seed in (int(s) for s in parse_values(args.seeds)):
        params = TrainingParams(epochs=args.epochs, seed=seed)
        c_last = calibrate(segments.padded, base, params)[0]
        for beta in (float(b) for b in parse_values(args.betas)):
            for allocation in parse_values(args.allocations):
                start = time.perf_counter()
                capacities = allocate_capacity(c_last, allocation)
                model, _ = train_favae(segments.padded, replace(base), beta, capacities, params)
                scores = evaluate_fit(model, segments.padded, segments.length, segments.factors)
                effects = traverse(model, variables_of(model, None, None), VALUES, draw="values").effects
                fit = {
                    "seed": seed,
                    "beta": beta,
                    "allocation": allocation,
                    "c_last": c_last,
                    "capacities": capacities,
                    "mig": scores["mig"],
                    "mig_interval": scores["mig_interval"],
                    "mig_per_factor": {names[int(k)]: v for k, v in scores["mig_per_factor"].items()},
                    "mig_per_factor_interval": {names[int(k)]: v for k, v in scores["mig_per_factor_interval"].items()},
                    "kl_per_dim": scores["kl_per_dim"],
                    "kl_per_ladder": scores["kl_per_ladder"],
                    "reconstruction_mse": scores["reconstruction_mse"],
                    "effect_per_ladder": effects.reshape(3, 2).max(axis=1).tolist(),
                    "seconds": round(time.perf_counter() - start, 1),
                }
                fits.append(fit)
                per_factor = " ".join(f"{n} {v:.2f}" for n, v in fit["mig_per_factor"].items())
                print(
                    f"seed {seed} beta {beta:g} {allocation:8s} MIG {fit['mig']:.2f} "
                    f"[{fit['mig_interval'][0]:.2f}, {fit['mig_interval'][1]:.2f}] ({per_factor})  "
                    f"KL/ladder {np.round(fit['kl_per_ladder'], 2)}  MSE {fit['reconstruction_mse']:.5f}  "
                    f"effect/ladder {np.round(fit['effect_per_ladder'], 3)}",
                    flush=True,
                )
    out = args.out or RESULTS / f"favae_2d_reaching_{args.steps}.json"
    write_result(out, {"source": source.name, "epochs": args.epochs, "factor_names": names, "fits": fits})


if __name__ == "__main__":
    main()
