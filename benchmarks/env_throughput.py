"""Environment throughput in env steps per second: ContinuousWorld single and batched, RobotHand single and in a
gymnasium batch (the loop that trains on it).

    python benchmarks/env_throughput.py [--seconds 2] [--robot-hand-only] [--out benchmarks/results/env_throughput.json]
    python benchmarks/env_throughput.py --against [REV] [--rounds 3] [--seconds 2]

Each measurement steps random actions for about ``--seconds`` (after a short warm-up) and counts every
world's step, resets included. Prints a table and writes the numbers as JSON. ``--robot-hand-only`` measures
RobotHand's rows alone and records nothing in measured.json, whose entries need every row.

``--against REV`` measures RobotHand's single envs alone, as the package at git revision REV steps them and as this
checkout's does, each in an interpreter of its own, the two taking turns for ``--rounds`` rounds (each keeps its
fastest), and records this checkout's rate per core over REV's. REV defaults to the code before RobotHand's step was
rewritten, against which its target of three times the rate is set.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
from common import (
    RESULTS,
    ROOT,
    checked_out,
    command_line,
    fastest_in_turns,
    peak_rss_mib,
    rate,
    record,
    rounded,
    single_env_rate,
    verdict,
    write_result,
)

from famarl_cli.core.declare import default_of
from famarl_cli.envs import ENV_IDS
from famarl_cli.envs.batched import ContinuousWorldBatch
from famarl_cli.envs.vector import GymBatch
from famarl_cli.rl.options import PPOOptions

ROBOT_HANDS = ("robot-hand-base", "robot-hand-reaching", "robot-hand-ball-placing")
HAND_BATCH = default_of(PPOOptions, "n_envs")
"""RobotHand envs in the gymnasium batch measured: training's default --n-envs."""
BEFORE = "332e638^"
"""The code whose RobotHand step went through pymunk's properties and numpy on 2-vectors: RobotHand's rate per core
is set at three times its rate (docs/performance.md)."""
TARGET = 3.0
# Run as ``python -c`` in the measured checkout, with it first on the path: it imports nothing of this checkout's
# package, which the older one lacks, but its env ids and benchmarks/common.py; it says which package it stepped.
CHILD = (
    "import json, sys, famarl_cli; from common import single_env_rate; from famarl_cli.envs import ENV_IDS; "
    "print(json.dumps({'package': famarl_cli.__file__, "
    "'rates': {t: single_env_rate(ENV_IDS[t], float(sys.argv[1])) for t in sys.argv[2:]}}))"
)


def batched_env(task: str, n_envs: int, seconds: float) -> float:
    batch = ContinuousWorldBatch(task, n_envs=n_envs, seed=0)
    actions = np.random.default_rng(0).uniform(-1, 1, (8, n_envs, 2))
    counter = iter(range(1 << 62))
    return rate(lambda: batch.step(actions[next(counter) % 8]), n_envs, seconds)


def gym_batch(env_id: str, n_envs: int, seconds: float) -> float:
    """Steps per second of ``n_envs`` envs in famarl's gymnasium batch, which resets each as its episode ends."""
    batch = GymBatch.make(env_id, n_envs, seed=0)
    batch.reset()
    # as many distinct actions per env as single_env_rate's: a short cycle of them pins the hand against things, whose
    # contacts cost the physics more
    actions = np.random.default_rng(0).uniform(-1, 1, (1024, n_envs, *batch.envs[0].action_space.shape))
    counter = iter(range(1 << 62))
    return rate(lambda: batch.step(actions[next(counter) % 1024]), n_envs, seconds)


def records(rows: list[tuple[str, str, int, float]], command: str) -> dict[str, dict]:
    """measured.json's entries from the rows: the Maze's batched worlds, and its single env with RobotHand's."""
    rates = {(task, kind, n_envs): per_s for task, kind, n_envs, per_s in rows}
    batched = [rates["maze", "batched", n] for n in (1, 64, 1024)]
    hands = [rates[task, "single (gym.make)", 1] for task in ROBOT_HANDS]
    batches = [rates[task, "gymnasium batch", HAND_BATCH] for task in ROBOT_HANDS]
    return {
        "env_throughput_batched": {
            "what": "ContinuousWorld Maze, batched, 1 / 64 / 1024 worlds",
            "command": command,
            "measured": f"{rounded(batched[0])} / {rounded(batched[1])} / **{rounded(batched[2])}** env steps/s"
            + verdict(batched[2] >= 1_000_000),
            "target": ">= 1,000,000 at 1024",
            "values": {f"worlds_{n}": per_s for n, per_s in zip((1, 64, 1024), batched, strict=True)},
            "unit": "env steps/s",
        },
        "env_throughput_single": {
            "what": "ContinuousWorld Maze, single env (`gym.make`); RobotHand Base / Reaching / BallPlacing, single "
            f"env (pymunk), and {HAND_BATCH} in a gymnasium batch (as training steps them)",
            "command": command,
            "measured": f"{rounded(rates['maze', 'single (gym.make)', 1])} env steps/s; RobotHand "
            + " / ".join(rounded(per_s) for per_s in hands)
            + f" env steps/s; {HAND_BATCH} in a batch "
            + " / ".join(rounded(per_s) for per_s in batches)
            + " env steps/s",
            "values": {
                "maze": rates["maze", "single (gym.make)", 1],
                **dict(zip(ROBOT_HANDS, hands, strict=True)),
                **{f"{task} batch": per_s for task, per_s in zip(ROBOT_HANDS, batches, strict=True)},
            },
            "unit": "env steps/s",
        },
    }


