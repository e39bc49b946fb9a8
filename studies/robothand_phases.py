"""Do pegging demos whose phases vary give macros that reach more of RobotHand than today's constant-phase demos,
before any RL? The calibration protocol's third step (docs/robothand.md): for each demo set, 100 demos (seed 0)
segmented and pre-run/fitted with pipelines/robothand's settings into one FAVAE per replicate, then, in each
replicate's macro space, on each of the pipeline's tasks:

- the action-space oracle's share of layouts an open-loop plan of macros solved (``famarl oracle``, the pipeline's
  search, on the layouts the evaluation seed draws), a lower bound of what the macros can reach;
- chance: the share of plans drawn from an untrained policy's spread (latents from N(0, 1)) that succeed, and on
  BallPlacing the shares that move the ball and lift it (the milestones before success; robothand_chance.py).

Each with its 95% interval over replicates, and the paired difference (phases minus constant) per replicate: the
same replicate seeds the FAVAE of both sets. No policy is trained: the runs the oracle and chance read are one
rollout at learning rate 0 (their action spaces only).

    python studies/robothand_phases.py [--seeds 0-4] [--layouts 10] [--plans 64] [--chance-layouts 5]
        [--jobs N] [--data data]

Runs on the development replicates (0-4, evaluation seed 100): pipelines/robothand judges on others. Run it alone
(one CPU-heavy job at a time): its famarl sweeps and oracle use $FAMARL_JOBS or every core, its chance counts
--jobs cores on famarl sweep's executors (by default the same; --ray-address a Ray cluster). Records one row per
measure, task and set in studies/measured.json (docs/robothand.md shows them) and writes
studies/results/robothand_phases.json.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import yaml
from robothand_chance import chance_of
from robothand_demos import fit_macros
from study import RESULTS, ROOT, command_line, famarl, fan_out, fan_out_options, record, seed_list, write_result

from famarl_cli.artifacts.runs import ORACLE_FILE, read_oracle
from famarl_cli.core.statistics import mean_interval, paired_difference_interval

DEMOS = {"pegging": "constant-phase pegging demos", "pegging-phases": "pegging demos whose phases vary"}
"""The demo sets compared, by ``famarl demos --script`` name: today's expert (every descent 0.8 m) and the same
expert with its hover clearance, grasp height, carry height and an alignment leg drawn per episode."""
TASKS = ("Reaching-v1", "BallPlacing-v0")
PARAMS = ROOT / "pipelines/robothand/params.yaml"
EVALUATION_SEED = 100
"""The development runs' evaluation seed: pipelines/robothand's judged runs draw their layouts from another."""


def untrained(favaes: Path, task: str, seeds: str, out: Path) -> Path:
    """Runs of one rollout at learning rate 0 over ``seeds``, replicate S decoding with ``favaes``' seed S."""
    famarl("sweep", "train", "--seeds", seeds, "--name", "seed{seed}", "--out", str(out), "--",
           "--env", f"famarl/RobotHand-{task}", "--agent", "famarl", "--favae", str(favaes / "seed{seed}/favae.pt"),
           "--steps", "1", "--lr", "0", "--label", "untrained")  # fmt: skip
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", default="0-4", help="Replicates (FAVAE seeds): development ones.")
    parser.add_argument("--layouts", type=int, default=10, help="Layouts the oracle searches per replicate.")
    parser.add_argument("--plans", type=int, default=64, help="Plans drawn by chance per layout.")
    parser.add_argument("--chance-layouts", type=int, default=5, help="Layouts per replicate for chance.")
    fan_out_options(parser)
    parser.add_argument("--data", type=Path, default=ROOT / "data")
    parser.add_argument("--out", type=Path, default=RESULTS / "robothand_phases.json")
    args = parser.parse_args()
    if min(args.layouts, args.plans, args.chance_layouts, 1 if args.jobs is None else args.jobs) < 1:
        raise SystemExit("error: --layouts, --plans, --chance-layouts and --jobs must be at least 1")
    seeds = seed_list(args.seeds)
    params = yaml.safe_load(PARAMS.read_text(encoding="utf-8"))
    line = command_line(__file__, parser, args, shown=("seeds", "layouts", "plans", "chance_layouts"),
                        hidden=("out", "data", "jobs", "ray_address"))  # fmt: skip
    shares: dict[tuple[str, str, str], list[float]] = {}
    for demos in DEMOS:
        folder = args.data / "robothand-phases" / demos
        favaes = fit_macros(demos, args.seeds, params, folder, plot=False)
        for task in TASKS:
            runs = untrained(favaes, task, args.seeds, folder / f"{task}-untrained")
            searched = folder / f"{task}-oracle"
            famarl("oracle", "--run", str(runs), "--layouts", str(args.layouts), "--seed", str(EVALUATION_SEED),
                   "--out", str(searched), "--overwrite")  # fmt: skip
            shares[(demos, task, "oracle")] = [
                float(read_oracle(searched / f"seed{s}" / ORACLE_FILE)["success_rate"]) for s in seeds
            ]
            chances = [(str(runs / f"seed{s}"), args.chance_layouts, args.plans) for s in seeds]
            found = np.array(fan_out(chance_of, chances, args.jobs, args.ray_address))
            for column, name in enumerate(("chance", "moved", "lifted")):
                if column and not task.startswith("BallPlacing"):
                    continue
                shares[(demos, task, name)] = (found[:, column] / found[:, 3]).tolist()
    what = {
        "oracle": (f"share of {args.layouts} layouts an open-loop plan of macros solved (famarl oracle, lower bound)",
                   args.layouts),
        "chance": (f"share of {args.chance_layouts} layouts x {args.plans} plans drawn by chance (latents from "
                   "N(0, 1)) that succeed", args.chance_layouts * args.plans),
        "moved": ("share of plans drawn by chance that move the ball at least 0.05 m",
                  args.chance_layouts * args.plans),
        "lifted": ("share of plans drawn by chance that lift the ball at least 0.3 m above its rest",
                   args.chance_layouts * args.plans),
    }  # fmt: skip
    rows = {}
    for (demos, task, measure), values in shares.items():
        text, count = what[measure]
        interval = mean_interval(values, count).text("{:.3f}")
        rows[f"{demos}/{task}/{measure}"] = {"values": values, "interval": interval}
        record(
            f"robothand_phases_{demos}_{task}_{measure}".replace("-", "_").lower(),
            f"RobotHand-{task}, macros of {DEMOS[demos]}, before any RL: {text}; replicates {args.seeds}, "
            "mean [95% CI]",
            line,
            interval,
        )
        if demos == "pegging-phases":
            old = shares[("pegging", task, measure)]
            difference = paired_difference_interval(values, old, count).text("{:+.3f}")
            rows[f"difference/{task}/{measure}"] = {"interval": difference}
            record(
                f"robothand_phases_difference_{task}_{measure}".replace("-", "_").lower(),
                f"RobotHand-{task}, before any RL: {text}, macros of pegging demos whose phases vary minus "
                f"constant-phase ones, paired by replicate; replicates {args.seeds}, mean [95% CI]",
                line,
                difference,
            )
    write_result(args.out, {"command": line, "rows": rows})
    for name, row in rows.items():
        print(f"{name:<42} {row['interval']:<26} {row.get('values', '')}")


if __name__ == "__main__":
    main()
