"""A user's expert, named ``module:attribute`` (``famarl demos --env ID --expert module:attribute``).

The attribute is one of:

- **a class**, made once per demos run as ``Class(env)`` when its constructor takes an argument (planners need the
  env: PointMaze's maze) or ``Class()``. Its instances have ``act(observation) -> action`` and may have
  ``reset(observation)``, called at each episode's start. An instance may also keep famarl's expert protocol
  (``phase_starts``, ``phase_factors`` and ``factor_names``, as :mod:`famarl_cli.experts.bipedal` does): then
  its phases are the episode's ground truth;
- **a function** ``policy(observation) -> action``: a stateless policy.

``act`` or the function may return ``(action, phase)`` instead of an action: ``phase`` is any label and a new
phase begins where it changes. Phase boundaries are optional: without them an episode is one phase. Observations
are the env's own (a Dict stays a dict); actions must have the action space's shape and be finite.
"""

from __future__ import annotations

import importlib
import inspect
from typing import Any

import gymnasium as gym
import numpy as np

from famarl_cli.core.errors import UsageError, foreign, one_line
from famarl_cli.envs.external import importable_from_here


def resolve(path: str) -> Any:
    """The object that ``module:attribute`` names; a one-line error when it does not import."""
    module_name, _, attribute = path.partition(":")
    if not module_name or not attribute:
        raise UsageError(f"--expert must be module:attribute (like mypackage.experts:policy), got {path!r}")
    importable_from_here()
    try:
        module = importlib.import_module(module_name)
    except Exception as exc:  # the user's module may fail in any way on import
        raise UsageError(f"expert {path}: cannot import {module_name}: {type(exc).__name__}: {exc}") from exc
    try:
        target = module
        for name in attribute.split("."):
            target = getattr(target, name)
    except AttributeError as exc:
        raise UsageError(f"expert {path}: {module_name} has no {attribute!r}") from exc
    if not callable(target):
        raise UsageError(f"expert {path}: {attribute} is a {type(target).__name__}, not a class or a function")
    return target


def _construct(path: str, target: type, env: gym.Env) -> Any:
    """``target(env)`` when its constructor takes an argument, else ``target()``; one line when it needs more than
    famarl can give, or fails."""
    try:
        parameters = list(inspect.signature(target).parameters.values())
    except (TypeError, ValueError):  # a builtin or extension type without a signature
        parameters = []
    required = [
        p.name
        for p in parameters
        if p.default is p.empty and p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)
    ]
    if len(required) > 1 or any(p.kind == p.KEYWORD_ONLY and p.name in required for p in parameters):
        raise UsageError(
            f"expert {path}: {target.__name__}({', '.join(required)}) needs arguments famarl cannot give; famarl "
            f"makes it as {target.__name__}(env) or {target.__name__}()"
        )
    with foreign(f"expert {path}: {target.__name__}()"):
        return target(env) if parameters else target()


def _shown(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


class ExternalExpert:
    """Any expert of the module docstring, behind famarl's expert protocol (reset, act, phase_starts,
    phase_factors, factor_names), with its actions checked against the env's action space."""

    def __init__(self, path: str, env: gym.Env) -> None:
        self.path, self.shape = path, env.action_space.shape
        target = resolve(path)
        if inspect.isclass(target):
            self.policy = _construct(path, target, env)
            if not callable(getattr(self.policy, "act", None)):
                raise UsageError(f"expert {path}: {target.__name__} has no act(observation) method")
            self.act_fn = self.policy.act
        else:
            self.policy, self.act_fn = None, target
        self.own_phases = hasattr(self.policy, "factor_names")
        names = getattr(self.policy, "factor_names", ()) if self.own_phases else ()
        if not isinstance(names, list | tuple | np.ndarray) or not all(isinstance(name, str) for name in names):
            raise UsageError(f"expert {path}: factor_names must be a sequence of strings, got {_shown(names)}")
        self.factor_names: tuple[str, ...] = tuple(names)

    def reset(self, observation) -> None:
        if callable(getattr(self.policy, "reset", None)):
            with foreign(f"expert {self.path}: reset"):
                self.policy.reset(observation)
        self.step, self.label, self.starts = 0, object(), []

    def act(self, observation) -> np.ndarray:
        with foreign(f"expert {self.path}"):
            out = self.act_fn(observation)
        action, label = out if isinstance(out, tuple) and len(out) == 2 else (out, None)
        try:
            values = np.asarray(action)
        except ValueError as exc:  # ragged nested sequences
            raise UsageError(f"expert {self.path} returned {_shown(action)}, not an array of numbers") from exc
        if values.dtype.kind not in "biuf":
            raise UsageError(
                f"expert {self.path} returned {_shown(action)} ({values.dtype}), not real numbers; return a float array"
            )
        action = values.astype(np.float32)
        if action.shape != self.shape:
            raise UsageError(
                f"expert {self.path} returned an action of shape {action.shape}; the env takes {self.shape}"
            )
        if not np.isfinite(action).all():
            raise UsageError(f"expert {self.path} returned a non-finite action {action}")
        try:
            changed = self.step == 0 or (label is not None and bool(label != self.label))
        except (ValueError, TypeError) as exc:  # an array label: its comparison is elementwise
            raise UsageError(
                f"expert {self.path} returned the phase label {_shown(label)}; a label must be one value (a number "
                "or a string), compared with ==",
            ) from exc
        if changed:
            self.starts.append(self.step)
        self.label, self.step = label, self.step + 1
        return action

    @property
    def phase_starts(self) -> list[int]:
        return list(self.policy.phase_starts) if self.own_phases else self.starts

    @property
    def phase_factors(self) -> np.ndarray:
        if not self.own_phases:
            return np.zeros((len(self.starts), 0))
        try:
            factors = np.asarray(self.policy.phase_factors, dtype=np.float64).reshape(len(self.phase_starts), -1)
        except (TypeError, ValueError) as exc:
            raise UsageError(
                f"expert {self.path}: its phase_factors must be numbers, one row per phase start ({one_line(exc)})"
            ) from exc
        return factors
