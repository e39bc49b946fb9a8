"""Seeds trained together in one process (one batched network, PureJaxRL's idea) against the same seeds each alone.

    python benchmarks/batched_seeds.py [--steps 100000] [--seeds 0-4] [--agents ppo figar famarl] [--favae PT]
        [--out benchmarks/results/batched_seeds.json]

For each agent, the seeds are trained one after another alone (``Run.train``) and then as one batch
(``train_together``), on one core, with `famarl train`'s defaults on the Maze; the figure is env steps per second
of all seeds over the time they took. FaMARL needs a FAVAE (``--favae``, else it is left out). Results in
benchmarks/results/batched_seeds.json (or ``--out``).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import torch
from common import RESULTS, command_line, record, step_count, write_result

from famarl_cli.rl import Agent
from famarl_cli.stages.train import TrainOptions, run_spec
from famarl_cli.sweep.plan import parse_values


def runs(agent: Agent, seeds: list[int], steps: int, favae: Path | None):
    from famarl_cli.rl.training import Run

    spec = run_spec(TrainOptions(agent=agent, steps=steps, favae=favae))
    return [Run.start(replace(spec, seed=seed)) for seed in seeds]


NAMES = {"ppo": "PPO", "figar": "FiGAR", "famarl": "FaMARL"}


def records(steps: int, seeds: list[int], rows: list[dict], command: str) -> dict[str, dict]:
    """measured.json's entry: each agent's speed-up of its seeds trained together over each seed alone (x, by
    agent)."""
    speedups = ", ".join(
        f"{NAMES.get(row['agent'], row['agent'])} {row['alone_s'] / row['together_s']:.2f}x" for row in rows
    )
    return {
        "batched_seeds": {
            "what": f"{len(seeds)} seeds x {step_count(steps)} env steps on one core (`famarl train` defaults, Maze), "
            "trained together in one process against each alone",
            "command": command,
            "measured": speedups or "no agent ran",
            "values": {row["agent"]: row["alone_s"] / row["together_s"] for row in rows},
            "unit": "x",
            "better": "higher",
        }
    }


def main() -> None:
    from famarl_cli.rl.training import train_together

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=100_000)
    parser.add_argument("--seeds", default="0-4")
    parser.add_argument("--agents", nargs="+", default=["ppo", "figar", "famarl"])
    parser.add_argument("--favae", type=Path)
    parser.add_argument("--out", type=Path, default=RESULTS / "batched_seeds.json")
    args = parser.parse_args()
    torch.set_num_threads(1)
    seeds = [int(s) for s in parse_values(args.seeds)]
    rows = []
    print(f"{'agent':<8} {'seeds':>5} {'alone (s)':>10} {'together (s)':>13} {'speed-up':>9} {'env steps/s':>12}")
    for name in args.agents:
        agent = Agent(name)
        if agent.decodes_macros and args.favae is None:
            print(f"{name:<8} left out: give --favae")
            continue
        with tempfile.TemporaryDirectory() as folder:
            alone, together = (runs(agent, seeds, args.steps, args.favae) for _ in range(2))
            start = time.perf_counter()
            for k, run in enumerate(alone):
                run.train(Path(folder) / f"a{k}", 20)
            alone_s = time.perf_counter() - start
            start = time.perf_counter()
            train_together(together, [Path(folder) / f"t{k}" for k in range(len(seeds))], 20)
            together_s = time.perf_counter() - start
        steps = sum(run.own.env_steps for run in together)
        row = {"agent": name, "seeds": len(seeds), "alone_s": alone_s, "together_s": together_s, "env_steps": steps}
        rows.append(row)
        print(
            f"{name:<8} {len(seeds):>5} {alone_s:>10.1f} {together_s:>13.1f} {alone_s / together_s:>8.2f}x "
            f"{steps / together_s:>12,.0f}"
        )
    write_result(args.out, {"steps": args.steps, "seeds": seeds, "rows": rows})
    for name, entry in records(args.steps, seeds, rows, command_line(__file__, parser, args)).items():
        record(name, **entry)


if __name__ == "__main__":
    main()
