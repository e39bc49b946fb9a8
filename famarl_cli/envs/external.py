"""Environments famarl did not write: any gymnasium id, made in one place so that every stage treats them alike.

- **Ids.** Gymnasium's own ids (``BipedalWalker-v3``, ``Pendulum-v1``), famarl's (``famarl/...``), the ids of
  gymnasium-robotics (``PointMaze_Large-v3``), which this module registers when that package is installed, and
  gymnasium's ``module:Id`` form for any package that registers its ids on import.
- **Errors.** An unknown id, keyword arguments the env does not take, a dependency that is not installed (named
  with the famarl extra that installs it) and an action space that is not a Box are one-line errors.
- **Success.** Where an env reports it (``info["success"]``, gymnasium-robotics' and RobotHand's), success is what
  it says; otherwise it is termination, except BipedalWalker, whose termination is a fall as often as the far end:
  its success is reaching the end (:class:`ReportsBipedalSuccess`).
- **Observations** of any space with a flat form are flattened by :class:`~famarl_cli.rl.vector.GymBatch` with
  ``gymnasium.spaces.flatten``: a Dict's entries in the space's key order, which gymnasium sorts (PointMaze:
  achieved_goal (2), desired_goal (2), observation (4)).
"""

from __future__ import annotations

import contextlib
import importlib.util
import io
import warnings

import gymnasium as gym

from famarl_cli.errors import FamarlError, UsageError

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
    """``gymnasium.make(env_id, **env_kwargs, **make_kwargs)`` with famarl's errors and success report."""
    kwargs = {**(env_kwargs or {}), **make_kwargs}
    if ":" not in env_id and env_id not in gym.registry:
        _register_robotics()
    try:
        env = gym.make(env_id, **kwargs)
    except gym.error.DependencyNotInstalled as exc:
        text = str(exc).lower()
        extra = "mujoco" if "mujoco" in text else "box2d" if ("box2d" in text or "pygame" in text) else None
        if extra is None:
            raise FamarlError(f"{env_id}: a dependency is missing: {exc}") from exc
        raise MissingExtra(extra, env_id) from exc
    except gym.error.Error as exc:
        if importlib.util.find_spec("gymnasium_robotics") is None and "Maze" in env_id:
            raise MissingExtra("mujoco", env_id) from exc
        raise UsageError(f"unknown environment {env_id!r}: {str(exc).splitlines()[0]}") from exc
    except TypeError as exc:
        raise UsageError(f"{env_id} does not take the keyword arguments {kwargs}: {exc}") from exc
    except ModuleNotFoundError as exc:
        raise UsageError(f"{env_id}: cannot import {exc.name!r}") from exc
    if not isinstance(env.action_space, gym.spaces.Box):
        env.close()
        raise UsageError(f"{env_id}: famarl needs a Box (continuous) action space, not {env.action_space}")
    if type(env.unwrapped).__name__ == "BipedalWalker":
        env = ReportsBipedalSuccess(env)
    return env


def episode_success(info: dict, terminated: bool) -> bool:
    """Whether a finished step succeeded: the env's own report where it gives one, else termination."""
    for key in ("success", "is_success"):
        if key in info:
            return bool(info[key])
    return bool(terminated)


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
    except json.JSONDecodeError as exc:
        raise UsageError(f"--env-kwargs must be a JSON object like '{{\"continuing_task\": false}}': {exc}") from exc
    if not isinstance(kwargs, dict):
        raise UsageError(f"--env-kwargs must be a JSON object, got {text!r}")
    return kwargs
