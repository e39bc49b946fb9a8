"""Variants of the hybrid agent against each other on one env, from their training logs: which pays?

    dvc repro                                            # data/maze/macros/seed*/favae.pt
    dvc repro pipelines/robothand/dvc.yaml               # data/robothand/macros/seed*/favae.pt (for --env reaching)
    python studies/hybrid_variants.py [--env maze|reaching] [--seeds 0-9] [--variants h10,h5,...]

Each variant is a ``famarl sweep train --agent hybrid`` over the seeds (seed S decodes with replicate S's FAVAE),
into data/hybrid-variants/<env>/<variant>; finished runs are reused. Per variant it prints, with 95% intervals
over seeds: the training success in the first 2% of the budget, env steps to 0.8 training success (censored runs
count the budget), the AUC, the training return over the last 10% of updates, the share of env steps in macros
and the wall time per run (two runs at a time).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np
from study import RESULTS, write_result

from famarl_cli.artifacts.runs import read_run_file, read_training_log
from famarl_cli.core.statistics import mean_interval, normalised_auc, steps_to_threshold
from famarl_cli.sweep.plan import parse_values

ENVS = {
    "maze": ("famarl/ContinuousWorld-Maze-v0", "data/maze/macros", 500_000),
    "reaching": ("famarl/RobotHand-Reaching-v0", "data/robothand/macros", 300_000),
}
VARIANTS = {
    "whole": ["--macro-horizon", "0", "--residual", "0"],
    "h10": ["--macro-horizon", "10", "--residual", "0"],
    "h5": ["--macro-horizon", "5", "--residual", "0"],
    "h10-residual": ["--macro-horizon", "10", "--residual", "0.25"],
    "residual": ["--macro-horizon", "0", "--residual", "0.25"],
    "h10-no-floor": ["--macro-horizon", "10", "--residual", "0", "--type-entropy-floor", "0"],
    "h10-128": ["--macro-horizon", "10", "--residual", "0", "--n-steps", "128"],
}
"""Each variant's options, all explicit (``h10-residual`` is the hybrid's default since these measurements)."""


def run_variant(env: str, name: str, seeds: str) -> Path:
    env_id, macros, steps = ENVS[env]
    out = Path("data/hybrid-variants") / env / name
    command = ["famarl", "sweep", "train", "--seeds", seeds, "--name", "seed{seed}", "--out", str(out), "--"]
    favae = f"{macros}/seed{{seed}}/favae.pt"
    command += ["--env", env_id, "--agent", "hybrid", "--steps", str(steps), "--favae", favae]
    subprocess.run(command + ["--label", f"hybrid-{name}", *VARIANTS[name]], check=True)
    return out


def measure(folder: Path) -> dict[str, list[float]]:
    values: dict[str, list[float]] = {}
    for run in sorted(folder.glob("seed*")):
        log, budget = read_training_log(run), int(read_run_file(run)["spec"]["ppo"]["total_steps"])
        steps, success = log["env_steps"], log["episode_success"]
        known = ~np.isnan(success)
        early = known & (steps <= 0.02 * budget)
        reached = steps_to_threshold(steps, success, 0.8)
        last = max(1, len(steps) // 10)
        row = {
            "start": success[early].mean() if early.any() else success[known][0],
            "steps to 0.8 (k)": (budget if reached is None else reached) / 1000,
            "AUC": normalised_auc(steps, success, budget),
            "return (last 10%)": np.nanmean(log["episode_return"][-last:]),
            "macro step share": np.nanmean(log["macro_step_share"][-last:]),
            "wall (s)": float(read_run_file(run)["wall_s"]),
        }
        for key, value in row.items():
            values.setdefault(key, []).append(float(value))
    return values


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", choices=sorted(ENVS), default="maze")
    parser.add_argument("--seeds", default="0-9")
    parser.add_argument("--variants", default=",".join(VARIANTS))
    args = parser.parse_args()
    results = {}
    for name in args.variants.split(","):
        if name not in VARIANTS:
            sys.exit(f"unknown variant {name!r}; known: {', '.join(VARIANTS)}")
        results[name] = measure(run_variant(args.env, name, args.seeds))
    n = len(parse_values(args.seeds))
    columns = list(next(iter(results.values())))
    print(f"\n{args.env}, n = {n} seeds per variant, mean [95% CI]\n")
    print("| variant | " + " | ".join(columns) + " |")
    print("|---" * (len(columns) + 1) + "|")
    for name, values in results.items():
        formats = ["{:.0f}" if abs(np.mean(values[c])) >= 10 else "{:.2f}" for c in columns]
        cells = [mean_interval(values[c]).text(f) for c, f in zip(columns, formats, strict=True)]
        print(f"| {name} | " + " | ".join(cells) + " |")
    write_result(RESULTS / f"hybrid_variants_{args.env}.json", {"seeds": args.seeds, "variants": results})


if __name__ == "__main__":
    main()
