"""Foreign input end to end: a Minari dataset recorded from gymnasium's own LunarLander heuristic, through
``famarl demos --from-minari``, ``famarl macros``, ``famarl train`` and ``famarl evaluate``, with the success and
return each stage reports.

    python studies/lunar_lander_chain.py [--episodes 30] [--steps 200000] [--work /tmp/lander]

LunarLanderContinuous reports no success and terminates on every crash; gymnasium declares its
``reward_threshold`` (200), the return at which the task counts as solved. Before famarl judged success by that
(famarl_cli.envs.success), every crash counted as a success: 100% success with a return of -118. The run here
trains twice on the same macros: an untrained agent (one PPO update) and a trained one (``--steps``), and
evaluates each on 100 episodes; success must follow the return, not termination.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
from study import RESULTS, write_result

from famarl_cli.artifacts.runs import read_evaluation

ENV = "LunarLanderContinuous-v3"


def record_dataset(root: Path, episodes: int, seed: int) -> str:
    """``episodes`` of gymnasium's heuristic lander as the Minari dataset ``lander/heuristic-v0`` under ``root``."""
    import minari
    from gymnasium.envs.box2d.lunar_lander import heuristic

    os.environ["MINARI_DATASETS_PATH"] = str(root)
    dataset_id = "lander/heuristic-v0"
    if (root / dataset_id).exists():
        return dataset_id
    env = minari.DataCollector(gym.make(ENV))
    for episode in range(episodes):
        observation, _ = env.reset(seed=seed + episode)
        done = False
        while not done:
            observation, _, terminated, truncated, _ = env.step(heuristic(env.unwrapped, observation))
            done = terminated or truncated
    env.create_dataset(
        dataset_id=dataset_id,
        algorithm_name="gymnasium.envs.box2d.lunar_lander.heuristic",
        author="famarl benchmarks",
        author_email="benchmarks@famarl.invalid",
        code_permalink="https://example.invalid/famarl",
        description="gymnasium's LunarLander heuristic, continuous actions",
        eval_env=ENV,
    )
    env.close()
    return dataset_id


def famarl(*args: object) -> str:
    done = subprocess.run(
        [sys.executable, "-m", "famarl_cli", *map(str, args)], capture_output=True, text=True, check=False
    )
    if done.returncode != 0:
        sys.exit(f"famarl {' '.join(map(str, args))} failed:\n{done.stdout[-2000:]}\n{done.stderr[-2000:]}")
    print(done.stdout)
    return done.stdout


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", type=int, default=30, help="Heuristic episodes in the dataset.")
    parser.add_argument("--steps", type=int, default=200_000, help="Env steps of the trained agent.")
    parser.add_argument("--epochs", type=int, default=300, help="Epochs of the FAVAE pre-run and fit.")
    parser.add_argument("--work", type=Path, default=Path("/tmp/famarl-lander"), help="Working folder.")
    parser.add_argument("--out", type=Path, default=RESULTS / "lunar_lander_chain.json")
    args = parser.parse_args()
    work = args.work
    work.mkdir(parents=True, exist_ok=True)
    dataset = record_dataset(work / "minari", args.episodes, seed=0)
    demos = work / "demos.h5"
    famarl("demos", "--from-minari", dataset, "--out", demos, "--no-plot")
    from famarl_cli.artifacts import read_demos

    recorded = read_demos(demos)
    returns = np.array([e.rewards.sum() for e in recorded.episodes])
    macros = work / "macros"
    famarl("macros", "--demos", demos, "--out", macros, "--epochs", args.epochs, "--segment-epochs", 100)
    results = {
        "demos": {
            "episodes": len(recorded.episodes),
            "success_rate": recorded.success_rate,
            "success_rule": recorded.success_rule,
            "terminated": float(np.mean([e.terminations[-1] for e in recorded.episodes])),
            "return_mean": float(returns.mean()),
        }
    }
    for name, steps in (("untrained", 2048), ("trained", args.steps)):
        run = work / name
        famarl(
            "train", "--env", ENV, "--agent", "famarl", "--favae", macros / "favae.pt", "--steps", steps,
            "--out", run, "--overwrite",
        )  # fmt: skip
        famarl("evaluate", "--run", run, "--episodes", 100, "--no-film", "--out", work / "eval")
        evaluation = read_evaluation(work / "eval" / name / "eval.json")
        mode = evaluation["deterministic"]
        results[name] = {
            "env_steps": evaluation["env_steps"],
            **{key: mode[key] for key in ("success_rate", "success_rule", "return_mean", "episode_length")},
            "sampled": {key: evaluation[key] for key in ("success_rate", "return_mean")},
        }
    print(json.dumps(results, indent=1))
    write_result(args.out, {"dataset_episodes": args.episodes, "epochs": args.epochs, **results})


if __name__ == "__main__":
    main()