def hand_rates(tree: Path, seconds: float) -> dict[str, float]:
    """RobotHand's single-env rates (:data:`ROBOT_HANDS`) as the package checked out at ``tree`` steps them, in an
    interpreter of its own on one torch thread."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tree), str(Path(__file__).parent)]), "OMP_NUM_THREADS": "1"}
    done = subprocess.run(
        [sys.executable, "-W", "ignore", "-c", CHILD, str(seconds), *ROBOT_HANDS],
        cwd=tree,
        env=env,
        capture_output=True,
        text=True,
    )
    if done.returncode:
        lines = done.stderr.strip().splitlines() or ["no message"]
        raise SystemExit(f"error: RobotHand's rates at {tree}: {lines[-1]}")
    measured = json.loads(done.stdout.splitlines()[-1])
    # an installed famarl found first would measure the same code on both sides
    if not Path(measured["package"]).resolve().is_relative_to(tree.resolve()):
        raise SystemExit(f"error: RobotHand's rates at {tree} stepped the package at {measured['package']}")
    return measured["rates"]


def against(revision: str, rounds: int, seconds: float) -> dict[str, dict[str, float]]:
    """RobotHand's single-env rates of ``revision``'s package and of this checkout's, taking turns for ``rounds``
    rounds, each side's fastest per task: ``{"before": {task: rate}, "now": {task: rate}}``."""
    with checked_out(revision) as tree:
        where = {"before": tree, "now": ROOT}
        return fastest_in_turns(where, lambda side: hand_rates(where[side], seconds), rounds)


def against_record(revision: str, best: dict[str, dict[str, float]], command: str) -> dict:
    """measured.json's entry of :func:`against`'s rates: this checkout's over ``revision``'s, per task."""
    ratios = {task: best["now"][task] / best["before"][task] for task in ROBOT_HANDS}
    return {
        "what": f"RobotHand Base / Reaching / BallPlacing, single env (`gym.make`), per core, against {revision}'s "
        "code measured in turn in the same run",
        "command": command,
        "measured": " / ".join(rounded(best["now"][task]) for task in ROBOT_HANDS)
        + " against "
        + " / ".join(rounded(best["before"][task]) for task in ROBOT_HANDS)
        + " env steps/s: **"
        + " / ".join(f"{ratio:.2f}x" for ratio in ratios.values())
        + "**"
        + verdict(min(ratios.values()) >= TARGET),
        "target": f">= {TARGET:g}x {revision}'s, every task",
        "values": ratios,
        "unit": "x",
        "better": "higher",
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument("--robot-hand-only", action="store_true", help="RobotHand's rows alone, unrecorded")
    parser.add_argument(
        "--against",
        nargs="?",
        const=BEFORE,
        metavar="REV",
        help=f"RobotHand's single envs alone, against git revision REV's (default {BEFORE}, the code before its step "
        "was rewritten), recorded as this checkout's rate over REV's",
    )
    parser.add_argument("--rounds", type=int, default=3, help="with --against: turns each side takes (default 3)")
    parser.add_argument(
        "--out",
        type=Path,
        help="the JSON result (default benchmarks/results/env_throughput.json, or "
        "env_throughput_against.json with --against)",
    )
    args = parser.parse_args()
    if args.rounds < 1 or not 0 < args.seconds < float("inf"):
        raise SystemExit("error: --rounds must be at least 1 and --seconds a finite number above 0")
    if args.against is not None:
        best = against(args.against, args.rounds, args.seconds)
        print(f"{'task':<24} {args.against:>14} {'this checkout':>14} {'ratio':>7}")
        for task in ROBOT_HANDS:
            before, now = best["before"][task], best["now"][task]
            print(f"{task:<24} {before:>14,.0f} {now:>14,.0f} {now / before:>6.2f}x")
        write_result(
            args.out or RESULTS / "env_throughput_against.json",
            {"against": args.against, "rounds": args.rounds, "seconds": args.seconds, **best},
        )
        record(
            "env_throughput_robot_hand_against",
            **against_record(args.against, best, command_line(__file__, parser, args, shown=("against",))),
        )
        return

    rows = []
    for task in () if args.robot_hand_only else ("base", "maze"):
        rows.append((task, "single (gym.make)", 1, single_env_rate(ENV_IDS[task], args.seconds)))
        rows.append((task, "single (unwrapped)", 1, single_env_rate(ENV_IDS[task], args.seconds, unwrapped=True)))
        for n_envs in (1, 64, 1024):
            rows.append((task, "batched", n_envs, batched_env(task, n_envs, args.seconds)))
    for task in ROBOT_HANDS:
        rows.append((task, "single (gym.make)", 1, single_env_rate(ENV_IDS[task], args.seconds)))
        rows.append((task, "gymnasium batch", HAND_BATCH, gym_batch(ENV_IDS[task], HAND_BATCH, args.seconds)))

    print(f"{'task':<24} {'env':<20} {'worlds':>7} {'env steps/s':>14}")
    for task, kind, n_envs, per_s in rows:
        print(f"{task:<24} {kind:<20} {n_envs:>7} {per_s:>14,.0f}")
    print(f"peak RSS {peak_rss_mib():.0f} MiB")
    write_result(
        args.out or RESULTS / "env_throughput.json",
        {
            "seconds_per_measurement": args.seconds,
            "rows": [{"task": t, "env": k, "worlds": n, "env_steps_per_s": round(r)} for t, k, n, r in rows],
        },
    )
    if not args.robot_hand_only:
        for name, entry in records(rows, command_line(__file__, parser, args)).items():
            record(name, **entry)


if __name__ == "__main__":
    main()
