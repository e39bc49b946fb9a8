"""How wide the prior and closed-loop decoder should be: ``famarl prior fit`` at several widths on the FAVAEs of the
default pipeline (Maze) and of pipelines/pointmaze (UMaze), 10 replicates each, the same seeds and held-out episodes.

    python studies/prior_widths.py [--widths 64 32 16 8] [--seeds 0-9]

Per width and demos: the held-out cross-entropy of the prior less N(0, I)'s (negative: the prior knows more than
the standard normal about which latent the expert used where), mean over replicates with its 95% t-interval and
how many replicates are below 0; and the closed-loop decoder's held-out action error as a share of the FAVAE's
open-loop one. Needs the two pipelines' data (``dvc repro``, ``dvc repro pipelines/pointmaze/dvc.yaml``). The
default width of ``PriorFitChoices`` was chosen from this table, so its held-out scores are slightly optimistic.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch
from study import RESULTS, command_line, record, write_result

from famarl_cli.artifacts import read_demos
from famarl_cli.artifacts.segments import read_segments
from famarl_cli.core.statistics import mean_interval
from famarl_cli.method.favae.checkpoint import load_favae
from famarl_cli.method.prior.choices import PriorFitChoices
from famarl_cli.method.prior.data import skill_pairs
from famarl_cli.method.prior.training import fit_prior
from famarl_cli.sweep.plan import parse_values

SOURCES = {
    "Maze": (Path("data/demos/pushed-down-only.h5"), Path("data/maze/macros")),
    "PointMaze UMaze": (Path("data/demos/pointmaze.h5"), Path("data/pointmaze/macros")),
}


def scores(demos: Path, macros: Path, seed: int, hidden: int) -> tuple[float, float]:
    """One replicate's (prior - N(0, I) held-out cross-entropy, closed / open-loop held-out action error)."""
    favae = load_favae(macros / f"seed{seed}" / "favae.pt")[0]
    pairs = skill_pairs(read_demos(demos), read_segments(macros / f"seed{seed}" / "segments.h5"), favae)
    _, _, fitted, _ = fit_prior(pairs, replace(PriorFitChoices(), seed=seed, hidden=hidden), favae.config.length, favae)
    return (
        fitted["held_out_prior_nll"] - fitted["held_out_standard_nll"],
        fitted["held_out_closed_mse"] / fitted["held_out_open_mse"],
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--widths", type=int, nargs="+", default=[64, 32, 16, 8])
    parser.add_argument("--seeds", default="0-9")
    parser.add_argument("--out", type=Path, default=RESULTS / "prior_widths.json")
    args = parser.parse_args()
    torch.set_num_threads(1)
    seeds = [int(s) for s in parse_values(args.seeds)]
    rows, cells = [], []
    for hidden in args.widths:
        parts = []
        for name, (demos, macros) in SOURCES.items():
            measured = np.array([scores(demos, macros, seed, hidden) for seed in seeds])
            interval = mean_interval(measured[:, 0])
            below = int((measured[:, 0] < 0).sum())
            share = float(measured[:, 1].mean())
            rows.append({"width": hidden, "demos": name, "differences": measured[:, 0].tolist(), "decoder": share})
            print(
                f"width {hidden:>3} {name:<16} prior - N(0, I) {interval.text()}, {below} of {len(seeds)} below 0; "
                f"closed / open-loop error {share:.2f}",
                flush=True,
            )
            parts.append(f"{name} {interval.text()} ({below} of {len(seeds)} below 0; decoder {share:.2f})")
        cells.append(f"width {hidden}: " + ", ".join(parts))
    write_result(args.out, {"seeds": seeds, "rows": rows})
    record(
        "prior_widths",
        f"the prior's width: held-out cross-entropy of the prior less N(0, I)'s, mean [95% t-interval] over "
        f"{len(seeds)} replicates, and the closed-loop decoder's held-out error as a share of the open-loop one",
        command_line(__file__, parser, args),
        "; ".join(cells),
        "below 0 at the 95% level on both",
    )


if __name__ == "__main__":
    main()
