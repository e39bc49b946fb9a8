"""Our PPO against Stable-Baselines3's on the same work: env steps per second and learning curves.

    pip install -e ".[bench]"
    python benchmarks/ppo_vs_sb3.py [--steps 200000] [--seeds 0 1 2] [--together] [--out ...ppo_vs_sb3.json]

Both learn `famarl/ContinuousWorld-Maze-v0` on primitive actions with the same PPO: 16 environments x 128 steps
per rollout, minibatches of 256, 10 epochs, 64-64 tanh networks, gamma 0.99, lambda 0.95, clip 0.2, lr 3e-4
annealed linearly, observation and reward normalisation, one torch thread. Each uses its best vector-env setup:
ours the numpy batch (all worlds in one call), SB3 a DummyVecEnv of gymnasium envs with VecNormalize.
They run in one process, alternating seed by seed (with ``--together``, our seeds first, as one batch: one
batched network for all, as ``famarl sweep train`` trains a setting's seeds); the speed is total env steps over total
seconds, so it is the rate of one core, and two cores run two such processes.
Learning is compared on the curves: the env steps from which the success, smoothed over 5 updates, holds 80% to
the end (the report's steps to 0.8) and the mean success over the last fifth of training, each a mean over seeds.
The JSON holds every learning curve (success rate and return of the last 100 episodes against env steps) and a PNG
draws them.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch
from common import RESULTS, command_line, record, rounded, step_count, timed, verdict, write_result
from matplotlib.figure import Figure

from famarl_cli.core.statistics import THRESHOLD, steps_to_threshold
from famarl_cli.envs import ENV_IDS
from famarl_cli.envs.batched import ContinuousWorldBatch
from famarl_cli.rl.action_modes import PrimitiveActions
from famarl_cli.rl.ppo import PPOConfig, PPOTrainer

N_ENVS, N_STEPS, MINIBATCH, EPOCHS = 16, 128, 256, 10


def ours(steps: int, seeds: list[int]) -> list[dict]:
    """Our PPO on ``seeds``, trained together in one process (PPOTrainer.together; one seed: alone); each seed's
    time is the batch's share, the batch's wall over its seeds."""
    config = PPOConfig(
        total_steps=steps, n_envs=N_ENVS, n_steps=N_STEPS, minibatches=N_ENVS * N_STEPS // MINIBATCH, epochs=EPOCHS
    )
    trainers = []
    for seed in seeds:
        env = ContinuousWorldBatch("maze", n_envs=N_ENVS, seed=seed)
        trainers.append(PPOTrainer(env, PrimitiveActions(*env.action_bounds), config, seed))
    trainer = trainers[0] if len(trainers) == 1 else PPOTrainer.together(trainers)
    curves = [[] for _ in seeds]

    def on_update(k: int, row: dict) -> None:
        curves[k].append((row["env_steps"], row["episode_success"], row["episode_return"]))

    _, seconds = timed(lambda: trainer.train(on_member_update=on_update))
    return [
        {"env_steps": member.env_steps, "seconds": seconds / len(seeds), "curve": curve}
        for member, curve in zip(trainer.members, curves, strict=True)
    ]


def sb3_ppo(env, n_steps: int, minibatch: int, seed: int):
    """Stable-Baselines3's PPO with our PPO's settings (``famarl train``'s defaults but the rollout's shape)."""
    from stable_baselines3 import PPO

    return PPO(
        "MlpPolicy",
        env,
        n_steps=n_steps,
        batch_size=minibatch,
        n_epochs=EPOCHS,
        learning_rate=lambda progress: 3e-4 * progress,
        gamma=0.99,
        gae_lambda=0.95,
        clip_range=0.2,
        clip_range_vf=0.2,
        ent_coef=0.0,
        vf_coef=0.5,
        max_grad_norm=0.5,
        policy_kwargs={"net_arch": {"pi": [64, 64], "vf": [64, 64]}, "activation_fn": torch.nn.Tanh},
        seed=seed,
        device="cpu",
        verbose=0,
    )


def stable_baselines3(steps: int, seed: int) -> dict:
    import gymnasium as gym
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor, VecNormalize

    env = VecNormalize(VecMonitor(DummyVecEnv([lambda: gym.make(ENV_IDS["maze"])] * N_ENVS)), gamma=0.99)
    env.seed(seed)
    limit = 400
    curve = []

    class Curve(BaseCallback):
        def _on_rollout_end(self) -> None:
            episodes = list(self.model.ep_info_buffer)
            success = np.mean([e["l"] < limit for e in episodes]) if episodes else float("nan")
            returns = np.mean([e["r"] for e in episodes]) if episodes else float("nan")
            curve.append((self.num_timesteps, float(success), float(returns)))

        def _on_step(self) -> bool:
            return True

    model = sb3_ppo(env, N_STEPS, MINIBATCH, seed)
    _, seconds = timed(lambda: model.learn(total_timesteps=steps, callback=Curve()))
    return {"env_steps": int(model.num_timesteps), "seconds": seconds, "curve": curve}


def rate(runs: list[dict]) -> float:
    return sum(r["env_steps"] for r in runs) / sum(r["seconds"] for r in runs)


def learning(runs: list[dict]) -> dict[str, float]:
    """How well the runs learned, on their curves: the env steps from which the success holds 80% to the end
    (:func:`~famarl_cli.core.statistics.steps_to_threshold`, what the report judges "learns faster" on), and the mean
    success over the last fifth of training, each a mean over seeds (not a number where a seed ends below 80%)."""
    reached, late = [], []
    for run in runs:
        steps, success, _ = np.array(run["curve"], dtype=float).T
        held = steps_to_threshold(steps, success, THRESHOLD)
        reached.append(np.nan if held is None else held)
        late.append(success[steps >= 0.8 * steps[-1]].mean())
    return {"steps_to_80pct_success": float(np.mean(reached)), "late_success": float(np.mean(late))}


def plot(results: dict[str, list[dict]], path: Path) -> None:
    fig = Figure(figsize=(10, 3.6))
    axes = fig.subplots(1, 2)
    for (name, runs), color in zip(results.items(), ("tab:blue", "tab:orange"), strict=False):
        for i, run in enumerate(runs):
            steps, success, returns = np.array(run["curve"], dtype=float).T
            label = f"{name}: {rate(runs):,.0f} env steps/s" if i == 0 else None
            axes[0].plot(steps, success, color=color, alpha=0.8, lw=1, label=label)
            axes[1].plot(steps, returns, color=color, alpha=0.8, lw=1)
    axes[0].set(xlabel="environment steps", ylabel="success (last 100 episodes)", ylim=(-0.02, 1.02))
    axes[1].set(xlabel="environment steps", ylabel="return (last 100 episodes)")
    axes[0].legend(fontsize=8)
    seeds = len(next(iter(results.values())))
    fig.suptitle(f"PPO on ContinuousWorld-Maze, same hyperparameters, one torch thread, {seeds} seeds each", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def records(steps: int, seeds: list[int], together: bool, ratio: float, summary: dict, command: str) -> dict:
    """measured.json's entries: with each of our seeds alone, the speed against SB3's and the learning; with
    ``together``, both in one entry."""
    ours, sb3 = summary["famarl"], summary["stable-baselines3"]

    def k(value: float) -> str:
        return f"{value / 1000:.0f}k" if np.isfinite(value) else "not held"

    speed = (
        f"ours {rounded(ours['env_steps_per_s'])}, SB3 {rounded(sb3['env_steps_per_s'])} env steps/s: **{ratio:.1f}x**"
    )
    first = ours["steps_to_80pct_success"]
    reached = f"80% success held from {k(first)} steps" if np.isfinite(first) else "80% success not held"
    runs = f"{len(seeds)} seed{'s' if len(seeds) > 1 else ''}"
    rates = {
        "values": {"ours": ours["env_steps_per_s"], "sb3": sb3["env_steps_per_s"], "ratio": ratio},
        "unit": {"ours": "env steps/s", "sb3": "env steps/s", "ratio": "x"},
        "better": {"ratio": "higher"},
    }
    learning = {
        "values": {
            "steps_to_80": first,
            "sb3_steps_to_80": sb3["steps_to_80pct_success"],
            "late_success": ours["late_success"],
            "sb3_late_success": sb3["late_success"],
        },
        "unit": {
            "steps_to_80": "env steps",
            "sb3_steps_to_80": "env steps",
            "late_success": "share",
            "sb3_late_success": "share",
        },
        "better": {
            "steps_to_80": "lower",
            "sb3_steps_to_80": "lower",
            "late_success": "higher",
            "sb3_late_success": "higher",
        },
    }
    if together:
        learned = f"{reached} (SB3 {k(sb3['steps_to_80pct_success'])}), late success {ours['late_success']:.2f} "
        learned += f"({sb3['late_success']:.2f})"
        return {
            "ppo_vs_sb3_together": {
                "what": f"the same with our {len(seeds)} seeds trained together in one process, {len(seeds)} x "
                f"{step_count(steps)} steps, one core",
                "command": command,
                "measured": f"{speed}; {learned}" + verdict(ratio >= 10),
                "target": "10x",
                "values": rates["values"] | learning["values"],
                "unit": rates["unit"] | learning["unit"],
                "better": rates["better"] | learning["better"],
            }
        }
    command = f'pip install -e ".[bench]" && {command}'
    return {
        "ppo_vs_sb3": {
            "what": f"PPO on the Maze vs Stable-Baselines3, same hyperparameters, {runs} x {step_count(steps)} steps",
            "command": command,
            "measured": speed + verdict(ratio >= 5),
            "target": ">= 5x",
            **rates,
        },
        "ppo_vs_sb3_learning": {
            "what": "the same, learning",
            "command": command,
            "measured": f"{reached} (SB3 {k(sb3['steps_to_80pct_success'])}); late success "
            f"{ours['late_success']:.2f} (SB3 {sb3['late_success']:.2f})",
            "target": "no worse",
            **learning,
        },
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=200_000)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--out", type=Path, default=RESULTS / "ppo_vs_sb3.json")
    parser.add_argument(
        "--together", action="store_true", help="Train our seeds together in one process (as famarl sweep train does)."
    )
    args = parser.parse_args()
    torch.set_num_threads(1)
    results = {"famarl": [], "stable-baselines3": []}
    if args.together:
        results["famarl"] = ours(args.steps, args.seeds)
    for seed in args.seeds:  # alternating, so that a slow spell of the machine slows both
        if not args.together:
            results["famarl"] += ours(args.steps, [seed])
        results["stable-baselines3"].append(stable_baselines3(args.steps, seed))
    header = f"{'implementation':<18} {'env steps':>10} {'seconds':>8} {'env steps/s':>12}"
    print(f"{header} {'80% held from':>15} {'late success':>13}")
    summary = {name: {"env_steps_per_s": rate(runs), **learning(runs)} for name, runs in results.items()}
    for name, runs in results.items():
        steps, seconds = sum(r["env_steps"] for r in runs), sum(r["seconds"] for r in runs)
        row = summary[name]
        print(
            f"{name:<18} {steps:>10,} {seconds:>8.1f} {row['env_steps_per_s']:>12,.0f} "
            f"{row['steps_to_80pct_success']:>15,.0f} {row['late_success']:>13.2f}"
        )
    ratio = rate(results["famarl"]) / rate(results["stable-baselines3"])
    print(f"ratio famarl / stable-baselines3: {ratio:.2f}x")
    write_result(
        args.out,
        {
            "steps": args.steps,
            "seeds": args.seeds,
            "together": args.together,
            "ratio": ratio,
            "summary": summary,
            "results": results,
        },
    )
    plot(results, args.out.with_suffix(".png"))
    print(f"written {args.out.with_suffix('.png')}")
    command = command_line(__file__, parser, args)
    for name, entry in records(args.steps, args.seeds, args.together, ratio, summary, command).items():
        record(name, **entry)


if __name__ == "__main__":
    main()
