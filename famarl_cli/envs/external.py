"""Environments famarl did not write: any gymnasium id, made in one place so that every stage treats them alike.

- **Ids.** Gymnasium's own ids (``BipedalWalker-v3``, ``Pendulum-v1``), famarl's (``famarl/...``), the ids of
  gymnasium-robotics (``PointMaze_Large-v3``), which this module registers when that package is installed, and
  gymnasium's ``module:Id`` form for any package that registers its ids on import.
- **Errors.** An unknown id, keyword arguments the env does not take, a dependency that is not installed (named
  with the famarl extra that installs it) and an action space that is not a Box are one-line errors.
- **Success** follows :mod:`famarl_cli.envs.success`: the env's report where it gives one (gymnasium-robotics',
  famarl's), else its ``reward_threshold``, never termination. BipedalWalker's termination is a fall as often as
  the far end: it reports reaching the end (:class:`ReportsBipedalSuccess`).
- **Observations** of any space with a flat form are flattened by :class:`~famarl_cli.envs.vector.GymBatch` with
  ``gymnasium.spaces.flatten``: a Dict's entries in the space's key order, which gymnasium sorts (PointMaze:
  achieved_goal (2), desired_goal (2), observation (4)).
"""

from __future__ import annotations

import contextlib
import importlib.util
import io
import os
import sys
import warnings
from dataclasses import dataclass

import gymnasium as gym

from famarl_cli.core.declare import option
from famarl_cli.core.errors import FamarlError, ForeignError, UsageError, foreign

EXTRAS = {
    "box2d": "Box2D (BipedalWalker, LunarLander, CarRacing)",
    "mujoco": "MuJoCo and gymnasium-robotics (PointMaze, AntMaze, Fetch, the MuJoCo tasks)",
    "minari": "Minari datasets",
}
"""famarl's optional extras for environments and data, with what each installs (pyproject.toml)."""


class MissingExtra(FamarlError):
    """A feature whose dependency is not installed; the message names the extra that installs it."""

    def __init__(self, extra: str, what: str) -> None:
        super().__init__(f"{what} needs the {extra} extra ({EXTRAS[extra]}): pip install 'famarl[{extra}]'")


def _register_robotics() -> None:
    if importlib.util.find_spec("gymnasium_robotics") is not None:
        # Its import prints a notice about envs famarl does not use (AdroitHand) into the user's output.
        with contextlib.redirect_stderr(io.StringIO()), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            import gymnasium_robotics

        gym.register_envs(gymnasium_robotics)


def make_env(env_id: str, env_kwargs: dict | None = None, **make_kwargs) -> gym.Env:
    """``gymnasium.make(env_id, **env_kwargs, **make_kwargs)`` with famarl's errors and success report. The env's
    own constructor may fail in any way (an assertion on a keyword's range): that is one line naming the env."""
    kwargs = {**(env_kwargs or {}), **make_kwargs}
    module, _, name = env_id.rpartition(":")
    if ":" in env_id and (not module or not name):
        raise UsageError(f"environment {env_id!r}: the module:Id form needs both a module and an id")
    steps = kwargs.get("max_episode_steps")
    if steps is not None and (isinstance(steps, bool) or not isinstance(steps, int) or steps < 1):
        raise UsageError(f"{env_id}: max_episode_steps must be a positive integer, got {steps!r}")
    if ":" in env_id:
        importable_from_here()
    elif env_id not in gym.registry:
        _register_robotics()
    try:
        with foreign(f"env {env_id}"):
            env = gym.make(env_id, **kwargs)
    except ForeignError as exc:
        raise _make_error(env_id, kwargs, exc.__cause__) or exc from exc.__cause__
    if not isinstance(env.action_space, gym.spaces.Box):
        env.close()
        raise UsageError(f"{env_id}: famarl needs a Box (continuous) action space, not {env.action_space}")
    if type(env.unwrapped).__name__ == "BipedalWalker":
        env = ReportsBipedalSuccess(env)
    return env


def importable_from_here() -> None:
    """Users' own modules, named ``module:attribute`` (an env here, an expert in famarl_cli.experts.external), are
    found in the current folder too, as ``python -m`` finds them: an installed command such as ``famarl`` starts
    without it on ``sys.path``. The folder goes last, so a module of the user's does not shadow an installed
    package of the same name."""
    here = os.getcwd()
    if here not in sys.path and "" not in sys.path:
        sys.path.append(here)


def _make_error(env_id: str, kwargs: dict, exc: BaseException) -> FamarlError | None:
    """The error a failed ``gymnasium.make`` is known to mean (a missing extra, an unknown id, keyword arguments
    the env does not take); None for any other failure of the env's own code."""
    if isinstance(exc, gym.error.DependencyNotInstalled):
        text = str(exc).lower()
        extra = "mujoco" if "mujoco" in text else "box2d" if ("box2d" in text or "pygame" in text) else None
        if extra is None:
            return FamarlError(f"{env_id}: a dependency is missing: {exc}")
        return MissingExtra(extra, env_id)
    if isinstance(exc, gym.error.Error):
        if importlib.util.find_spec("gymnasium_robotics") is None and "Maze" in env_id:
            return MissingExtra("mujoco", env_id)
        return UsageError(f"unknown environment {env_id!r}: {str(exc).splitlines()[0]}")
    if isinstance(exc, TypeError) and "argument" in str(exc):
        return UsageError(f"{env_id} does not take the keyword arguments {kwargs}: {exc}")
    if isinstance(exc, ModuleNotFoundError):
        return UsageError(f"{env_id}: cannot import {exc.name!r}")
    return None


BIPEDAL_FALL_REWARD = -100.0
"""The reward BipedalWalker gives, and only gives, on the step it falls (or walks off the start)."""


class ReportsBipedalSuccess(gym.Wrapper):
    """BipedalWalker with ``info["success"]``: the episode terminated at the far end, not by a fall."""

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        info = {**info, "success": bool(terminated and reward != BIPEDAL_FALL_REWARD)}
        return obs, reward, terminated, truncated, info


def parse_env_kwargs(text: str | None) -> dict:
    """``--env-kwargs``: a JSON object of ``gymnasium.make`` keyword arguments (None or empty: none)."""
    import json

    if not text:
        return {}
    try:
        kwargs = json.loads(text)
    except RecursionError as exc:
        raise UsageError("--env-kwargs is nested too deeply to be keyword arguments") from exc
    except json.JSONDecodeError as exc:
        raise UsageError(f"--env-kwargs must be a JSON object like '{{\"continuing_task\": false}}': {exc}") from exc
    if not isinstance(kwargs, dict):
        raise UsageError(f"--env-kwargs must be a JSON object, got {text!r}")
    return kwargs


@dataclass(frozen=True)
class MakeOptions:
    """What ``gymnasium.make`` gets besides the id, declared once for every command that makes an env."""

    env_kwargs: dict = option(
        factory=dict,
        help="Keyword arguments of gymnasium.make, as JSON: '{\"continuing_task\": false}'.",
        parse=parse_env_kwargs,
    )
