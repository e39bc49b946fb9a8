"""Our PPO against Stable-Baselines3's on the same work: env steps per second and learning curves.

    pip install -e ".[bench]"
    python benchmarks/ppo_vs_sb3.py [--steps 200000] [--seed 0] [--out benchmarks/results/ppo_vs_sb3.json]

Both learn `famarl/ContinuousWorld-Maze-v0` on primitive actions with the same PPO: 16 environments x 128 steps
per rollout, minibatches of 256, 10 epochs, 64-64 tanh networks, gamma 0.99, lambda 0.95, clip 0.2, lr 3e-4
annealed linearly, observation and reward normalisation, one torch thread. Each uses its best vector-env setup:
ours the numpy batch (all worlds in one call), SB3 a DummyVecEnv of gymnasium envs with VecNormalize.
They run one after the other in one process; the JSON holds both learning curves (success rate and return of
the last 100 episodes against env steps) and a PNG draws them.
"""

from __future__ import annotations

import argparse
import json
import platform
import resource
import time
from pathlib import Path

import numpy as np
import torch
from matplotlib.figure import Figure

import famarl_cli
from famarl_cli.envs import ENV_IDS
from famarl_cli.envs.batched import ContinuousWorldBatch
from famarl_cli.rl.action_modes import PrimitiveActions
from famarl_cli.rl.ppo import PPOConfig, PPOTrainer

N_ENVS, N_STEPS, MINIBATCH, EPOCHS = 16, 128, 256, 10


def ours(steps: int, seed: int) -> dict:
    env = ContinuousWorldBatch("maze", n_envs=N_ENVS, seed=seed)
    config = PPOConfig(
        total_steps=steps, n_envs=N_ENVS, n_steps=N_STEPS, minibatches=N_ENVS * N_STEPS // MINIBATCH, epochs=EPOCHS
    )
    trainer = PPOTrainer(env, PrimitiveActions(*env.action_bounds), config, seed)
    curve = []
    start = time.perf_counter()
    trainer.train(lambda t, row: curve.append((row["env_steps"], row["episode_success"], row["episode_return"])))
    elapsed = time.perf_counter() - start
    return {"env_steps": trainer.env_steps, "seconds": elapsed, "curve": curve}


def stable_baselines3(steps: int, seed: int) -> dict:
    import gymnasium as gym
    from stable_baselines3 import PPO
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

    model = PPO(
        "MlpPolicy",
        env,
        n_steps=N_STEPS,
        batch_size=MINIBATCH,
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
    start = time.perf_counter()
    model.learn(total_timesteps=steps, callback=Curve())
    elapsed = time.perf_counter() - start
    return {"env_steps": int(model.num_timesteps), "seconds": elapsed, "curve": curve}


def plot(results: dict, path: Path) -> None:
    fig = Figure(figsize=(10, 3.6))
    axes = fig.subplots(1, 2)
    for name, result in results.items():
        steps, success, returns = np.array(result["curve"], dtype=float).T
        label = f"{name}: {result['env_steps'] / result['seconds']:,.0f} env steps/s"
        axes[0].plot(steps, success, label=label)
        axes[1].plot(steps, returns, label=label)
    axes[0].set(xlabel="environment steps", ylabel="success (last 100 episodes)", ylim=(-0.02, 1.02))
    axes[1].set(xlabel="environment steps", ylabel="return (last 100 episodes)")
    axes[0].legend(fontsize=8)
    fig.suptitle("PPO on ContinuousWorld-Maze, same hyperparameters, one torch thread", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=200_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/ppo_vs_sb3.json"))
    args = parser.parse_args()
    torch.set_num_threads(1)
    results = {"famarl": ours(args.steps, args.seed), "stable-baselines3": stable_baselines3(args.steps, args.seed)}
    rates = {name: r["env_steps"] / r["seconds"] for name, r in results.items()}
    print(f"{'implementation':<20} {'env steps':>10} {'seconds':>8} {'env steps/s':>12} {'final success':>14}")
    for name, r in results.items():
        final = r["curve"][-1][1] if r["curve"] else float("nan")
        print(f"{name:<20} {r['env_steps']:>10,} {r['seconds']:>8.1f} {rates[name]:>12,.0f} {final:>14.2f}")
    ratio = rates["famarl"] / rates["stable-baselines3"]
    print(f"ratio famarl / stable-baselines3: {ratio:.2f}x")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    summary = {
        "famarl_version": famarl_cli.__version__,
        "machine": platform.platform(),
        "steps": args.steps,
        "seed": args.seed,
        "ratio": ratio,
        "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "results": results,
    }
    args.out.write_text(json.dumps(summary, indent=2))
    plot(results, args.out.with_suffix(".png"))
    print(f"written {args.out} and {args.out.with_suffix('.png')}")


if __name__ == "__main__":
    main()
