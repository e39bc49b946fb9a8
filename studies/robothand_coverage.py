"""Which moves can the pegging macros make, and are they the moves Reaching asks for? For each replicate's pegging
FAVAE, latents drawn from its prior N(0, I) (where FaMARL's policy starts) are decoded and run open-loop in the
empty RobotHand world from its centre; each macro's move is where the grip ends up. Against them, the move each
layout of the pipeline's Reaching asks for: from the grip's start to the goal.

    python studies/robothand_coverage.py [--demos pegging] [--seeds 0-9] [--samples 2000] [--layouts 2000]

``--demos pegging`` measures the pipeline's FAVAEs (data/robothand/macros, from ``dvc repro
pipelines/robothand/dvc.yaml``); ``--demos pegging-varied`` those of the pegging demos with raised baskets
(data/robothand-demos/pegging-varied/macros, from ``python studies/robothand_demos.py``): before and after.

Directions are 8 sectors of 45 degrees (0: right, counter-clockwise); a macro counts in its move's sector when it
moves at least 0.5 m. A sector is covered when at least 2% of a replicate's macros fall in it. Reported, over the
replicates (mean [95% t-interval]): the sectors covered, the macros' median move, and the share of Reaching layouts
whose direction lies in a covered sector. Records the three rows per demo set in studies/measured.json
(docs/robothand.md shows them) and writes studies/results/robothand_coverage-<demos>.json with each replicate's
sector shares.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch
from study import RESULTS, ROOT, command_line, record, seed_list, write_result

import famarl_cli  # noqa: F401  (registers the envs)
from famarl_cli.core.statistics import mean_interval
from famarl_cli.envs.robot_hand import OBSERVATION_NAMES, traversal_paths
from famarl_cli.method.favae.checkpoint import load_favae
from famarl_cli.report.experiments.robothand import REACHING

SECTORS, LEAST_MOVE, COVERED = 8, 0.5, 0.02
MACROS = {"pegging": "robothand/macros", "pegging-varied": "robothand-demos/pegging-varied/macros"}
"""Each demo set's FAVAEs, under --data."""
WORDS = {"pegging": "the pipeline's pegging demos", "pegging-varied": "pegging demos with raised baskets"}


def sector(moves: np.ndarray) -> np.ndarray:
    """(n, 2) moves -> (n,) sector indices, 0 .. SECTORS - 1, counter-clockwise from the right."""
    angle = np.arctan2(moves[:, 1], moves[:, 0]) % (2 * np.pi)
    return (angle // (2 * np.pi / SECTORS)).astype(int) % SECTORS


def macro_moves(favae_path: Path, samples: int, seed: int) -> np.ndarray:
    """(samples, 2): where the grip ends up after each of ``samples`` prior latents' macros, run from the centre."""
    model = load_favae(favae_path)[0]
    z = torch.from_numpy(np.random.default_rng(seed).standard_normal((samples, model.config.latent_size)))
    actions, lengths = model.decode_macro_actions(z.float())
    paths = traversal_paths(actions, lengths)
    return paths[:, -1] - paths[:, 0]


def asked_moves(layouts: int) -> np.ndarray:
    """(layouts, 2): from the grip's start to the goal, in the pipeline's Reaching layouts (reset seeds from 0)."""
    env = gym.make(REACHING)
    grip = [OBSERVATION_NAMES.index(n) for n in ("grip_x", "grip_y")]
    target = [OBSERVATION_NAMES.index(n) for n in ("target_x", "target_y")]
    moves = np.empty((layouts, 2))
    for layout in range(layouts):
        obs, _ = env.reset(seed=layout)
        moves[layout] = obs[target] - obs[grip]
    return moves


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--demos", default="pegging", choices=sorted(MACROS), help="Whose FAVAEs are measured.")
    parser.add_argument("--seeds", default="0-9", help="Replicates whose pegging FAVAEs are measured.")
    parser.add_argument("--samples", type=int, default=2000, help="Prior latents per replicate.")
    parser.add_argument("--layouts", type=int, default=2000, help="Reaching layouts.")
    parser.add_argument("--data", type=Path, default=ROOT / "data")
    parser.add_argument("--out", type=Path, help="Result file [default: studies/results/robothand_coverage-DEMOS.json]")
    args = parser.parse_args()
    seeds = seed_list(args.seeds)
    favaes = [args.data / MACROS[args.demos] / f"seed{s}/favae.pt" for s in seeds]
    if missing := [path for path in favaes if not path.is_file()]:
        made_by = "dvc repro pipelines/robothand/dvc.yaml" if args.demos == "pegging" else "robothand_demos.py"
        parser.error(f"{missing[0]}: no such file; {made_by} first")
    asked = asked_moves(args.layouts)
    asked_sector = sector(asked)
    covered, medians, served, per_replicate = [], [], [], {}
    for seed, path in zip(seeds, favaes, strict=True):
        moves = macro_moves(path, args.samples, seed)
        length = np.linalg.norm(moves, axis=1)
        shares = np.bincount(sector(moves[length >= LEAST_MOVE]), minlength=SECTORS) / len(moves)
        reached = shares >= COVERED
        covered.append(float(reached.sum()))
        medians.append(float(np.median(length)))
        served.append(float(reached[asked_sector].mean()))
        per_replicate[seed] = {"sector_shares": shares.round(4).tolist(), "median_move_m": round(medians[-1], 3)}
    line = command_line(__file__, parser, args, shown=("demos", "seeds", "samples", "layouts"), hidden=("out", "data"))
    rows = {
        "sectors": (covered, f"of {SECTORS}", "{:.1f}", (0, SECTORS)),
        "median_move": (medians, "m", "{:.2f}", (0, np.inf)),
        "layouts_served": (served, "", "{:.2f}", (0, 1)),
    }
    words = {
        "sectors": f"directions (of {SECTORS} sectors of 45 degrees) in which at least {COVERED:.0%} of a replicate's "
        f"pegging macros (prior latents) move the grip at least {LEAST_MOVE:g} m",
        "median_move": "the pegging macros' median move (m), prior latents run from the world's centre",
        "layouts_served": f"share of {REACHING.removeprefix('famarl/')} layouts whose start-to-goal direction is one "
        "the pegging macros cover",
    }
    for name, (values, unit, fmt, bounds) in rows.items():
        interval = mean_interval(values, bounds=bounds)
        record(
            f"robothand_coverage_{args.demos.replace('-', '_')}_{name}",
            f"RobotHand, macros from {WORDS[args.demos]}: {words[name]}; replicates {args.seeds}, mean [95% CI]",
            line,
            interval.text(fmt) + (f" {unit}" if unit else ""),
        )
        print(f"{name:<16} {interval.text(fmt)} {unit}")
    write_result(
        args.out or RESULTS / f"robothand_coverage-{args.demos}.json", {"command": line, "replicates": per_replicate}
    )


if __name__ == "__main__":
    main()
