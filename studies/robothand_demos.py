"""Do pegging demos with the baskets raised to varied heights give FaMARL macros that solve RobotHand? FaMARL trained
on the pipeline's tasks with the macros of a demo set, under the paper's per-decision discount or semi-MDP
discounting, the success of its sampled policy, and the macro-space oracle's share of layouts, each with a 95%
interval over replicates.

    dvc repro pipelines/robothand/dvc.yaml               # its settings; the pegging set's FAVAEs
    python studies/robothand_demos.py [--seeds 0-9] [--demos pegging-varied] [--discounts decision,steps]
                                         [--steps N] [--lr X] [--tasks Reaching-v1,BallPlacing-v0]
                                         [--env-kwargs JSON]

Demo sets: ``pegging``, the pipeline's own demos and FAVAEs (data/robothand/macros); ``pegging-varied``, 100 demos of
the same expert in RobotHand BaseVaried (each basket raised on a post to a floor height drawn in [0, 3] m, so the
approaches, carries and placings go up, down and across at every slope), segmented and pre-run/fitted with the
pipeline's settings (pipelines/robothand/params.yaml) into data/robothand-demos/pegging-varied. Each cell (demo set,
task, discount) is a ``famarl sweep train`` over the seeds at the pipeline's budget and learning rate, or those
of --steps and --lr, in the env of --tasks (any RobotHand task: the pipeline's by default) made with
--env-kwargs (the settings in the cell's folder name then; seed S decodes with replicate S's FAVAE) into
data/robothand-demos/<demos>/<task>-<discount>, evaluated like the pipeline's runs (100 layouts from seed 100,
sampled policy); the oracle (``famarl oracle``, the pipeline's 10 layouts a run) searches each demo set's macro
space per task on the first discount's runs, at the pipeline's budget or, in an env made with --env-kwargs, at the
budget given (the search uses neither the policy nor the budget, so its row is named by the demo set, the task and
the env's keyword arguments, not the budget). Finished work is reused.
Records one row per cell and oracle in studies/measured.json (docs/robothand.md shows them) and writes
studies/results/robothand_demos.json. Run it alone: it uses both cores (about 25 minutes for pegging-varied at 10
replicates on a 2-core AMD EPYC VM).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import yaml
from study import (
    RESULTS,
    ROOT,
    command_line,
    env_kwargs,
    famarl,
    kwargs_slug,
    kwargs_text,
    record,
    seed_list,
    train_and_evaluate,
    write_result,
)

from famarl_cli.artifacts.runs import ORACLE_FILE, read_oracle
from famarl_cli.core.errors import FamarlError
from famarl_cli.core.statistics import mean_interval
from famarl_cli.envs import ROBOT_HAND_IDS
from famarl_cli.envs.external import make_env

DEMOS = {"pegging": "the pipeline's pegging demos", "pegging-varied": "pegging demos with raised baskets"}
DISCOUNTS = {"decision": "the paper's per-decision discount", "steps": "semi-MDP discounting"}
PARAMS = ROOT / "pipelines/robothand/params.yaml"
EPISODES, EVALUATION_SEED = 100, 100


def fit_macros(demos: str, seeds: str, params: dict, folder: Path, plot: bool = True) -> Path:
    """The FAVAEs of ``famarl demos --script demos`` (seed S in ``folder/macros/seedS/favae.pt``), its demos made
    and its macros fitted with the pipeline's settings (``params``) where they are not yet."""
    recorded = folder / f"{demos}.h5"
    if not recorded.is_file():
        famarl("demos", "--script", demos, "--episodes", str(params["demos"]["episodes"]),
               "--seed", str(params["demos"]["seed"]), *([] if plot else ["--no-plot"]),
               "--out", str(recorded))  # fmt: skip
    segment, favae = params["segment"], params["favae"]
    famarl("sweep", "macros", "--seeds", seeds, "--out", str(folder / "macros"), "--", "--demos", str(recorded),
           "--margin", str(segment["margin"]), "--segment-epochs", str(segment["epochs"]),
           "--beta", str(favae["beta"]), "--epochs", str(favae["epochs"]))  # fmt: skip
    return folder / "macros"


