"""PPO's gradient by autograd against the written-out gradient it replaced, on the default pipeline's training: the
rule is to keep a hand-written path only where the derived one is more than 1.2x slower there.

    python benchmarks/ppo_gradient.py [--steps 100000] [--seeds 0-4] [--favae data/maze/macros/seed{seed}/favae.pt]
        [--baseline JSON] [--out benchmarks/results/ppo_gradient.json]

The default pipeline's train stage trains each agent's 10 seeds in 2 batches of 5, one batched network a batch
(``train_together``, `famarl train`'s defaults, the Maze). This trains one such batch of each agent for ``--steps``
env steps per seed on one core and reports env steps per second of the batch. Run it once on a revision with the
written-out gradient (the last: 98d71ea) and once on this one with ``--baseline`` naming the first's JSON: the
record is each agent's rate on both and the ratio of the summed times.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import torch
from common import RESULTS, command_line, record, rounded, seed_list, step_count, verdict, write_result

from famarl_cli.rl import Agent
from famarl_cli.stages.train import TrainOptions, run_spec

AGENTS = ("ppo", "figar", "famarl")
GATE = 1.2
"""The derived gradient stays unless it makes the training this many times slower."""


def batch_rate(agent: Agent, seeds: list[int], steps: int, favae: str) -> dict:
    from famarl_cli.rl.training import Run, train_together

    path = Path(favae.format(seed=seeds[0])) if agent.decodes_macros else None
    runs = []
    for seed in seeds:
        options = TrainOptions(agent=agent, steps=steps, favae=None if path is None else Path(favae.format(seed=seed)))
        runs.append(Run.start(replace(run_spec(options), seed=seed)))
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        train_together(runs, [Path(folder) / f"seed{seed}" for seed in seeds], 20)
        seconds = time.perf_counter() - start
    env_steps = sum(run.trainer.members[run.member].env_steps for run in runs)
    return {"agent": str(agent), "seconds": seconds, "env_steps": env_steps, "env_steps_per_s": env_steps / seconds}


def read_baseline(path: Path) -> dict:
    """This script's JSON from the revision compared against, with a row of every agent; else one ``error:`` line."""
    try:
        text = path.read_text()
    except OSError as exc:
        raise SystemExit(f"error: --baseline {path}: {exc.strerror or exc}") from None
    try:
        baseline = json.loads(text)
        found = {row["agent"] for row in baseline["rows"] if row["seconds"] > 0}
    except (ValueError, KeyError, TypeError) as exc:
        raise SystemExit(f"error: --baseline {path}: not this script's JSON ({type(exc).__name__}: {exc})") from None
    missing = [agent for agent in AGENTS if agent not in found]
    if missing:
        raise SystemExit(f"error: --baseline {path}: no timed row of {', '.join(missing)}")
    return baseline


def records(rows: list[dict], baseline: dict, steps: int, seeds: list[int], command: str) -> dict[str, dict]:
    """measured.json's entry: each agent's rate with the written-out gradient and with autograd, and the gate."""
    theirs = {row["agent"]: row for row in baseline["rows"]}
    ratio = sum(row["seconds"] for row in rows) / sum(theirs[row["agent"]]["seconds"] for row in rows)
    rates = ", ".join(
        f"{row['agent']} {theirs[row['agent']]['env_steps_per_s']:,.0f} -> {row['env_steps_per_s']:,.0f}"
        for row in rows
    )
    return {
        "ppo_gradient": {
            "what": f"the default pipeline's training, {len(seeds)} seeds together x {step_count(steps)} env steps "
            f"per agent on one core: env steps/s with the written-out gradient ({baseline['revision']}) -> by "
            "autograd, and the time of all three, autograd over written out",
            "command": command,
            "measured": f"{rates}; {rounded(ratio)}x the time{verdict(ratio <= GATE)}",
            "target": f"<= {GATE}x (else the written-out gradient stays)",
            "values": {
                **{f"{row['agent']}_before": theirs[row["agent"]]["env_steps_per_s"] for row in rows},
                **{row["agent"]: row["env_steps_per_s"] for row in rows},
                "time_ratio": ratio,
            },
            "unit": {
                **{f"{row['agent']}{after}": "env steps/s" for row in rows for after in ("_before", "")},
                "time_ratio": "x",
            },
            "better": {"time_ratio": "lower"},
        }
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=100_000)
    parser.add_argument("--seeds", default="0-4")
    parser.add_argument("--favae", default="data/maze/macros/seed{seed}/favae.pt")
    parser.add_argument("--baseline", type=Path, help="this script's JSON from the revision to compare against")
    parser.add_argument("--revision", default="", help="the revision this run measures (stored in its JSON)")
    parser.add_argument("--out", type=Path, default=RESULTS / "ppo_gradient.json")
    args = parser.parse_args()
    if args.steps < 1:
        raise SystemExit("error: --steps must be at least 1")
    torch.set_num_threads(1)
    seeds = seed_list(args.seeds)
    if not Path(args.favae.format(seed=seeds[0])).exists():
        raise SystemExit(f"error: no FAVAE at {args.favae.format(seed=seeds[0])} (run `dvc repro macros` first)")
    baseline = None if args.baseline is None else read_baseline(args.baseline)
    rows = []
    for name in AGENTS:
        rows.append(batch_rate(Agent(name), seeds, args.steps, args.favae))
        print(f"{name:<8} {rows[-1]['env_steps_per_s']:>10,.0f} env steps/s  ({rows[-1]['seconds']:.1f} s)", flush=True)
    write_result(args.out, {"steps": args.steps, "seeds": seeds, "revision": args.revision, "rows": rows})
    if baseline is not None:
        for name, entry in records(rows, baseline, args.steps, seeds, command_line(__file__, parser, args)).items():
            record(name, **entry)


if __name__ == "__main__":
    main()
