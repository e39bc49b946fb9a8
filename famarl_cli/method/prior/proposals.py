"""What the prior proposes where the expert started: from a few demo episodes' first states, macros decoded from
latents drawn from p(z | s) and from N(0, I), each run in the demos' env from that very state (the env reset with the
episode's own seed), beside the path the expert took.

For the picture ``famarl prior fit`` draws beside the prior file (:func:`famarl_cli.method.plots.plot_proposals`).
"""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium
import numpy as np
import torch

from famarl_cli.core.errors import foreign
from famarl_cli.envs.external import make_env

SAMPLES = 8
"""Latents drawn from each distribution per state."""


@dataclass
class Proposals:
    episodes: list[int]
    """The demo episodes whose first states are drawn."""
    prior_paths: list[list[np.ndarray]]
    """Per episode, per sample: observation dims (T + 1, 2) along the macro of a latent from p(z | s)."""
    standard_paths: list[list[np.ndarray]]
    """Likewise for latents from N(0, I)."""
    expert_paths: list[np.ndarray]
    """Per episode: the expert's own path over its first segment."""
    dims: tuple[int, int]


def _run(env: gymnasium.Env, seed: int, actions: np.ndarray, dims: tuple[int, int]) -> np.ndarray:
    obs, _ = env.reset(seed=seed)
    path = [gymnasium.spaces.flatten(env.observation_space, obs)[list(dims)]]
    for action in actions:
        obs, _, terminated, truncated, _ = env.step(action.astype(np.float32))
        path.append(gymnasium.spaces.flatten(env.observation_space, obs)[list(dims)])
        if terminated or truncated:
            break
    return np.array(path)


def propose(demos, segments, favae, prior, episodes: list[int], dims: tuple[int, int] = (0, 1), seed: int = 0):
    """Proposals from the first state of each of ``episodes`` (that start a segment at step 0)."""
    rng = np.random.default_rng(seed)
    with foreign(f"env {demos.env_id}"):
        env = make_env(demos.env_id, demos.env_kwargs)
    low, high = env.action_space.low, env.action_space.high
    prior_paths, standard_paths, expert_paths = [], [], []
    for episode in episodes:
        demo = demos.episodes[episode]
        first = np.flatnonzero((segments.episode == episode) & (segments.start == 0))
        length = int(segments.length[first[0]]) if len(first) else demo.length
        with torch.no_grad():
            mean, log_std = prior(torch.as_tensor(demo.observations[:1]))
        drawn = {
            "prior": mean.numpy() + np.exp(log_std.numpy()) * rng.standard_normal((SAMPLES, mean.shape[1])),
            "standard": rng.standard_normal((SAMPLES, mean.shape[1])),
        }
        paths = {}
        for name, latents in drawn.items():
            actions, lengths = favae.decode_macro_actions(latents.astype(np.float32))
            with foreign(f"env {demos.env_id}"):
                paths[name] = [
                    _run(env, demo.seed, np.clip(a[:n], low, high), dims) for a, n in zip(actions, lengths, strict=True)
                ]
        prior_paths.append(paths["prior"])
        standard_paths.append(paths["standard"])
        expert_paths.append(demo.observations[: length + 1, list(dims)])
    env.close()
    return Proposals(episodes, prior_paths, standard_paths, expert_paths, dims)
