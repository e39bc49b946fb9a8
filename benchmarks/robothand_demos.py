"""Do pegging demos with the baskets raised to varied heights give FaMARL macros that solve RobotHand? FaMARL trained
on the pipeline's tasks with the macros of a demo set, under the paper's per-decision discount or semi-MDP
discounting, the success of its sampled policy, and the macro-space oracle's share of layouts, each with a 95%
interval over replicates.

    dvc repro pipelines/robothand/dvc.yaml               # its settings; the pegging set's FAVAEs
    python benchmarks/robothand_demos.py [--seeds 0-9] [--demos pegging-varied] [--discounts decision,steps]
                                         [--steps N] [--lr X] [--tasks Reaching-v1,BallPlacing-v0]

Demo sets: ``pegging``, the pipeline's own demos and FAVAEs (data/robothand/macros); ``pegging-varied``, 100 demos of
the same expert in RobotHand BaseVaried (each basket raised on a post to a floor height drawn in [0, 3] m, so the
approaches, carries and placings go up, down and across at every slope), segmented and pre-run/fitted with the
pipeline's settings (pipelines/robothand/params.yaml) into data/robothand-demos/pegging-varied. Each cell (demo set,
task, discount) is a ``famarl sweep train`` over the seeds at the pipeline's budget and learning rate, or those
of --steps and --lr (in the cell's folder name then; seed S
decodes with replicate S's FAVAE) into data/robothand-demos/<demos>/<task>-<discount>, evaluated like the
pipeline's runs (100 layouts from seed 100, sampled policy); the oracle (``famarl oracle``, the pipeline's 10
layouts a run) searches each demo set's macro space once per task, on the per-decision runs (the search does not
use the policy). Finished work is reused. Records one row per cell and oracle in benchmarks/measured.json
(docs/robothand.md shows them) and writes benchmarks/results/robothand_demos.json. Run it alone: it uses both cores
(about 25 minutes for pegging-varied at 10 replicates on a 2-core AMD EPYC VM).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import yaml
from common import RESULTS, ROOT, command_line, famarl, record, seed_list, train_and_evaluate, write_result

from famarl_cli.artifacts.runs import ORACLE_FILE, read_oracle
from famarl_cli.core.statistics import mean_interval

DEMOS = {"pegging": "the pipeline's pegging demos", "pegging-varied": "pegging demos with raised baskets"}
DISCOUNTS = {"decision": "the paper's per-decision discount", "steps": "semi-MDP discounting"}
PARAMS = ROOT / "pipelines/robothand/params.yaml"
EPISODES, EVALUATION_SEED = 100, 100


def macros(demos: str, seeds: str, params: dict, data: Path) -> Path:
    """The folder of the demo set's FAVAEs (seed S in seedS/favae.pt), made where they are not yet."""
    if demos == "pegging":
        return data / "robothand/macros"
    folder = data / "robothand-demos" / demos
    recorded = folder / f"{demos}.h5"
    if not recorded.is_file():
        famarl("demos", "--script", demos, "--episodes", str(params["demos"]["episodes"]),
               "--seed", str(params["demos"]["seed"]), "--out", str(recorded))  # fmt: skip
    segment, favae = params["segment"], params["favae"]
    famarl("sweep", "macros", "--seeds", seeds, "--out", str(folder / "macros"), "--", "--demos", str(recorded),
           "--margin", str(segment["margin"]), "--segment-epochs", str(segment["epochs"]),
           "--beta", str(favae["beta"]), "--epochs", str(favae["epochs"]))  # fmt: skip
    return folder / "macros"


def success(cell: Path, task: str, discount: str, favaes: Path, seeds: str, train: dict) -> list[float]:
    """Sampled-policy success of the cell's runs over ``seeds``, trained and evaluated where they are not yet."""
    options = ["--env", f"famarl/RobotHand-{task}", "--agent", "famarl", "--favae", str(favaes / "seed{seed}/favae.pt"),
               "--steps", str(train["steps"]), "--lr", str(train["lr"]),
               "--macro-discount", discount, "--label", f"famarl-{discount}"]  # fmt: skip
    runs = train_and_evaluate(cell, seeds, options, EPISODES, EVALUATION_SEED)
    return [float(evaluation["sampled"]["success_rate"]) for _, evaluation in runs]


def oracle(cell: Path, seeds: str, episodes: int) -> list[float]:
    """The oracle's share of layouts per replicate, searched in the macro space of the cell's runs."""
    out = cell.with_name(cell.name + "-oracle")
    famarl("oracle", "--run", str(cell), "--episodes", str(episodes), "--out", str(out))
    return [float(read_oracle(out / f"seed{s}" / ORACLE_FILE)["success_rate"]) for s in seed_list(seeds)]


