"""FAVAE designs against each other on the default pipeline's segments: which ladder carries what, and at what cost.

    dvc repro                                   # data/maze/macros/seed*/segments.h5
    python studies/favae_variants.py [--seeds 0-2] [--designs shared-kl,ladder-info-p20] [--beta 50]
    python studies/favae_variants.py --data data/scripts/macros --pattern 'down-and-up-seed{seed}' --beta 0.1

Per design (studies/favae_designs.py) and seed, the C_last pre-run and a fit at the pipeline's settings (beta
50, 1500 epochs, 3 ladders x 2 latents) on replicate S's segments, scored: KL, information and shift per ladder,
the active latents, MIG with its interval, reconstruction MSE, length accuracy, the traversal effect of each
variable (m; values -3,-1,1,3, run in ContinuousWorld) and the time per optimiser step. Printed per design: the
means over seeds, how many seeds' ladder 3 moves the path >= 0.5 m, and in how many the strongest variable is in
ladder 3.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from favae_designs import run_all, summary
from study import RESULTS, fan_out_options, write_result

from famarl_cli.sweep.plan import parse_values

VALUES = [-3.0, -1.0, 1.0, 3.0]
MOVES = 0.5
"""Effect (m) from which a variable visibly changes the path (famarl_cli.report.experiments.traversal.MOVES)."""


def design_line(design: str, group: list[dict]) -> str:
    """One design's fits: means over seeds, per-seed MIG and length accuracy, and what ladder 3 does."""

    def mean(key: str, digits: int = 2) -> str:
        return str(np.round(np.mean([f[key] for f in group], axis=0), digits))

    def each(key: str) -> str:
        return " ".join(f"{f[key]:.2f}" for f in group)

    deepest = [f["effect_per_ladder"][-1] for f in group]
    strongest_deep = [
        max(f["effect_per_variable"], key=f["effect_per_variable"].get).startswith(f"({len(f['dims'])},") for f in group
    ]
    return (
        f"{design:22s} n {len(group)}: info/ladder {mean('information_per_ladder')} KL/ladder "
        f"{mean('kl_per_ladder')} effect/ladder {mean('effect_per_ladder')}  MIG {mean('mig', 3)} (per seed "
        f"{each('mig')})  length acc {mean('length_accuracy')} (per seed {each('length_accuracy')})  MSE "
        f"{mean('reconstruction_mse', 4)}  ladder 3 >= {MOVES} m in {sum(d >= MOVES for d in deepest)}, strongest "
        f"in ladder 3 in {sum(strongest_deep)}  {mean('ms_per_step')} ms/step"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", default="0-2")
    parser.add_argument("--designs", default="shared-kl,ladder-info-p20")
    parser.add_argument("--beta", type=float, default=50.0)
    parser.add_argument("--epochs", type=int, default=1500)
    parser.add_argument("--data", type=Path, default=Path("data/maze/macros"))
    parser.add_argument("--pattern", default="seed{seed}", help="Each seed's folder under --data.")
    parser.add_argument("--out", type=Path, default=RESULTS / "favae_variants.json")
    fan_out_options(parser)
    args = parser.parse_args()
    jobs = [
        {
            "design": design,
            "seed": int(seed),
            "beta": args.beta,
            "epochs": args.epochs,
            "segments": str(args.data / args.pattern.format(seed=seed) / "segments.h5"),
            "values": VALUES,
            "draw": "run",
        }
        for design in parse_values(args.designs)
        for seed in parse_values(args.seeds)
    ]
    fits = run_all(jobs, args.jobs, args.ray_address)
    print()
    for design in parse_values(args.designs):
        print(design_line(design, [f for f in fits if f["design"] == design]))
    keys = (
        "c_last",
        "kl_per_ladder",
        "information_per_ladder",
        "effect_per_ladder",
        "mig",
        "length_accuracy",
        "reconstruction_mse",
        "ms_per_step",
    )
    write_result(args.out, {"seeds": args.seeds, "beta": args.beta, "summary": summary(fits, keys), "fits": fits})


if __name__ == "__main__":
    main()
