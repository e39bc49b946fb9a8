"""What the prior and the closed-loop decoder cost: one PPO minibatch step with and without the prior's KL, and
the env steps per second of FaMARL's rollouts with the open-loop and the closed-loop decoder.

    python benchmarks/skills_cost.py [--replicate data/maze/macros/seed0]
        [--prior data/skills/maze/prior/seed0/prior.pt] [--out benchmarks/results/skills_cost.json]

1. Minibatch step: ``ppo_loss`` and its gradient + gradient clip + Adam on a 2048/8-row minibatch of a FaMARL
   policy (12 observations, the FAVAE's latent), without and with the prior (its KL term, the per-row std):
   median over ``--repeats`` of the mean of ``--steps`` steps.
2. Rollouts: ``PPOTrainer.collect_rollout`` on the Maze, 16 environments, 16 decisions each, open-loop (the FAVAE)
   against closed-loop (the prior file's decoder, one call per env step): env steps per second.

Run it alone (one CPU-heavy job at a time). Prints a table and writes benchmarks/results/skills_cost.json (or
``--out``).
"""

from __future__ import annotations

import argparse
import re
import time
from pathlib import Path

import numpy as np
import torch
from common import RESULTS, command_line, record, rounded, write_result

from famarl_cli.core.replicate_adam import ReplicateAdam
from famarl_cli.envs.vector import make_batch
from famarl_cli.method.favae.checkpoint import load_favae
from famarl_cli.method.prior.checkpoint import load_skills
from famarl_cli.rl import Agent, MacroDecoder
from famarl_cli.rl.policy import ActorCritic
from famarl_cli.rl.ppo import Minibatch, PPOConfig, PPOTrainer, clip_rows, ppo_loss
from famarl_cli.rl.spec import RunSpec, build_guide, build_mode

MAZE = "famarl/ContinuousWorld-Maze-v0"


def minibatch_step(latent: int, guided: bool, steps: int) -> float:
    torch.manual_seed(0)
    policy = ActorCritic(12, latent)
    optimizer = ReplicateAdam(policy.flat, lr=3e-4, eps=1e-5)
    rows = 256
    obs, u = torch.randn(rows, 12), torch.randn(rows, latent)
    base = (torch.randn(rows, latent), 0.3 * torch.randn(rows, latent)) if guided else (None, None)
    batch = Minibatch(obs, u, torch.zeros(rows, dtype=torch.long), -torch.rand(rows) * 5, torch.randn(rows),
                      torch.randn(rows), torch.randn(rows), *base)  # fmt: skip
    mask = torch.ones(latent)
    cfg = PPOConfig()

    def step() -> None:
        loss, _ = ppo_loss(policy, batch, cfg, 0.0, 0.1 if guided else 0.0, mask if guided else None)
        loss.backward()
        optimizer.step(clip_rows(policy.gradient(), cfg.max_grad_norm))

    for _ in range(20):
        step()
    start = time.perf_counter()
    for _ in range(steps):
        step()
    return (time.perf_counter() - start) / steps


def rollout_rate(favae_path: Path, prior_path: Path, decoder: MacroDecoder, guided: bool, rollouts: int) -> float:
    favae, skills = load_favae(favae_path)[0], load_skills(prior_path)
    config = PPOConfig(total_steps=10**9, n_steps=16)
    spec = RunSpec(MAZE, Agent.FAMARL, 0, config, favae=str(favae_path), prior=str(prior_path),
                   prior_guide=guided, loop=decoder, prior_obs_prefix=True)  # fmt: skip
    env = make_batch(MAZE, config.n_envs, seed=0)
    mode = build_mode(spec, env, favae, skills)
    trainer = PPOTrainer(env, mode, config, 0, build_guide(spec, mode, skills))
    trainer.collect_rollout()
    before, start = trainer.members[0].env_steps, time.perf_counter()
    for _ in range(rollouts):
        trainer.collect_rollout()
    return (trainer.members[0].env_steps - before) / (time.perf_counter() - start)


def records(step: dict[str, float], rates: dict[str, float], command: str) -> dict[str, dict]:
    """measured.json's entry: the minibatch step without and with the prior's KL, and the rollouts' rates."""
    plain, guided = step["plain"], step["with the prior's KL"]
    open_loop = rates["open-loop"]
    named = {re.sub(r"\W+", "_", name): per_s for name, per_s in rates.items()}
    rollouts = " / ".join(
        rounded(per_s) + ("" if name == "open-loop" else f" ({per_s / open_loop:.2f}x)")
        for name, per_s in rates.items()
    )
    return {
        "skills_cost": {
            "what": "the prior's and the closed-loop decoder's cost: a PPO minibatch step without / with the prior's "
            "KL; FaMARL's rollouts on the Maze open-loop / with the prior's guide / closed-loop",
            "command": command,
            "measured": f"{1000 * plain:.2f} / {1000 * guided:.2f} ms ({guided / plain:.2f}x); {rollouts} env steps/s",
            "values": {"step": 1000 * plain, "step_prior": 1000 * guided, **named},
            "unit": {"step": "ms", "step_prior": "ms", **dict.fromkeys(named, "env steps/s")},
        }
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--replicate", type=Path, default=Path("data/maze/macros/seed0"))
    parser.add_argument("--prior", type=Path, default=Path("data/skills/maze/prior/seed0/prior.pt"))
    parser.add_argument("--steps", type=int, default=400)
    parser.add_argument("--rollouts", type=int, default=10)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--out", type=Path, default=RESULTS / "skills_cost.json")
    args = parser.parse_args()
    torch.set_num_threads(1)
    favae = args.replicate / "favae.pt"
    latent = load_favae(favae)[0].config.latent_size
    step = {
        name: float(np.median([minibatch_step(latent, guided, args.steps) for _ in range(args.repeats)]))
        for name, guided in (("plain", False), ("with the prior's KL", True))
    }
    rates = {}
    for name, decoder, guided in (
        ("open-loop", MacroDecoder.OPEN, False),
        ("open-loop, prior guide", MacroDecoder.OPEN, True),
        ("closed-loop", MacroDecoder.CLOSED, False),
    ):
        rates[name] = float(np.median([rollout_rate(favae, args.prior, decoder, guided, args.rollouts)
                                       for _ in range(args.repeats)]))  # fmt: skip
    print("PPO minibatch step (ms, median of repeats):")
    for name, seconds in step.items():
        print(f"  {name:24s} {1000 * seconds:.3f}")
    print(f"  ratio {step['with the prior' + chr(39) + 's KL'] / step['plain']:.2f}")
    print("FaMARL rollouts on the Maze (env steps / s, median of repeats):")
    for name, per_s in rates.items():
        print(f"  {name:24s} {per_s:,.0f}   ({per_s / rates['open-loop']:.2f} of open-loop)")
    write_result(args.out, {"minibatch_step_s": step, "rollout_env_steps_per_s": rates})
    for name, entry in records(step, rates, command_line(__file__, parser, args)).items():
        record(name, **entry)


if __name__ == "__main__":
    main()
