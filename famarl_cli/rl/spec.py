"""A run's settings (:class:`RunSpec`): what run.json and the checkpoint record, and all a run needs besides the
FAVAE (and prior) it decodes with; the label plots and reports give a kind of run; and what the settings build
around the policy: its action mode (:func:`build_mode`) and the prior's guidance (:func:`build_guide`)."""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from famarl_cli.core.declare import default_of, plain
from famarl_cli.core.errors import UsageError
from famarl_cli.method.favae.model import Favae
from famarl_cli.rl import Agent, MacroDecoder
from famarl_cli.rl.action_modes import (
    ActionMode,
    ClosedLoopMacroActions,
    HybridActions,
    LatentMacroActions,
    PrimitiveActions,
    RepeatedActions,
)
from famarl_cli.rl.options import RunOptions
from famarl_cli.rl.ppo import PPOConfig
from famarl_cli.rl.prior_guide import PriorGuide

if TYPE_CHECKING:  # named in annotations only
    from famarl_cli.envs.vector import BatchedEnv
    from famarl_cli.method.prior.checkpoint import Skills


@dataclass(frozen=True)
class RunSpec:
    """A run's settings, as run.json records them; those ``famarl train`` offers take its defaults
    (:class:`~famarl_cli.rl.options.RunOptions`, whose help says what each means)."""

    env_id: str
    agent: Agent
    seed: int
    ppo: PPOConfig
    latent_bound: float = default_of(RunOptions, "latent_bound")
    macro_horizon: int = 0
    """FaMARL and hybrid: macro actions are cut after this many steps (0: where the decoder stops them)."""
    residual: float = 0.0
    """Hybrid: a macro decision adds this times the primitive output to each of its actions (0: off)."""
    max_repeat: int = default_of(RunOptions, "max_repeat")
    favae: str | None = None
    """FaMARL and hybrid: the FAVAE checkpoint it was started from (its weights are copied into the run)."""
    prior: str | None = default_of(RunOptions, "prior")
    """The prior file it was started from (copied into the run like the FAVAE)."""
    prior_guide: bool = default_of(RunOptions, "prior_guide")
    prior_weight: float = default_of(RunOptions, "prior_weight")
    prior_target_kl: float = default_of(RunOptions, "prior_target_kl")
    prior_obs_prefix: bool = default_of(RunOptions, "prior_obs_prefix")
    loop: MacroDecoder = default_of(RunOptions, "loop")
    """Runs written before recorded it as ``decoder`` (:meth:`from_dict` reads both)."""
    label: str = ""
    """How plots and reports name this kind of run; seeds of one experiment share it."""
    env_kwargs: dict = field(default_factory=dict)
    """Keyword arguments of ``gymnasium.make`` (PointMaze's ``continuing_task``, say)."""
    success_return: float | None = None
    """``--success-return``: an episode succeeds when its return reaches this, whatever the env reports
    (:mod:`famarl_cli.envs.success`); None: the env's report, else its reward_threshold, else not defined."""

    def __post_init__(self) -> None:
        # Held in one form whatever the caller gave (an enum or its value, a Path or its text), so that the spec
        # written into run.json and checkpoint.pt is plain data that reads back equal.
        object.__setattr__(self, "agent", Agent(self.agent))
        object.__setattr__(self, "loop", MacroDecoder(self.loop))
        for name in ("favae", "prior"):
            if (path := getattr(self, name)) is not None:
                object.__setattr__(self, name, os.fspath(path))

    def to_dict(self) -> dict:
        """Plain data (enums as their values), as JSON and the safe checkpoint loader read it back."""
        return {**plain(asdict(self)), "ppo": self.ppo.to_dict()}

    @staticmethod
    def from_dict(values: dict) -> RunSpec:
        # Runs written before 0 meant "whole macros" stored None.
        horizon = values.get("macro_horizon") or 0
        ppo = PPOConfig.from_dict(values["ppo"])
        values = {("loop" if name == "decoder" else name): value for name, value in values.items()}
        return RunSpec(**{**values, "ppo": ppo, "macro_horizon": horizon})

    @property
    def guided(self) -> bool:
        return self.prior is not None and self.prior_guide


def default_label(
    agent: Agent, favae: str | os.PathLike | None, guided: bool = False, loop: MacroDecoder = MacroDecoder.OPEN
) -> str:
    """``<agent>[+prior][+closed] (<FAVAE file name>)``, without the name for a FAVAE named favae.pt (famarl macros
    folders)."""
    if not agent.decodes_macros:
        return str(agent)
    name = f"{agent}{'+prior' if guided else ''}{'+closed' if loop == MacroDecoder.CLOSED else ''}"
    return name if not favae or Path(favae).stem == "favae" else f"{name} ({Path(favae).stem})"


def build_mode(spec: RunSpec, env: BatchedEnv, favae: Favae | None, skills: Skills | None = None) -> ActionMode:
    """The action mode of a run of ``spec`` on ``env``: its agent's, decoding with ``favae`` (and, closed-loop,
    the decoder of ``skills``)."""
    low, high = env.action_bounds
    if spec.agent == Agent.PPO:
        return PrimitiveActions(low, high)
    if spec.agent == Agent.FIGAR:
        return RepeatedActions(low, high, spec.max_repeat)
    try:
        if spec.loop == MacroDecoder.CLOSED:
            decoder = skills.decoder.frozen()
            macros = ClosedLoopMacroActions(favae, decoder, low, high, spec.latent_bound, spec.macro_horizon)
        else:
            macros = LatentMacroActions(favae, low, high, spec.latent_bound, spec.macro_horizon)
    except ValueError as exc:
        raise UsageError(f"{spec.favae}: {exc}") from exc
    return HybridActions(macros, spec.residual) if spec.agent == Agent.HYBRID else macros


def build_guide(spec: RunSpec, mode: ActionMode, skills: Skills | None) -> PriorGuide | None:
    """The prior's guidance of the latent outputs (the last ones, for FaMARL all of them), where the run has it."""
    if skills is None or not spec.prior_guide:
        return None
    size, latent = mode.policy_action_size, skills.config.latent_size
    return PriorGuide(skills.prior.frozen(), size, slice(size - latent, size), spec.prior_weight, spec.prior_target_kl)