def _choices(value: str, known: dict, option: str) -> list[str]:
    chosen = value.split(",")
    if unknown := [c for c in chosen if c not in known]:
        raise SystemExit(f"error: {option}: unknown {unknown[0]!r} (known: {', '.join(known)})")
    return chosen


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", default="0-9", help="Replicates (FAVAE and RL seed).")
    parser.add_argument("--demos", default="pegging-varied", help=f"Demo sets, of {', '.join(DEMOS)}.")
    parser.add_argument("--discounts", default=",".join(DISCOUNTS), help=f"Of {', '.join(DISCOUNTS)}.")
    parser.add_argument("--tasks", help="Of the pipeline's tasks [default: all of them].")
    parser.add_argument("--steps", type=int, help="Env steps per run [default: the pipeline's].")
    parser.add_argument("--lr", type=float, help="Learning rate [default: the pipeline's].")
    parser.add_argument("--oracle-episodes", type=int, default=10, help="Layouts the oracle searches a run (0: none).")
    parser.add_argument("--data", type=Path, default=ROOT / "data")
    parser.add_argument("--out", type=Path, default=RESULTS / "robothand_demos.json")
    args = parser.parse_args()
    demo_sets = _choices(args.demos, DEMOS, "--demos")
    discounts = _choices(args.discounts, DISCOUNTS, "--discounts")
    seeds = seed_list(args.seeds)
    if args.oracle_episodes < 0:
        raise SystemExit(f"error: --oracle-episodes {args.oracle_episodes}: not a count of layouts")
    if (args.steps is not None and args.steps < 1) or (args.lr is not None and not 0 < args.lr < 1):
        raise SystemExit("error: --steps must be at least 1 and --lr in (0, 1)")
    pegging = [args.data / f"robothand/macros/seed{s}/favae.pt" for s in seeds] if "pegging" in demo_sets else []
    if missing := [path for path in pegging if not path.is_file()]:
        raise SystemExit(f"error: {missing[0]}: no pegging FAVAE there; dvc repro pipelines/robothand/dvc.yaml first")
    params = yaml.safe_load(PARAMS.read_text(encoding="utf-8"))
    tasks = _choices(args.tasks or params["tasks"], dict.fromkeys(params["tasks"].split(",")), "--tasks")
    line = command_line(
        "robothand_demos.py", parser, args, shown=("seeds", "demos", "discounts"), hidden=("out", "data")
    )
    train = {"steps": args.steps or params["train"]["steps"], "lr": args.lr or params["train"]["lr"]}
    budget = f"{train['steps']:,} env steps, lr {train['lr']:g}"
    changed = (f"-{train['steps']}steps" if train["steps"] != params["train"]["steps"] else "") + (
        f"-lr{train['lr']:g}" if train["lr"] != params["train"]["lr"] else ""
    )
    rows = {}
    for demos in demo_sets:
        favaes = macros(demos, args.seeds, params, args.data)
        for task in tasks:
            for discount in discounts:
                cell = args.data / "robothand-demos" / demos / f"{task}-{discount}{changed}"
                rates = success(cell, task, discount, favaes, args.seeds, train)
                interval = mean_interval(rates, EPISODES)
                rows[f"{demos}/{task}/{discount}{changed}"] = {"success": rates, "interval": interval.text()}
                record(
                    f"robothand_demos_{demos}_{task}_{discount}{changed}".replace("-", "_").replace(".", "_").lower(),
                    f"RobotHand-{task}, FaMARL with macros from {DEMOS[demos]}, {DISCOUNTS[discount]}, {budget}: "
                    f"success of the sampled policy over {EPISODES} layouts, replicates {args.seeds}; mean [95% CI]",
                    line,
                    interval.text(),
                )
            if args.oracle_episodes and not changed:  # the oracle searches the macro space: no budget in it
                shares = oracle(args.data / "robothand-demos" / demos / f"{task}-{discounts[0]}", args.seeds,
                                args.oracle_episodes)  # fmt: skip
                interval = mean_interval(shares, args.oracle_episodes)
                rows[f"{demos}/{task}/oracle"] = {"shares": shares, "interval": interval.text()}
                record(
                    f"robothand_demos_{demos}_{task}_oracle".replace("-", "_").lower(),
                    f"RobotHand-{task}: share of layouts an open-loop plan of macros from {DEMOS[demos]} solved "
                    f"(famarl oracle, lower bound), replicates {args.seeds}, {args.oracle_episodes} layouts each; "
                    "mean [95% CI]",
                    line,
                    interval.text(),
                )
    write_result(args.out, {"command": line, "rows": rows})
    for name, row in rows.items():
        print(f"{name:<40} {row['interval']:<20} {row.get('success', row.get('shares'))}")


if __name__ == "__main__":
    main()
