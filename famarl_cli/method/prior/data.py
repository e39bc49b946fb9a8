"""The pairs a prior and a closed-loop decoder learn from, taken from demos, their segments and a FAVAE.

For segment i (episode e, first step t0, length n): the state s_{t0} with the FAVAE posterior q(z | segment i)
(the prior's pair), and for each of its steps k < n the state s_{t0+k}, the segment's latent, the progress
k / L (L: the FAVAE's input length) and the expert's action a_{t0+k} (the decoder's). The segments must have been
cut from these demos: their actions are compared with the demos' own.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from famarl_cli.core.errors import UsageError


@dataclass
class SkillPairs:
    episode: np.ndarray
    """(S,) the demos episode of each segment (held-out splits go by episode)."""
    start_obs: np.ndarray
    """(S, O) the state where each segment starts."""
    z_mean: np.ndarray
    """(S, Z) FAVAE posterior means."""
    z_logvar: np.ndarray
    """(S, Z) FAVAE posterior log-variances."""
    step_segment: np.ndarray
    """(N,) which segment each step belongs to."""
    step_obs: np.ndarray
    """(N, O) the state before each step."""
    step_progress: np.ndarray
    """(N,) k / L for the segment's k-th step."""
    step_actions: np.ndarray
    """(N, D) the expert's actions."""

    @property
    def obs_size(self) -> int:
        return self.start_obs.shape[1]

    @property
    def latent_size(self) -> int:
        return self.z_mean.shape[1]

    @property
    def action_size(self) -> int:
        return self.step_actions.shape[1]


def skill_pairs(demos, segments, favae, demos_name: str = "demos", segments_name: str = "segments") -> SkillPairs:
    """The pairs from :class:`~famarl_cli.artifacts.demos.Demos`, :class:`~famarl_cli.artifacts.segments.Segments`
    and a :class:`~famarl_cli.method.favae.model.Favae`; a mismatch between them is one UsageError naming both."""
    import torch

    from famarl_cli.method.favae.model import to_input

    config = favae.config
    if segments.action_dim != config.action_dim or segments.max_length != config.length:
        raise UsageError(
            f"{segments_name} holds {segments.action_dim}-D macro actions of length {segments.max_length}, but the "
            f"FAVAE reads {config.action_dim}-D ones of length {config.length}"
        )
    widths = {episode.actions.shape[1] for episode in demos.episodes}
    if widths != {segments.action_dim}:
        raise UsageError(
            f"{demos_name} holds {'/'.join(map(str, sorted(widths)))}-D actions, but {segments_name} "
            f"{segments.action_dim}-D ones: these segments were not cut from these demos"
        )
    n_episodes = len(demos.episodes)
    if len(segments.episode) == 0:
        raise UsageError(f"{segments_name} holds no segments")
    if segments.episode.max() >= n_episodes:
        raise UsageError(
            f"{segments_name} has segments of episode {int(segments.episode.max())}, but {demos_name} holds "
            f"{n_episodes} episodes: these segments were not cut from these demos"
        )
    start_obs, step_segment, step_obs, step_progress, step_actions = [], [], [], [], []
    for i, (episode, start, length, actions) in enumerate(
        zip(segments.episode, segments.start, segments.length, segments.macro_actions(), strict=True)
    ):
        demo = demos.episodes[int(episode)]
        stop = int(start) + int(length)
        if stop > demo.length or not np.allclose(demo.actions[int(start) : stop], actions, atol=1e-5):
            raise UsageError(
                f"segment {i} of {segments_name} (episode {int(episode)}, steps {int(start)}..{stop - 1}) is not in "
                f"{demos_name}: these segments were not cut from these demos"
            )
        start_obs.append(demo.observations[int(start)])
        step_segment.append(np.full(int(length), i))
        step_obs.append(demo.observations[int(start) : stop])
        step_progress.append(np.arange(int(length)) / config.length)
        step_actions.append(actions)
    with torch.no_grad():
        mus, logvars = favae.encode(to_input(segments.padded))
    return SkillPairs(
        episode=segments.episode.astype(np.int64),
        start_obs=np.asarray(start_obs, dtype=np.float32),
        z_mean=torch.cat(mus, dim=1).numpy(),
        z_logvar=torch.cat(logvars, dim=1).numpy(),
        step_segment=np.concatenate(step_segment),
        step_obs=np.concatenate(step_obs).astype(np.float32),
        step_progress=np.concatenate(step_progress).astype(np.float32),
        step_actions=np.concatenate(step_actions).astype(np.float32),
    )


def held_out_episodes(episodes: np.ndarray, share: float, seed: int) -> np.ndarray:
    """(S,) bool: which segments belong to the episodes drawn (with ``seed``) to be held out; at least one episode
    stays in training, and none is held out when ``share`` is 0 or only one episode exists."""
    unique = np.unique(episodes)
    count = min(int(round(share * len(unique))), len(unique) - 1)
    chosen = np.random.default_rng(seed).choice(unique, size=count, replace=False) if count > 0 else []
    return np.isin(episodes, chosen)
