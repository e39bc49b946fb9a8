"""Stable-Baselines3's PPO over :class:`~famarl_cli.wrappers.MacroActionWrapper` against ``famarl train --agent
famarl``, on the Maze, with the same FAVAE per seed and the same budget of environment steps.

    pip install -e ".[bench]"
    dvc repro                      # the default pipeline: data/maze/macros/seed*/favae.pt and data/maze/eval
    python studies/sb3_over_wrapper.py [--seeds 0-9] [--steps 500000]

Seed S of SB3 learns over the FAVAE of ``data/maze/macros/seedS`` and is compared with the default pipeline's
``famarl-seedS`` run (the same FAVAE, 500k env steps). SB3 is set up as our PPO is (``famarl train``'s defaults:
16 envs x 64 decisions per rollout, minibatches of 128, 10 epochs, 64-64 tanh networks, lr 3e-4 annealed,
observation and reward normalisation), over the paper's reward convention: the wrapper sums a macro's rewards
(``reward="sum"``) and SB3 discounts once per decision, as ``--macro-discount decision`` does. SB3 counts
decisions; a callback stops it once the macros have run the budget in environment steps (``info["steps"]``).

Each side is judged as the report judges runs: success over 100 evaluation episodes with the policy sampling its
actions as in training (ours from ``data/maze/eval``, SB3 on episodes reset with seeds 100-199), and the
training success of the last 100 episodes at the end of the budget; means with 95% t intervals over seeds.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch
from study import RESULTS, command_line, record, step_count, write_result

from famarl_cli.core.statistics import mean_interval
from famarl_cli.envs import ENV_IDS
from famarl_cli.report.results import read_json
from famarl_cli.sweep.plan import parse_values
from famarl_cli.wrappers import MacroActionWrapper

N_ENVS, N_STEPS, MINIBATCH = 16, 64, 128
EVAL_EPISODES, EVAL_SEED = 100, 100


def sb3_run(favae: Path, steps: int, seed: int) -> dict:
    from ppo_vs_sb3 import sb3_ppo  # benchmarks/ppo_vs_sb3.py (study.py puts benchmarks/ on the path)
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor, VecNormalize

    def make() -> gym.Env:
        return MacroActionWrapper(gym.make(ENV_IDS["maze"]), favae, reward="sum")

    env = VecNormalize(VecMonitor(DummyVecEnv([make] * N_ENVS)), gamma=0.99)
    env.seed(seed)

    class Budget(BaseCallback):
        """Counts environment steps, stops at the budget, and records the training success per rollout."""

        def __init__(self) -> None:
            super().__init__()
            self.env_steps, self.curve, self.recent = 0, [], []

        def _on_step(self) -> bool:
            for info, done in zip(self.locals["infos"], self.locals["dones"], strict=True):
                self.env_steps += info["steps"]
                if done:
                    self.recent = (self.recent + [float(info["success"])])[-100:]
            return self.env_steps < steps

        def _on_rollout_end(self) -> None:
            self.curve.append((self.env_steps, float(np.mean(self.recent)) if self.recent else float("nan")))

        def _on_training_end(self) -> None:
            # learning stopped by the budget ends inside a rollout, whose end is not called
            if not self.curve or self.curve[-1][0] != self.env_steps:
                self._on_rollout_end()

    budget = Budget()
    model = sb3_ppo(env, N_STEPS, MINIBATCH, seed)
    start = time.perf_counter()
    # SB3's budget is in decisions; the callback ends learning at the env-step budget long before this one.
    model.learn(total_timesteps=steps, callback=budget)
    seconds = time.perf_counter() - start
    env.training = False
    return {
        "seed": seed,
        "env_steps": budget.env_steps,
        "seconds": round(seconds, 1),
        "training_success": budget.curve[-1][1],
        "success": evaluate(model, env, make),
        "curve": budget.curve,
    }


def evaluate(model, normalizer, make) -> float:
    """Success over EVAL_EPISODES episodes, the policy sampling, observations normalised with frozen statistics."""
    env, successes = make(), 0
    for i in range(EVAL_EPISODES):
        obs, _ = env.reset(seed=EVAL_SEED + i)
        done = False
        while not done:
            action, _ = model.predict(normalizer.normalize_obs(obs[None]), deterministic=False)
            obs, _, terminated, truncated, info = env.step(action[0])
            done = terminated or truncated
        successes += info["success"]
    return successes / EVAL_EPISODES


def ours(data: Path, seed: int) -> dict:
    evaluation = read_json(data / "maze" / "eval" / f"famarl-seed{seed}" / "eval.json", "evaluation")
    log = np.genfromtxt(data / "maze" / "runs" / f"famarl-seed{seed}" / "train.csv", delimiter=",", names=True)
    return {
        "seed": seed,
        "env_steps": int(evaluation["env_steps"]),
        "seconds": evaluation["train_wall_s"],
        "training_success": float(log["episode_success"][-1]),
        "success": float(evaluation["success_rate"]),
    }


def summary(runs: list[dict]) -> dict:
    out = {}
    for key in ("success", "training_success", "seconds"):
        interval = mean_interval([r[key] for r in runs], EVAL_EPISODES if key == "success" else None)
        out[key] = {"mean": round(interval.estimate, 3), "low": round(interval.low, 3), "high": round(interval.high, 3)}
    return out


def records(result: dict, command: str) -> dict[str, dict]:
    """measured.json's entry: each side's evaluation success with its interval, and its wall per run."""

    def success(name: str) -> str:
        s = result[name]["success"]
        return f"{s['mean']:.3f} [{s['low']:.3f}, {s['high']:.3f}]"

    seconds = {name: result[name]["seconds"]["mean"] for name in ("sb3", "famarl")}
    seeds = len(result["seeds"])
    return {
        "sb3_over_wrapper": {
            "what": "SB3's PPO over `MacroActionWrapper` vs `famarl train --agent famarl`, Maze, "
            f"{seeds} seed{'s' if seeds > 1 else ''} x {step_count(result['steps'])} env steps",
            "command": command,
            "measured": f"success {success('sb3')} vs {success('famarl')}; {seconds['sb3']:.1f} s vs "
            f"{seconds['famarl']:.1f} s per run",
            "target": "the same success",
        }
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", default="0-9")
    parser.add_argument("--steps", type=int, default=500_000, help="Budget in environment steps.")
    parser.add_argument("--data", type=Path, default=Path("data"))
    parser.add_argument("--out", type=Path, default=RESULTS / "sb3_over_wrapper.json")
    args = parser.parse_args()
    torch.set_num_threads(1)
    seeds = [int(s) for s in parse_values(args.seeds)]
    missing = [
        seed for seed in seeds if not (args.data / "maze" / "eval" / f"famarl-seed{seed}" / "eval.json").is_file()
    ]
    if missing:
        parser.error(f"no default-pipeline FaMARL run for seeds {missing} under {args.data}: run `dvc repro` first")
    sb3, mine = [], []
    for seed in seeds:
        sb3.append(sb3_run(args.data / "maze" / "macros" / f"seed{seed}" / "favae.pt", args.steps, seed))
        mine.append(ours(args.data, seed))
        print(
            f"seed {seed}: SB3 {sb3[-1]['success']:.2f} in {sb3[-1]['seconds']:.0f} s, ours {mine[-1]['success']:.2f}"
        )
    result = {"steps": args.steps, "seeds": seeds, "sb3": summary(sb3), "famarl": summary(mine), "runs": sb3 + mine}
    for name in ("sb3", "famarl"):
        s = result[name]["success"]
        print(f"{name}: success {s['mean']:.2f} [{s['low']:.2f}, {s['high']:.2f}] (n={len(seeds)})")
    write_result(args.out, result)
    for name, entry in records(result, command_line(__file__, parser, args)).items():
        record(name, **entry)


if __name__ == "__main__":
    main()
