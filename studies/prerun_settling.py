"""How soon the C_last pre-run settles: pre-runs as long as the fit, and each ladder's mean over candidate windows
against its mean over the last 100 epochs, paired over the replicates.

    python studies/prerun_settling.py [--macros data/maze/macros] [--seeds 0-9]

Fits the pre-runs of replicates ``--seeds`` on the segments of a default-pipeline sweep (``--macros``; the default
params: 1500 epochs, progressive 0.2, beta 0.1, information), as long as the fit (``--pre-run 1``), in one batch, one
torch thread. For each window (the epochs a shorter pre-run averages: this project's 337-450 of a pre-run of 0.3,
and others) and for the last epoch alone (the paper's reading), the per-ladder difference from the mean over epochs
1400-1499, mean [95% t-interval] over the replicates; and the standard deviation of single epochs after epoch 400.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch
from study import RESULTS, command_line, record, write_result

from famarl_cli.core.statistics import mean_interval
from famarl_cli.method.favae import FavaeOptions
from famarl_cli.method.favae.training import Replicate, TrainingParams, calibrate_replicates
from famarl_cli.stages.method import favae_setup
from famarl_cli.sweep.plan import parse_values

WINDOWS = {"337-450 (pre-run 0.3)": (337, 450), "400-600 (0.4)": (400, 600), "500-750 (0.5)": (500, 750)}
SETTLED = (1400, 1500)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--macros", type=Path, default=Path("data/maze/macros"))
    parser.add_argument("--seeds", default="0-9")
    parser.add_argument("--out", type=Path, default=RESULTS / "prerun_settling.json")
    args = parser.parse_args()
    seeds = [int(s) for s in parse_values(args.seeds)]
    missing = [s for s in seeds if not (args.macros / f"seed{s}" / "segments.h5").is_file()]
    if missing:
        raise SystemExit(f"error: {args.macros}: no seed{missing[0]}/segments.h5 (run the default pipeline first)")
    torch.set_num_threads(1)
    replicates = []
    for seed in seeds:
        options = FavaeOptions(seed=seed, pre_run=1.0)
        loaded, config = favae_setup(args.macros / f"seed{seed}" / "segments.h5", options)
        replicates.append(
            Replicate(loaded.padded, config, options.calibration_beta, [0.0] * 3, TrainingParams.of(options))
        )
    logs = [log for _, log in calibrate_replicates(replicates)]
    ladders = replicates[0].config.ladders
    information = np.array([[[row[f"information_{i + 1}"] for i in range(ladders)] for row in log] for log in logs])
    settled = information[:, SETTLED[0] : SETTLED[1]].mean(axis=1)  # (replicates, ladders)
    readings = {name: information[:, a:b].mean(axis=1) for name, (a, b) in WINDOWS.items()}
    readings["last epoch"] = information[:, -1]
    rows = {}
    for name, values in readings.items():
        rows[name] = [mean_interval(values[:, i] - settled[:, i]).text("{:+.3f}") for i in range(ladders)]
        print(f"{name:22s} - mean of {SETTLED[0]}-{SETTLED[1] - 1}: " + ", ".join(rows[name]))
    spread = information[:, 400:].std(axis=1).mean(axis=0)
    print("single epochs after 400, sd per ladder (mean over replicates): " + ", ".join(f"{s:.3f}" for s in spread))
    write_result(
        args.out,
        {"seeds": seeds, "macros": str(args.macros), "information": information.tolist(), "differences": rows},
    )
    record(
        "favae_prerun_settling",
        what=f"each ladder's information in pre-runs as long as the fit (1500 epochs, {len(seeds)} replicates of the "
        f"default pipeline's segments): its mean over a window, or its last epoch, less its mean over epochs "
        f"{SETTLED[0]}-{SETTLED[1] - 1}, ladders 1 / 2 / 3, nats, mean [95% t-interval]",
        command=command_line(__file__, parser, args, shown=("macros",)),
        measured="; ".join(f"{name}: {' / '.join(texts)}" for name, texts in rows.items())
        + "; single epochs after 400 wander with sd "
        + " / ".join(f"{s:.3f}" for s in spread),
    )


if __name__ == "__main__":
    main()
