"""The demos file: expert episodes plus the ground truth their scripts know.

Layout (HDF5, after Minari's, so plain h5py and Minari-style readers find their way)::

    /                      attrs: schema="famarl.demos", schema_version, famarl_version, provenance (JSON),
                                  env_id, env_kwargs (JSON), script, seed, n_episodes, total_steps,
                                  factor_names (JSON), attempts (episodes the expert ran, kept or not),
                                  success_rule (how success was judged, famarl_cli.envs.success)
    /episode_{i}/          attrs: id, seed (the episode's reset seed), total_steps, success (absent where
                                  success is not defined)
        observations       (T+1, obs_dim) float32, the reset observation first
        actions            (T, act_dim)   float32
        rewards            (T,)           float64
        terminations       (T,)           bool
        truncations        (T,)           bool
        ground_truth/
            segment_starts (K,)           int64, first step of each expert phase; starts at 0, increasing
            factors        (K, F)         float64, each phase's factors, columns named by factor_names

Nothing downstream of the demos stage may read ``ground_truth`` except evaluation metrics.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from famarl_cli.artifacts.base import atomic_path, check, open_artifact, require, write_header
from famarl_cli.envs.success import rate

SCHEMA = "famarl.demos"
SCHEMA_VERSION = 1
STEPS = {
    "observations": np.float32,
    "actions": np.float32,
    "rewards": np.float64,
    "terminations": bool,
    "truncations": bool,
}
"""Each episode's per-step arrays and their stored dtypes."""
TRUTH = {"segment_starts": np.int64, "factors": np.float64}
"""Each episode's ground truth (``ground_truth/``) and its stored dtypes."""
OLD_SUCCESS_RULE = "termination (a file written before famarl judged success by its rules)"
"""Files written before ``success_rule`` existed stored success as the last step's termination."""


@dataclass
class Episode:
    observations: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    terminations: np.ndarray
    truncations: np.ndarray
    seed: int
    segment_starts: np.ndarray
    factors: np.ndarray
    success: bool | None = None
    """Whether the episode succeeded by its demos' ``success_rule`` (:mod:`famarl_cli.envs.success`); None where
    success is not defined."""

    @property
    def length(self) -> int:
        return len(self.actions)


@dataclass
class Demos:
    episodes: list[Episode]
    env_id: str
    script: str
    seed: int
    factor_names: tuple[str, ...]
    env_kwargs: dict = field(default_factory=dict)
    provenance: dict = field(default_factory=dict)
    attempts: int | None = None
    """Episodes the expert ran, kept or not (``famarl demos --min-return`` keeps some); None: all were kept."""
    success_rule: str = ""
    """How the episodes' success was judged, in words (:mod:`famarl_cli.envs.success`)."""

    @property
    def keep_rate(self) -> float:
        return len(self.episodes) / (self.attempts or len(self.episodes))

    @property
    def total_steps(self) -> int:
        return sum(e.length for e in self.episodes)

    @property
    def has_ground_truth(self) -> bool:
        """Whether the expert said what its phases were: named factors, or more than one phase in some episode.
        Demos from outside (a Minari dataset, a policy without phase labels) have none to score against."""
        return bool(self.factor_names) or any(len(e.segment_starts) > 1 for e in self.episodes)

    @property
    def success_rate(self) -> float | None:
        """The share of episodes that succeeded; None where success is not defined."""
        return rate(e.success for e in self.episodes)


def write_demos(path: str | os.PathLike, demos: Demos) -> None:
    """Write ``demos`` to ``path`` atomically (see :func:`~famarl_cli.artifacts.base.atomic_path`)."""
    with atomic_path(path) as temp, h5py.File(temp, "w", track_order=False) as handle:
        write_header(
            handle,
            SCHEMA,
            SCHEMA_VERSION,
            demos.provenance,
            env_id=demos.env_id,
            env_kwargs=demos.env_kwargs,
            script=demos.script,
            seed=demos.seed,
            n_episodes=len(demos.episodes),
            total_steps=demos.total_steps,
            factor_names=list(demos.factor_names),
            attempts=demos.attempts or len(demos.episodes),
            success_rule=demos.success_rule,
        )
        for i, episode in enumerate(demos.episodes):
            group = handle.create_group(f"episode_{i}")
            group.attrs.update(id=i, seed=episode.seed, total_steps=episode.length)
            if episode.success is not None:  # no attribute: success is not defined
                group.attrs["success"] = episode.success
            for key, dtype in STEPS.items():
                group.create_dataset(key, data=getattr(episode, key).astype(dtype))
            truth = group.create_group("ground_truth")
            for key, dtype in TRUTH.items():
                truth.create_dataset(key, data=getattr(episode, key).astype(dtype))


