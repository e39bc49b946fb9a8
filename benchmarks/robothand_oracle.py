"""Can RobotHand's action spaces solve its tasks at all? ``famarl oracle`` on the committed robothand runs of the
given replicates, FaMARL's pegging macros, FiGAR's repeated actions and PPO's actions on Reaching and BallPlacing,
and the share of layouts a plan solved per space and task, with its 95% interval over replicates.

    python benchmarks/robothand_oracle.py [--seeds 0-2] [--episodes 10] [--jobs 2] [--data data]

Needs ``dvc repro pipelines/robothand/dvc.yaml`` first (its runs). Each share is a lower bound of what the space
can reach (the search is finite; docs/robothand.md). Run it alone (one CPU-heavy job at a time): it uses --jobs
cores. Records one row per task and agent in benchmarks/measured.json (docs/robothand.md shows them) and writes
benchmarks/results/robothand_oracle.json.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import RESULTS, ROOT, command_line, record, write_result

from famarl_cli.core.statistics import mean_interval
from famarl_cli.sweep.plan import parse_values

TASKS, AGENTS = ("Reaching-v1", "BallPlacing-v0"), ("famarl", "figar", "ppo")
"""The pipeline's tasks, as its run folders name them."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", default="0-2", help="Replicates whose runs are searched.")
    parser.add_argument("--episodes", type=int, default=10, help="Layouts per run.")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--data", type=Path, default=ROOT / "data")
    parser.add_argument("--out", type=Path, default=RESULTS / "robothand_oracle.json")
    args = parser.parse_args()
    seeds = [int(s) for s in parse_values(args.seeds)]
    runs = [args.data / "robothand/runs" / f"{t}-{a}-seed{s}" for t in TASKS for a in AGENTS for s in seeds]
    if missing := [run for run in runs if not (run / "run.json").is_file()]:
        parser.error(f"{missing[0]} is not a run folder: dvc repro pipelines/robothand/dvc.yaml first")
    with tempfile.TemporaryDirectory() as folder:
        options = ["--episodes", str(args.episodes), "--jobs", str(args.jobs), "--out", folder]
        command = [sys.executable, "-m", "famarl_cli", "oracle", *[a for run in runs for a in ("--run", str(run))]]
        start = time.perf_counter()
        subprocess.run([*command, *options], check=True, env={**os.environ, "OMP_NUM_THREADS": "1"})
        wall = time.perf_counter() - start
        found = {run.name: json.loads((Path(folder) / run.name / "oracle.json").read_text()) for run in runs}
    line = command_line(
        "robothand_oracle.py", parser, args, shown=("seeds", "episodes", "jobs"), hidden=("out", "data")
    )
    rows = {}
    for task in TASKS:
        for agent in AGENTS:
            shares = [found[f"{task}-{agent}-seed{s}"]["success_rate"] for s in seeds]
            interval = mean_interval(shares, args.episodes)
            rows[f"{task}-{agent}"] = {"shares": shares, "mean": interval.estimate, "interval": interval.text()}
            record(
                f"robothand_oracle_{task.lower().replace('-', '_')}_{agent}",
                f"RobotHand {task}: share of layouts an open-loop plan in {agent}'s action space solved (famarl "
                f"oracle, lower bound), replicates {args.seeds}, {args.episodes} layouts each; mean over replicates "
                "[95% CI]",
                line,
                interval.text(),
            )
    per_layout = wall * args.jobs / (len(runs) * args.episodes)
    record(
        "robothand_oracle_wall",
        "famarl oracle's core-seconds per layout, every RobotHand run above together (successes stop early)",
        line,
        f"{per_layout:.1f} s",
    )
    write_result(args.out, {"command": line, "wall_s": round(wall, 1), "rows": rows})
    for name, row in rows.items():
        print(f"{name:<22} {row['interval']}  {row['shares']}")


if __name__ == "__main__":
    main()