def macros(demos: str, seeds: str, params: dict, data: Path) -> Path:
    """The folder of the demo set's FAVAEs (seed S in seedS/favae.pt), made where they are not yet."""
    if demos == "pegging":
        return data / "robothand/macros"
    return fit_macros(demos, seeds, params, data / "robothand-demos" / demos)


def success(cell: Path, task: str, discount: str, favaes: Path, seeds: str, train: dict, kwargs: dict) -> list[float]:
    """Sampled-policy success of the cell's runs over ``seeds``, trained and evaluated where they are not yet."""
    options = ["--env", f"famarl/RobotHand-{task}", "--agent", "famarl", "--favae", str(favaes / "seed{seed}/favae.pt"),
               "--steps", str(train["steps"]), "--lr", str(train["lr"]),
               "--macro-discount", discount, "--label", f"famarl-{discount}"]  # fmt: skip
    if kwargs:  # braces doubled: the sweep fills {seed} in the options
        options += ["--env-kwargs", json.dumps(kwargs).replace("{", "{{").replace("}", "}}")]
    runs = train_and_evaluate(cell, seeds, options, EPISODES, EVALUATION_SEED)
    return [float(evaluation["success_rate"]) for _, evaluation in runs]


def oracle(cell: Path, seeds: str, episodes: int) -> list[float]:
    """The oracle's share of layouts per replicate, searched in the macro space of the cell's runs."""
    out = cell.with_name(cell.name + "-oracle")
    famarl("oracle", "--run", str(cell), "--layouts", str(episodes), "--out", str(out))
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
    parser.add_argument("--tasks", help="RobotHand tasks, as their ids end [default: the pipeline's].")
    parser.add_argument("--env-kwargs", default="{}", help="The env's keyword arguments, as JSON (gymnasium.make).")
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
    known = {env_id.removeprefix("famarl/RobotHand-"): env_id for env_id in ROBOT_HAND_IDS.values()}
    tasks = _choices(args.tasks or params["tasks"], known, "--tasks")
    kwargs = env_kwargs(args.env_kwargs)
    for task in tasks:  # made once here, so that a setting the env refuses stops the run before any work
        try:
            make_env(known[task], kwargs).close()
        except FamarlError as exc:
            raise SystemExit(f"error: {exc}") from None
    setting, slug = kwargs_text(kwargs), kwargs_slug(kwargs)
    line = command_line(__file__, parser, args, shown=("seeds", "demos", "discounts"), hidden=("out", "data"))
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
                cell = args.data / "robothand-demos" / demos / f"{task}{slug}-{discount}{changed}"
                rates = success(cell, task, discount, favaes, args.seeds, train, kwargs)
                interval = mean_interval(rates, EPISODES)
                rows[f"{demos}/{task}{slug}/{discount}{changed}"] = {"success": rates, "interval": interval.text()}
                record(
                    f"robothand_demos_{demos}_{task}{slug}_{discount}{changed}".replace("-", "_")
                    .replace(".", "_")
                    .lower(),
                    f"RobotHand-{task}{setting}, FaMARL with macros from {DEMOS[demos]}, {DISCOUNTS[discount]}, "
                    f"{budget}: success of the sampled policy over {EPISODES} layouts, replicates {args.seeds}; "
                    "mean [95% CI]",
                    line,
                    interval.text(),
                )
            if args.oracle_episodes and (slug or not changed):  # the search uses no policy and no budget
                cell = args.data / "robothand-demos" / demos / f"{task}{slug}-{discounts[0]}{changed}"
                shares = oracle(cell, args.seeds, args.oracle_episodes)
                interval = mean_interval(shares, args.oracle_episodes)
                rows[f"{demos}/{task}{slug}/oracle"] = {"shares": shares, "interval": interval.text()}
                record(
                    f"robothand_demos_{demos}_{task}{slug}_oracle".replace("-", "_").lower(),
                    f"RobotHand-{task}{setting}: share of layouts an open-loop plan of macros from {DEMOS[demos]} "
                    f"solved (famarl oracle, lower bound), replicates {args.seeds}, {args.oracle_episodes} layouts "
                    "each; mean [95% CI]",
                    line,
                    interval.text(),
                )
    write_result(args.out, {"command": line, "rows": rows})
    for name, row in rows.items():
        print(f"{name:<40} {row['interval']:<20} {row.get('success', row.get('shares'))}")


if __name__ == "__main__":
    main()
