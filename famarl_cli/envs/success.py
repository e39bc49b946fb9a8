"""What success means in an episode, in any env: the one rule every stage (demos, training, evaluation) uses.

In order:

1. **the user's** ``--success-return R``: the episode's return is at least R, whatever the env says;
2. **the env's report**: ``info["success"]`` or ``info["is_success"]`` on the episode's last step (famarl's envs,
   gymnasium-robotics', BipedalWalker through :class:`~famarl_cli.envs.external.ReportsBipedalSuccess`);
3. **the env's declared goal**: the return is at least ``EnvSpec.reward_threshold``, gymnasium's "the task counts
   as solved" (200 for LunarLander);
4. **not defined**: none of the above. Success is then NaN in every array and no rate is printed.

Termination is never success: LunarLander terminates on every crash, and counting that as success reported
100% for agents whose return was -118.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import gymnasium as gym

from famarl_cli.core.declare import option
from famarl_cli.core.errors import UsageError

REPORTED_KEYS = ("success", "is_success")
"""The info keys by which an env reports an episode's success."""

NOT_DEFINED = float("nan")


@dataclass(frozen=True)
class SuccessRule:
    """How an episode's success is judged (module docstring); ``threshold`` is a return to reach, from the user
    (``user=True``, which then outranks the env's report) or from the env's ``reward_threshold``."""

    threshold: float | None = None
    user: bool = False
    env_id: str = ""

    def judge(self, info: dict, episode_return: float) -> float:
        """1.0 or 0.0 for an episode that ended with ``info`` on its last step, NaN where success is not defined."""
        key = None if self.user else reported(info)
        if key is not None:
            return float(bool(info[key]))
        if self.threshold is not None:
            return float(episode_return >= self.threshold)
        return NOT_DEFINED

    def describe(self, info: dict) -> str:
        """The rule that :meth:`judge` applies to an episode ending with ``info``, in words."""
        key = None if self.user else reported(info)
        if key is not None:
            return f"info[{key!r}] reported by the env"
        if self.user:
            return f"return >= {self.threshold:g} (--success-return)"
        if self.threshold is not None:
            return f"return >= {self.threshold:g} (reward_threshold of {self.env_id})"
        return UNDEFINED


def reported(info: dict) -> str | None:
    """The key under which ``info`` reports success, None where it does not."""
    return next((key for key in REPORTED_KEYS if key in info), None)


UNDEFINED = "not defined (the env reports no success and declares no reward_threshold; give --success-return R)"
"""The rule's description where success is not defined."""


def success_rule(spec: gym.envs.registration.EnvSpec | None, success_return: float | None = None) -> SuccessRule:
    """The rule for an env with ``spec`` (None: unknown) and the user's ``--success-return``."""
    if success_return is not None:
        if not math.isfinite(success_return):
            raise UsageError(f"--success-return must be a finite return, got {success_return}")
        return SuccessRule(float(success_return), user=True)
    threshold = getattr(spec, "reward_threshold", None)
    env_id = getattr(spec, "id", "")
    if threshold is not None and math.isfinite(threshold):
        return SuccessRule(float(threshold), env_id=env_id)
    return SuccessRule(env_id=env_id)


def as_bool(success: float) -> bool | None:
    """A judged success (1.0, 0.0, NaN) as True, False, or None where it is not defined."""
    return None if math.isnan(success) else bool(success)


def shown(rate: float | None, digits: int = 0) -> str:
    """A success rate as a table shows it: "n/a" where it is None or NaN (not defined, or no episode ended)."""
    return "n/a" if rate is None or math.isnan(rate) else f"{rate:.{digits}%}"


def rate(values) -> float | None:
    """The share of successes among episodes whose success is defined; None where none is."""
    defined = [v for v in values if v is not None and not math.isnan(v)]
    return sum(defined) / len(defined) if defined else None


@dataclass(frozen=True)
class SuccessOptions:
    """``--success-return``, declared once for every command that judges episodes."""

    success_return: float | None = option(
        None,
        "An episode succeeds when its return reaches this, whatever the env reports.  [default: the env's own "
        "success report, else its gymnasium reward_threshold, else success is not defined]",
    )
