"""The demos stage: run a scripted expert in its Base task (ContinuousWorld or RobotHand) and collect its
episodes."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import gymnasium as gym
import numpy as np

from famarl_cli.artifacts import Demos, Episode, provenance
from famarl_cli.errors import UsageError
from famarl_cli.experts import Script, demonstration, make_expert


def episode_seeds(seed: int, n_episodes: int) -> np.ndarray:
    """Reset seeds of the episodes of a demos run, stored per episode so any one can be replayed alone."""
    return np.random.default_rng(seed).integers(0, 2**31 - 1, n_episodes)


def record_episode(env: gym.Env, expert, seed: int) -> Episode:
    observation, _ = env.reset(seed=int(seed))
    expert.reset(observation)
    observations, actions, rewards, terminations, truncations = [observation], [], [], [], []
    done = False
    while not done:
        action = expert.act(observation)
        observation, reward, terminated, truncated, _ = env.step(action)
        for store, value in zip(
            (observations, actions, rewards, terminations, truncations),
            (observation, action, reward, terminated, truncated),
            strict=True,
        ):
            store.append(value)
        done = terminated or truncated
    return Episode(
        observations=np.array(observations, dtype=np.float32),
        actions=np.array(actions, dtype=np.float32),
        rewards=np.array(rewards, dtype=np.float64),
        terminations=np.array(terminations, dtype=bool),
        truncations=np.array(truncations, dtype=bool),
        seed=int(seed),
        segment_starts=np.array(expert.phase_starts, dtype=np.int64),
        factors=expert.phase_factors,
    )


def record_demos(
    script: Script, n_episodes: int = 100, seed: int = 0, on_episode: Callable[[Episode], None] | None = None
) -> Demos:
    """``n_episodes`` demos of ``script``; the same ``seed`` always gives the same arrays.

    ``on_episode`` is called after each episode (the CLI advances its progress bar with it).
    """
    if n_episodes < 1:
        raise UsageError(f"episodes must be >= 1, got {n_episodes}")
    script = Script(script)
    spec = demonstration(script)
    env = gym.make(spec.env_id, **spec.env_kwargs)
    expert = make_expert(script)
    episodes = []
    for episode_seed in episode_seeds(seed, n_episodes):
        episodes.append(record_episode(env, expert, episode_seed))
        if on_episode:
            on_episode(episodes[-1])
    env.close()
    params = {"script": script.value, "episodes": n_episodes, "seed": seed}
    return Demos(
        episodes=episodes,
        env_id=spec.env_id,
        script=script.value,
        seed=seed,
        factor_names=spec.factor_names,
        env_kwargs=spec.env_kwargs,
        provenance=provenance("famarl demos", params, seed),
    )


DEMOS_FILE = "demos.h5"


def run_job(config: dict, folder: Path, context) -> dict:
    """Demos as a sweep job (:mod:`famarl_cli.sweep`): ``folder/demos.h5`` and, with ``plot``, ``demos.png``."""
    from famarl_cli.artifacts.demos import write_demos
    from famarl_cli.plots import plot_demos

    episodes = config["episodes"]
    done = []

    def advance(episode: Episode) -> None:
        done.append(episode)
        context.progress(len(done), episodes)

    recorded = record_demos(Script(config["script"]), episodes, config["seed"], on_episode=advance)
    write_demos(folder / DEMOS_FILE, recorded)
    if config["plot"]:
        plot_demos(recorded, (folder / DEMOS_FILE).with_suffix(".png"))
    return {"success": recorded.success_rate, "episodes": len(recorded.episodes)}
