"""Latent traversal: move one FAVAE latent variable over a range of values, keep the others fixed, decode, and
run each decoded macro action to see what the variable controls (the paper's Figure 5). Macro actions run in the
empty world of the env family they were learned in (:data:`famarl_cli.envs.WORLDS`: ContinuousWorld, or RobotHand,
whose grip point's path is drawn); given an env id, they run in that gymnasium env and two chosen observation
dimensions are drawn (:func:`run_in_env`).

Variables are named (ladder, index), both counted from 1 as in the paper: (3, 1) is the first latent of the
third, deepest ladder. The fixed latent vector is the prior's mean, 0. Each decoded macro action runs open-loop
from rest at the centre of an empty world (ContinuousWorld: a square twice Base's largest map; RobotHand: the hand
alone, no objects), so a macro action as long as the demos' longest
legs (about 5 m) never reaches an edge; values far outside the prior (|z| >= 3) can decode longer ones.

A variable's *effect* (metres) is how far apart the paths of neighbouring values are: the mean distance between
the two paths over time (the shorter held at its end), averaged over neighbouring pairs of values. A variable that
learned a factor moves the path; one that learned nothing has an effect near 0.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from famarl_cli.artifacts.traversal import Traversal
from famarl_cli.core.errors import FamarlError, UsageError, foreign
from famarl_cli.envs import DEFAULT_WORLD, WORLDS

EMPTY_LADDER_NATS = 0.1
"""A ladder whose variables together carry less information than this about the training segments
(:func:`famarl_cli.method.favae.loss.data_information`, at most log N) is empty: an active latent carries several
nats. A ladder can have a large KL and be empty: a posterior shifted alike for
every segment costs KL and says nothing."""


def variables_of(model: Favae, ladder: int | None, index: int | None) -> list[tuple[int, int]]:
    """The (ladder, index) pairs to traverse: all of one ladder, one variable, or every variable of the model."""
    dims = model.config.latent_dims
    if ladder is not None and not 1 <= ladder <= len(dims):
        raise UsageError(f"ladder {ladder} does not exist: the model has ladders 1..{len(dims)}")
    if index is not None and ladder is None:
        raise UsageError("--index needs --ladder")
    if index is not None and not 1 <= index <= dims[ladder - 1]:
        raise UsageError(f"index {index} does not exist: ladder {ladder} has variables 1..{dims[ladder - 1]}")
    ladders = [ladder] if ladder else range(1, len(dims) + 1)
    return [(lad, i) for lad in ladders for i in ([index] if index else range(1, dims[lad - 1] + 1))]


if TYPE_CHECKING:  # the model is only passed through: reading this module does not load torch
    from famarl_cli.method.favae.model import Favae

DRAWS = ("run", "values")
"""How a decoded sequence becomes a path: ``run`` it as actions in the environment that takes their size, or draw
its first two dimensions as positions (``values``: sequences that are themselves paths, like 2D Reaching's)."""


def traverse(
    model: Favae,
    variables: list[tuple[int, int]],
    values: list[float],
    draw: str = "run",
    env_id: str | None = None,
    env_kwargs: dict | None = None,
    dims: tuple[int, int] = (0, 1),
    frames: bool = False,
    world: str = DEFAULT_WORLD,
) -> Traversal:
    """Traverse ``variables`` over ``values``, running the macro actions in the empty ``world`` of one of famarl's
    env families (:func:`run_macro_actions`). With ``env_id`` instead, each macro action runs in that gymnasium env from
    ``reset(seed=0)``, its path is the observation dimensions ``dims`` and, with ``frames``, what the env renders
    at its end is kept (:func:`run_in_env`)."""
    if draw not in DRAWS:
        raise UsageError(f"draw must be one of {DRAWS}, got {draw!r}")
    if len(values) < 2:
        raise UsageError(f"give at least two values to traverse, got {values}")
    z = np.zeros((len(variables), len(values), model.config.latent_size), dtype=np.float32)
    for v, (ladder, index) in enumerate(variables):
        z[v, :, model.config.latent_index(ladder, index)] = values
    flat = z.reshape(-1, z.shape[-1])
    actions, lengths = model.decode_macro_actions(flat)
    end_frames = None
    if draw == "values":
        paths = sequence_paths(actions, lengths)
    elif env_id is not None:
        paths, end_frames = run_in_env(actions, lengths, env_id, env_kwargs, dims, frames)
    else:
        paths = run_macro_actions(actions, lengths, world)
    shape = (len(variables), len(values))
    paths = paths.reshape(*shape, *paths.shape[1:])
    gaps = np.linalg.norm(paths[:, 1:] - paths[:, :-1], axis=-1)  # (V, K - 1, L + 1)
    return Traversal(
        variables=np.array(variables, dtype=np.int64),
        values=np.array(values, dtype=np.float64),
        actions=actions.reshape(*shape, *actions.shape[1:]),
        lengths=lengths.reshape(shape),
        paths=paths,
        effects=gaps.mean(axis=(1, 2)),
        frames=None if end_frames is None else end_frames.reshape(*shape, *end_frames.shape[1:]),
    )


def empty_ladders(variables: list[tuple[int, int]], information: list[float]) -> dict[int, float]:
    """The ladders among ``variables`` whose traversed variables together carry under :data:`EMPTY_LADDER_NATS`,
    with the nats they carry (``information`` is each variable's, in the order of ``variables``)."""
    by_ladder: dict[int, float] = {}
    for (ladder, _), nats in zip(variables, information, strict=True):
        by_ladder[ladder] = by_ladder.get(ladder, 0.0) + nats
    return {ladder: nats for ladder, nats in by_ladder.items() if nats < EMPTY_LADDER_NATS}


def sequence_paths(sequences: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """(n, L + 1, 2) paths whose points are the sequences' first two dimensions, the first repeated at the start
    (where a run's path has its starting point) and the last held past each length."""
    if sequences.shape[-1] < 2:
        raise UsageError("drawing sequences as paths needs at least two dimensions")
    points = sequences[..., :2]
    steps = np.arange(points.shape[1])
    held = np.minimum(steps[None, :], (lengths - 1)[:, None])
    points = np.take_along_axis(points, held[..., None], axis=1)
    return np.concatenate([points[:, :1], points], axis=1)


def run_macro_actions(actions: np.ndarray, lengths: np.ndarray, world: str = DEFAULT_WORLD) -> np.ndarray:
    """(n, L + 1, 2) paths of (n, L, D) macro actions run in the empty world of famarl's env family ``world`` (a
    key of :data:`famarl_cli.envs.WORLDS`), which must take D-dimensional actions."""
    if world not in WORLDS:
        raise UsageError(f"no traversal world {world!r}; famarl's are {', '.join(WORLDS)}")
    size = WORLDS[world].ACTION_SPACE.shape[0]
    if actions.shape[-1] != size:
        raise UsageError(
            f"the FAVAE decodes {actions.shape[-1]}-dimensional actions and the {world} world takes {size}: give "
            f"the world of the demos' env (--world), or --env for a gymnasium env"
        )
    return WORLDS[world].traversal_paths(actions, lengths)


def run_in_env(
    actions: np.ndarray,
    lengths: np.ndarray,
    env_id: str,
    env_kwargs: dict | None,
    dims: tuple[int, int],
    frames: bool = False,
) -> tuple[np.ndarray, np.ndarray | None]:
    """Run (n, L, D) macro actions open-loop in any gymnasium env, each from the same reset (seed 0). Returns
    their (n, L + 1, 2) paths, the flattened observation's dimensions ``dims`` held after the macro action ends
    or the episode does, and, with ``frames``, what the env renders at each one's end ((n, H, W, 3), else None)."""
    import gymnasium as gym

    from famarl_cli.envs.external import make_env

    env = make_env(env_id, env_kwargs, **({"render_mode": "rgb_array"} if frames else {}))
    size = gym.spaces.flatdim(env.observation_space)
    if env.action_space.shape != actions.shape[-1:]:
        raise UsageError(
            f"{env_id} takes actions of shape {env.action_space.shape}, the model decodes {actions.shape[-1]}"
        )
    if not all(-size <= d < size for d in dims):
        raise UsageError(f"observation dimensions {dims} do not exist: {env_id}'s observations have {size}")
    paths, ends = np.zeros((len(actions), actions.shape[1] + 1, 2)), []
    for i, (sequence, length) in enumerate(zip(actions, lengths, strict=True)):
        with foreign(f"env {env_id} reset"):
            obs, _ = env.reset(seed=0)
        points = [gym.spaces.flatten(env.observation_space, obs)[list(dims)]]
        for action in sequence[:length]:
            with foreign(f"env {env_id} step"):
                obs, _, terminated, truncated, _ = env.step(
                    np.clip(action, env.action_space.low, env.action_space.high)
                )
            points.append(gym.spaces.flatten(env.observation_space, obs)[list(dims)])
            if terminated or truncated:
                break
        paths[i, : len(points)] = points
        paths[i, len(points) :] = points[-1]
        if frames:
            ends.append(_render(env, env_id))
    env.close()
    return paths, np.stack(ends) if frames else None


def _render(env, env_id: str) -> np.ndarray:
    try:
        return np.asarray(env.render())
    except Exception as exc:  # each renderer fails its own way without a display (MuJoCo: no OpenGL context)
        raise FamarlError(
            f"{env_id} cannot render here ({type(exc).__name__}: {exc}); MuJoCo envs need MUJOCO_GL=egl or osmesa "
            "on a machine without a display"
        ) from exc


def parse_values(text: str) -> list[float]:
    """``--values``: the finite latent values a traversal gives its variable, at least one."""
    wanted = f"values must be finite numbers separated by commas, like -3,-1,1,3; got {text!r}"
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError as exc:
        raise UsageError(wanted) from exc
    if not values or not all(math.isfinite(v) for v in values):
        raise UsageError(wanted)
    return values


def parse_dims(text: str) -> tuple[int, int]:
    """``--obs-dims``: two observation dimensions, like ``0,1``."""
    try:
        dims = tuple(int(v) for v in text.split(","))
    except ValueError as exc:
        raise UsageError(f"give two observation dimensions, like 0,1; got {text!r}") from exc
    if len(dims) != 2:
        raise UsageError(f"give two observation dimensions, like 0,1; got {text!r}")
    return dims