def read_demos(path: str | os.PathLike) -> Demos:
    """Read and validate a demos file; every problem is an ArtifactError naming the file and the fault."""
    path = Path(path)
    with open_artifact(path, SCHEMA, SCHEMA_VERSION) as handle:
        attrs = handle.attrs
        require(attrs, ("env_id", "script", "seed", "n_episodes", "factor_names"), path, "missing attribute {!r}")
        n_episodes = int(attrs["n_episodes"])
        factor_names = tuple(json.loads(attrs["factor_names"]))
        check(n_episodes > 0, path, "holds no episodes")
        episodes = [_read_episode(handle, i, len(factor_names), path) for i in range(n_episodes)]
        widths = {(e.observations.shape[1], e.actions.shape[1]) for e in episodes}
        check(
            len(widths) == 1,
            path,
            f"its episodes differ in width: (observation, action) sizes {sorted(widths)}; one env has one of each",
        )
        return Demos(
            episodes=episodes,
            env_id=str(attrs["env_id"]),
            script=str(attrs["script"]),
            seed=int(attrs["seed"]),
            factor_names=factor_names,
            env_kwargs=json.loads(attrs.get("env_kwargs", "{}")),
            provenance=json.loads(attrs.get("provenance", "{}")),
            attempts=int(attrs.get("attempts", n_episodes)),
            success_rule=str(attrs.get("success_rule", OLD_SUCCESS_RULE)),
        )


def _read_episode(handle: h5py.File, i: int, n_factors: int, path: Path) -> Episode:
    name = f"episode_{i}"
    check(name in handle, path, f"missing group {name!r} (file says it holds more episodes)")
    group = handle[name]
    require(group, (*STEPS, "ground_truth"), path, f"{name} has no {{!r}}")
    episode = Episode(
        **{key: group[key][()] for key in STEPS},
        **{key: group[f"ground_truth/{key}"][()] for key in TRUTH},
        seed=int(group.attrs.get("seed", -1)),
        success=bool(group.attrs["success"]) if "success" in group.attrs else None,
    )
    steps = episode.actions.shape[0] if episode.actions.ndim == 2 else -1
    check(steps >= 1, path, f"{name}: actions must be a non-empty (T, action_dim) array, got {episode.actions.shape}")
    check(
        episode.observations.ndim == 2 and episode.observations.shape[0] == steps + 1,
        path,
        f"{name}: observations must have T+1 = {steps + 1} rows, got shape {episode.observations.shape}",
    )
    for key in ("rewards", "terminations", "truncations"):
        shape = getattr(episode, key).shape
        check(shape == (steps,), path, f"{name}: {key} must have shape ({steps},), got {shape}")
    fault = content_fault(episode, n_factors)
    check(fault is None, path, f"{name}: {fault}")
    return episode


def content_fault(episode: Episode, n_factors: int) -> str | None:
    """What is wrong with the values of an episode whose arrays have their shapes (T+1 observations, T actions):
    NaN or Inf, or ground truth that does not fit it; None when nothing is. Every reader of episodes (our files,
    Minari datasets) holds them to these rules."""
    for key in ("observations", "actions", "rewards"):
        if not np.isfinite(getattr(episode, key)).all():
            return f"{key} contain NaN or Inf"
    starts, steps = episode.segment_starts, episode.length
    if not (
        starts.ndim == 1
        and len(starts) >= 1
        and starts[0] == 0
        and bool(np.all(np.diff(starts) > 0))
        and starts[-1] < steps
    ):
        return f"ground_truth/segment_starts must increase from 0 and stay below {steps}, got {starts}"
    if episode.factors.shape != (len(starts), n_factors):
        return f"ground_truth/factors must have shape ({len(starts)}, {n_factors}), got {episode.factors.shape}"
    return None
