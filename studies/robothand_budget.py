"""Why FaMARL did not learn RobotHand Reaching: its budget in PPO updates. FaMARL trained on Reaching with the
pipeline's pegging macros under a few budgets and learning rates, and the success of its sampled policy, with a
95% interval over replicates.

    dvc repro pipelines/robothand/dvc.yaml               # data/robothand/macros/seed*/favae.pt
    python studies/robothand_budget.py [--seeds 0-4] [--settings 300k,1M,1M-lr1e-3,3M,3M-semi-mdp]

The budget is counted in environment steps, as for every agent, but a macro action runs about 30 of them, so at
300k env steps FaMARL makes about 10k decisions and, at 16 envs x 16 decisions a rollout, about 40 PPO updates,
with its learning rate annealed to zero over them; PPO on primitive actions makes 30 times as many decisions from
the same budget. Each setting is a ``famarl sweep train`` over the seeds (seed S decodes with replicate S's FAVAE)
into data/robothand-budget/<setting>, evaluated like the pipeline's runs (100 layouts from seed 100, sampled
policy); finished runs are reused. Records one row per setting in studies/measured.json (docs/robothand.md
shows them) and writes studies/results/robothand_budget.json. Run it alone: it uses both cores.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from study import RESULTS, ROOT, command_line, record, seed_list, train_and_evaluate, write_result

from famarl_cli.artifacts.runs import read_run_file
from famarl_cli.core.statistics import mean_interval
from famarl_cli.report.experiments.robothand import REACHING

SETTINGS = {
    "300k": ["--steps", "300000"],
    "1M": ["--steps", "1000000"],
    "1M-lr1e-3": ["--steps", "1000000", "--lr", "0.001"],
    "3M": ["--steps", "3000000"],
    "3M-semi-mdp": ["--steps", "3000000", "--macro-discount", "steps"],
}
"""Each setting's options beside the pipeline's (300k: its budget until Reaching-v1; 1M-lr1e-3: its budget now;
pipelines/macro-length runs 1M-lr1e-3 under semi-MDP discounting; 3M: three times the budget under the paper's
per-decision discount and under semi-MDP discounting, ours)."""
EPISODES, EVALUATION_SEED = 100, 100


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", default="0-4", help="Replicates (FAVAE and RL seed).")
    parser.add_argument("--settings", default=",".join(SETTINGS), help=f"Of {', '.join(SETTINGS)}.")
    parser.add_argument("--data", type=Path, default=ROOT / "data")
    parser.add_argument("--out", type=Path, default=RESULTS / "robothand_budget.json")
    args = parser.parse_args()
    settings = args.settings.split(",")
    if unknown := [s for s in settings if s not in SETTINGS]:
        raise SystemExit(f"error: unknown setting {unknown[0]!r} (known: {', '.join(SETTINGS)})")
    seeds = seed_list(args.seeds)
    if missing := [s for s in seeds if not (args.data / f"robothand/macros/seed{s}/favae.pt").is_file()]:
        raise SystemExit(
            f"error: no pegging FAVAE of replicate {missing[0]} in {args.data}/robothand/macros: dvc repro "
            "pipelines/robothand/dvc.yaml first"
        )
    line = command_line(__file__, parser, args, shown=("seeds", "settings"), hidden=("out", "data"))
    rows = {}
    for setting in settings:
        favae = str(args.data / "robothand/macros/seed{seed}/favae.pt")
        options = ["--env", REACHING, "--agent", "famarl", "--favae", favae, "--label", f"famarl-{setting}"]
        out = args.data / "robothand-budget" / setting
        runs = train_and_evaluate(out, args.seeds, [*options, *SETTINGS[setting]], EPISODES, EVALUATION_SEED)
        success = [float(evaluation["success_rate"]) for _, evaluation in runs]
        updates = [int(read_run_file(run)["updates"]) for run, _ in runs]
        interval = mean_interval(success, EPISODES)
        rows[setting] = {"success": success, "updates": updates, "interval": interval.text()}
        record(
            f"robothand_budget_{setting}".replace("-", "_"),
            f"{REACHING.removeprefix('famarl/')}, FaMARL (pegging macros) at {' '.join(SETTINGS[setting])}: success "
            f"of the sampled policy over {EPISODES} layouts, replicates {args.seeds} ({min(updates)}-{max(updates)} "
            "PPO updates each); mean [95% CI]",
            line,
            interval.text(),
        )
    write_result(args.out, {"command": line, "rows": rows})
    for setting, row in rows.items():
        print(f"{setting:<20} {row['interval']:<20} updates {row['updates']}  {row['success']}")


if __name__ == "__main__":
    main()
