"""The ceiling of training several seeds in one process as batched networks (PureJaxRL's idea, on torch CPU).

    python benchmarks/batched_seeds.py [--seconds 3]

Our PPO step is bound by per-call overhead. If k seeds shared every torch and numpy call, a minibatch step would
carry k times the rows for the same number of calls. This measures that directly, on the real loss and update,
without building the batched trainer: one PPO minibatch step (forward, written-out gradient, clipping, Adam) and one
policy call and environment step of a rollout, at k = 1, 2, 4, 8 times the rows of one seed. If k times the rows
cost close to k times the time, batching seeds gains nothing over running them on separate cores; the closer to 1x
it stays, the more it could pay.
"""

from __future__ import annotations

import argparse

import numpy as np
import torch
from common import RESULTS, rate, write_result

from famarl_cli.envs.batched import ContinuousWorldBatch
from famarl_cli.rl.optimizer import FlatAdam
from famarl_cli.rl.policy import ActorCritic
from famarl_cli.rl.ppo import Minibatch, PPOConfig, clipped_objective_gradient

MINIBATCH, N_ENVS, OBS, ACTION = 256, 16, 12, 2  # the Maze's observation and action sizes


def update_step(rows: int):
    torch.manual_seed(0)
    policy = ActorCritic(OBS, ACTION)
    optimizer = FlatAdam(policy.flat, lr=3e-4, eps=1e-5)
    batch = Minibatch(
        obs=torch.randn(rows, OBS),
        u=torch.randn(rows, ACTION),
        index=torch.zeros(rows, dtype=torch.long),
        logp=torch.randn(rows),
        values=torch.randn(rows),
        advantages=torch.randn(rows),
        returns=torch.randn(rows),
    )
    config = PPOConfig()

    @torch.inference_mode()
    def step() -> None:
        clipped_objective_gradient(policy, batch, config)
        norm = float(policy.gradient.norm())
        if norm > config.max_grad_norm:
            policy.gradient.mul_(config.max_grad_norm / norm)
        optimizer.step(policy.gradient)

    return step


def rollout_step(envs: int):
    env = ContinuousWorldBatch("maze", n_envs=envs, seed=0)
    policy = ActorCritic(env.observation_size, ACTION)
    rng = np.random.default_rng(0)
    obs = env.reset()

    def step() -> None:
        action = policy.act(obs.astype(np.float32), rng)
        env.step(np.clip(action.u, -1, 1).astype(np.float64))

    return step


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=3.0)
    args = parser.parse_args()
    torch.set_num_threads(1)
    rows = []
    print(f"{'seeds':>5} {'update: steps/s':>16} {'x rows per s':>13} {'rollout: steps/s':>17} {'x rows per s':>13}")
    for k in (1, 2, 4, 8):
        update = rate(update_step(k * MINIBATCH), 1, args.seconds)
        rollout = rate(rollout_step(k * N_ENVS), 1, args.seconds)
        rows.append({"seeds": k, "update_steps_per_s": update, "rollout_steps_per_s": rollout})
        base = rows[0]
        print(
            f"{k:>5} {update:>16,.0f} {k * update / base['update_steps_per_s']:>12.2f}x "
            f"{rollout:>17,.0f} {k * rollout / base['rollout_steps_per_s']:>12.2f}x"
        )
    write_result(RESULTS / "batched_seeds.json", {"rows": rows})


if __name__ == "__main__":
    main()
