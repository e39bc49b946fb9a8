"""FAVAE designs on the FAVAE authors' own data with known factors: 2D Reaching (../shared/data/favae-2d-reaching).

    python studies/favae_2d_reaching.py [--steps 100] [--designs ladder-info-p20,shared-kl] [--betas 1]
                                           [--seeds 0-9] [--epochs 1500]

The 20 sequences are imported as ``famarl sequences`` does (one macro action each, standardised; ``--raw`` leaves
them as they are). Per design (studies/favae_designs.py), beta and seed: the C_last pre-run, the fit, MIG and
each factor's score (goal, curve in/out, curvature) with intervals over the 20 sequences, KL and information per
ladder, the reconstruction, and each ladder's traversal effect with the sequences drawn as paths (values
-3,-1,1,3). Printed per design: how often the deepest ladder holds >= 50% (100 steps) or >= 30% (1000 steps) of
the pre-run's total, against the authors' capacities (0, 0, 0.99 and 1.35, 0, 1.29: 100% and 49%), and the mean
MIG per factor. The authors searched beta over 0-1.4 (100 steps) and 0-5 (1000 steps).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from favae_designs import run_all, summary
from study import RESULTS, fan_out_options, write_result

from famarl_cli.method.sequences import load_arrays, to_segments
from famarl_cli.sweep.plan import parse_values

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "favae-2d-reaching"
VALUES = [-3.0, -1.0, 1.0, 3.0]
AUTHORS = {100: ([0.00, 0.00, 0.99], 0.5), 1000: ([1.35, 0.00, 1.29], 0.3)}
"""The authors' best capacities per ladder for their ladder model, and the deepest share the design asked of ours."""
CAPTURED = 0.1
"""A factor whose MIG score reaches this is captured by some latent."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, choices=(100, 1000), default=100)
    parser.add_argument("--designs", default="ladder-info-p20,shared-kl")
    parser.add_argument("--betas", default="1")
    parser.add_argument("--seeds", default="0-9")
    parser.add_argument("--epochs", type=int, default=1500)
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--raw", action="store_true", help="Do not standardise the sequences.")
    parser.add_argument("--pre-run-only", action="store_true", help="Only the C_last pre-runs (the capacities).")
    fan_out_options(parser)
    args = parser.parse_args()
    source = DATA / f"2d_reaching_{args.steps}.npz"
    segments = to_segments(load_arrays(source), source, None, 8, {}, standardize=not args.raw)
    names = list(segments.factor_names)
    data = {"padded": segments.padded, "lengths": segments.length, "factors": segments.factors}
    jobs = [
        {**data, "design": design, "beta": beta, "seed": int(seed), "epochs": args.epochs}
        | {"values": VALUES, "draw": "values", "pre_run_only": args.pre_run_only}
        for design in parse_values(args.designs)
        for beta in ([None] if args.pre_run_only else [float(b) for b in parse_values(args.betas)])
        for seed in parse_values(args.seeds)
    ]
    fits = run_all(jobs, args.jobs, args.ray_address)
    authors, share = AUTHORS[args.steps]
    print(f"\nauthors' capacities {authors}: deepest share {authors[-1] / sum(authors):.0%}; ours >= {share:.0%}?")
    for fit in fits:
        total = sum(fit["c_last"])
        fit["deepest_share"] = fit["c_last"][-1] / total if total > 0 else 0.0
    groups: dict[tuple, list[dict]] = {}
    for fit in fits:
        groups.setdefault((fit["design"], fit["beta"]), []).append(fit)
    for (design, beta), group in groups.items():
        shares = [f["deepest_share"] for f in group]
        deep = (
            f"{design:22s} deepest share of C_last >= {share:.0%} in {sum(s >= share for s in shares)} of "
            f"{len(group)} (per seed {' '.join(f'{s:.2f}' for s in shares)})"
        )
        if beta is None:
            print(deep)
            continue
        for fit in group:
            fit["mig_per_factor"] = {names[int(k)]: v for k, v in fit["mig_per_factor"].items()}
            fit["mig_per_factor_interval"] = {names[int(k)]: v for k, v in fit["mig_per_factor_interval"].items()}
            fit["factors_captured"] = sum(v >= CAPTURED for v in fit["mig_per_factor"].values())
        per_factor = {n: np.mean([f["mig_per_factor"].get(n, 0.0) for f in group]) for n in names}
        print(
            f"{deep}; beta {beta:g}: MIG {np.mean([f['mig'] for f in group]):.3f} (per factor "
            + ", ".join(f"{n} {v:.2f}" for n, v in per_factor.items())
            + f"); all factors captured in {sum(f['factors_captured'] == len(names) for f in group)}; "
            f"{np.mean([f['ms_per_step'] for f in group]):.2f} ms/step"
        )
    keys = ("c_last",)
    if not args.pre_run_only:
        keys += ("kl_per_ladder", "information_per_ladder", "effect_per_ladder", "mig", "reconstruction_mse")
    out = args.out or RESULTS / f"favae_2d_reaching_{args.steps}.json"
    write_result(
        out,
        {
            "source": source.name,
            "epochs": args.epochs,
            "factor_names": names,
            "authors_capacities": authors,
            "summary": summary(fits, keys),
            "fits": fits,
        },
    )


if __name__ == "__main__":
    main()
