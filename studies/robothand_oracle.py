"""Can RobotHand's action spaces solve its tasks at all? ``famarl oracle`` on the committed robothand runs of the
given replicates, FaMARL's pegging macros, FiGAR's repeated actions and PPO's actions on Reaching and BallPlacing
(``famarl-ours``: the pipeline's FaMARL beyond the paper, with the macros of the raised-basket demos), and the share
of layouts a plan solved per space and task, with its 95% interval over replicates.

    python studies/robothand_oracle.py [--seeds 0-2] [--episodes 10] [--jobs 2] [--data data]
        [--tasks Reaching-v1,BallPlacing-v0] [--agents famarl,figar,ppo] [--candidates 64] [--iterations 4]

Needs ``dvc repro pipelines/robothand/dvc.yaml`` first (its runs). Each share is a lower bound of what the space
can reach (the search is finite; docs/robothand.md): --candidates and --iterations above the pipeline's (64 and 4)
say whether a larger search finds more. Run it alone (one CPU-heavy job at a time): it uses --jobs cores. Records
one row per task and agent in studies/measured.json (docs/robothand.md shows them) and writes
studies/results/robothand_oracle.json (robothand_oracle_CxI.json for a search of C plans x I iterations).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from study import RESULTS, ROOT, command_line, record, seed_list, write_result

from famarl_cli.artifacts.runs import ORACLE_FILE, read_oracle
from famarl_cli.core.statistics import mean_interval

TASKS = ("Reaching-v1", "BallPlacing-v0")
"""The pipeline's tasks, as its run folders name them."""
RUNS = {agent: f"robothand/runs/{{task}}-{agent}-seed{{seed}}" for agent in ("famarl", "figar", "ppo")}
RUNS["famarl-ours"] = "robothand/ours/runs/{task}-famarl-ours-seed{seed}"
"""Each agent's run folders in the pipeline's data, by label."""
SEARCH = {"candidates": 64, "iterations": 4}
"""The pipeline's search (famarl oracle's defaults)."""


def pipeline_runs(data: Path, tasks: list[str], agents: list[str], seeds: list[int]) -> dict[tuple, Path]:
    """The pipeline's run folder of each (task, agent, seed) under ``data``; an unknown task or agent, or a folder
    that holds no run, ends the benchmark in one error line."""
    if unknown := [t for t in tasks if t not in TASKS] + [a for a in agents if a not in RUNS]:
        raise SystemExit(
            f"error: unknown task or agent {', '.join(unknown)} (tasks: {', '.join(TASKS)}; agents: {', '.join(RUNS)})"
        )
    runs = {(t, a, s): data / RUNS[a].format(task=t, seed=s) for t in tasks for a in agents for s in seeds}
    if missing := [run for run in runs.values() if not (run / "run.json").is_file()]:
        raise SystemExit(f"error: {missing[0]} is not a run folder: dvc repro pipelines/robothand/dvc.yaml first")
    return runs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", default="0-2", help="Replicates whose runs are searched.")
    parser.add_argument("--episodes", type=int, default=10, help="Layouts per run.")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--data", type=Path, default=ROOT / "data")
    parser.add_argument("--out", type=Path, default=None, help="[default: results/robothand_oracle[_CxI].json]")
    parser.add_argument("--tasks", default=",".join(TASKS), help="The pipeline's tasks to search.")
    parser.add_argument("--agents", default="famarl,figar,ppo", help=f"Action spaces, of {', '.join(RUNS)}.")
    parser.add_argument("--candidates", type=int, default=SEARCH["candidates"], help="Plans per iteration.")
    parser.add_argument("--iterations", type=int, default=SEARCH["iterations"], help="Iterations per layout.")
    args = parser.parse_args()
    seeds = seed_list(args.seeds)
    if args.episodes < 1 or args.candidates < 2 or args.iterations < 1:
        raise SystemExit("error: --episodes and --iterations must be at least 1, --candidates at least 2")
    tasks, agents = args.tasks.split(","), args.agents.split(",")
    runs = pipeline_runs(args.data, tasks, agents, seeds)
    search = {"candidates": args.candidates, "iterations": args.iterations}
    # the pipeline's search keeps its records' names; a larger one is a row of its own beside them
    larger = "" if search == SEARCH else f"_{args.candidates}x{args.iterations}"
    out = args.out or RESULTS / f"robothand_oracle{larger}.json"
    with tempfile.TemporaryDirectory() as folder:
        options = ["--layouts", str(args.episodes), "--jobs", str(args.jobs), "--out", folder]
        options += ["--candidates", str(args.candidates), "--iterations", str(args.iterations)]
        command = [sys.executable, "-m", "famarl_cli", "oracle"]
        command += [a for run in runs.values() for a in ("--run", str(run))]
        start = time.perf_counter()
        subprocess.run([*command, *options], check=True, env={**os.environ, "OMP_NUM_THREADS": "1"})
        wall = time.perf_counter() - start
        found = {key: read_oracle(Path(folder) / run.name / ORACLE_FILE) for key, run in runs.items()}
    line = command_line(__file__, parser, args, shown=("seeds", "episodes", "jobs"), hidden=("out", "data"))

    budget = "" if search == SEARCH else f", {args.candidates} plans x {args.iterations} iterations"
    rows = {}
    for task in tasks:
        for agent in agents:
            shares = [found[(task, agent, s)]["success_rate"] for s in seeds]
            interval = mean_interval(shares, args.episodes)
            rows[f"{task}-{agent}"] = {"shares": shares, "mean": interval.estimate, "interval": interval.text()}
            record(
                f"robothand_oracle_{task.lower().replace('-', '_')}_{agent.replace('-', '_')}{larger}",
                f"RobotHand {task}: share of layouts an open-loop plan in {agent}'s action space solved (famarl "
                f"oracle{budget}, lower bound), replicates {args.seeds}, {args.episodes} layouts each; mean over "
                "replicates [95% CI]",
                line,
                interval.text(),
            )
    per_layout = wall * args.jobs / (len(runs) * args.episodes)
    record(
        f"robothand_oracle_wall{larger}",
        f"famarl oracle's core-seconds per layout{budget}, every RobotHand run above together (successes stop early)",
        line,
        f"{per_layout:.1f} s",
    )
    write_result(out, {"command": line, "wall_s": round(wall, 1), "rows": rows})
    for name, row in rows.items():
        print(f"{name:<22} {row['interval']}  {row['shares']}")


if __name__ == "__main__":
    main()
