"""Environment throughput in env steps per second: ContinuousWorld single and batched, RobotHand single and in a
gymnasium batch (the loop that trains on it).

    python benchmarks/env_throughput.py [--seconds 2] [--robot-hand-only] [--out benchmarks/results/env_throughput.json]

Each measurement steps random actions for about ``--seconds`` (after a short warm-up) and counts every
world's step, resets included. Prints a table and writes the numbers as JSON. ``--robot-hand-only`` measures
RobotHand's rows alone and records nothing in measured.json, whose entries need every row.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import numpy as np
from common import RESULTS, command_line, peak_rss_mib, rate, record, rounded, verdict, write_result

from famarl_cli.core.declare import default_of
from famarl_cli.envs import ENV_IDS
from famarl_cli.envs.batched import ContinuousWorldBatch
from famarl_cli.envs.vector import GymBatch
from famarl_cli.rl.options import PPOOptions

ROBOT_HANDS = ("robot-hand-base", "robot-hand-reaching", "robot-hand-ball-placing")
HAND_BATCH = default_of(PPOOptions, "n_envs")
"""RobotHand envs in the gymnasium batch measured: training's default --n-envs."""


def single_env(env_id: str, seconds: float, unwrapped: bool) -> float:
    env = gym.make(env_id)
    if unwrapped:
        env = env.unwrapped
    env.reset(seed=0)
    actions = np.random.default_rng(0).uniform(-1, 1, (1024, *env.action_space.shape)).astype(np.float32)
    counter = iter(range(1 << 62))
    limit = gym.spec(env_id).max_episode_steps
    elapsed = [0]

    def step():
        _, _, terminated, truncated, _ = env.step(actions[next(counter) % 1024])
        elapsed[0] += 1
        if terminated or truncated or elapsed[0] >= limit:
            env.reset()
            elapsed[0] = 0

    return rate(step, 1, seconds)


def batched_env(task: str, n_envs: int, seconds: float) -> float:
    batch = ContinuousWorldBatch(task, n_envs=n_envs, seed=0)
    actions = np.random.default_rng(0).uniform(-1, 1, (8, n_envs, 2))
    counter = iter(range(1 << 62))
    return rate(lambda: batch.step(actions[next(counter) % 8]), n_envs, seconds)


def gym_batch(env_id: str, n_envs: int, seconds: float) -> float:
    """Steps per second of ``n_envs`` envs in famarl's gymnasium batch, which resets each as its episode ends."""
    batch = GymBatch.make(env_id, n_envs, seed=0)
    batch.reset()
    # as many distinct actions per env as single_env's: a short cycle of them pins the hand against things, whose
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument("--robot-hand-only", action="store_true", help="RobotHand's rows alone, unrecorded")
    parser.add_argument("--out", type=Path, default=RESULTS / "env_throughput.json")
    args = parser.parse_args()

    rows = []
    for task in () if args.robot_hand_only else ("base", "maze"):
        rows.append((task, "single (gym.make)", 1, single_env(ENV_IDS[task], args.seconds, unwrapped=False)))
        rows.append((task, "single (unwrapped)", 1, single_env(ENV_IDS[task], args.seconds, unwrapped=True)))
        for n_envs in (1, 64, 1024):
            rows.append((task, "batched", n_envs, batched_env(task, n_envs, args.seconds)))
    for task in ROBOT_HANDS:
        rows.append((task, "single (gym.make)", 1, single_env(ENV_IDS[task], args.seconds, unwrapped=False)))
        rows.append((task, "gymnasium batch", HAND_BATCH, gym_batch(ENV_IDS[task], HAND_BATCH, args.seconds)))

    print(f"{'task':<24} {'env':<20} {'worlds':>7} {'env steps/s':>14}")
    for task, kind, n_envs, per_s in rows:
        print(f"{task:<24} {kind:<20} {n_envs:>7} {per_s:>14,.0f}")
    print(f"peak RSS {peak_rss_mib():.0f} MiB")
    write_result(
        args.out,
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
