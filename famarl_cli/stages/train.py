"""``famarl train``'s options, declared once (:mod:`famarl_cli.core.declare`), and the run they describe.

The command, ``famarl sweep train``'s jobs and the run's ``run.json`` all come from :class:`TrainOptions`, built on
the settings of PPO and of a run (:mod:`famarl_cli.rl.options`) whose defaults PPOConfig and RunSpec share;
:func:`run_spec` fills in what depends on the agent (:func:`famarl_cli.rl.agent_defaults`)."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path

from famarl_cli.artifacts.made import Replaceable, option_names
from famarl_cli.core.declare import default_of, option, pick, same_as
from famarl_cli.core.errors import UsageError
from famarl_cli.envs.external import MakeOptions
from famarl_cli.envs.success import SuccessOptions
from famarl_cli.rl import (
    DECISIONS_PER_ROLLOUT,
    HYBRID_ENTROPY_FLOOR,
    HYBRID_HORIZON,
    HYBRID_RESIDUAL,
    Agent,
    MacroDecoder,
    MacroDiscount,
    agent_defaults,
)
from famarl_cli.rl.options import DEFAULT_STEPS, PPOOptions, RunOptions
from famarl_cli.stages import defaults as inputs
from famarl_cli.sweep.registry import JobRecipe

DEFAULT_ENV = "famarl/ContinuousWorld-Maze-v0"

MACRO_AGENTS = tuple(agent for agent in Agent if agent.decodes_macros)
AGENT_OPTIONS = {
    "favae": MACRO_AGENTS,
    "macro_horizon": MACRO_AGENTS,
    "latent_bound": MACRO_AGENTS,
    "residual": (Agent.HYBRID,),
    "type_entropy_floor": (Agent.HYBRID,),
    "type_entropy_until": (Agent.HYBRID,),
    "max_repeat": (Agent.FIGAR,),
    # a PPO decision is one step, so either discount is the same
    "macro_discount": (Agent.FAMARL, Agent.FIGAR, Agent.HYBRID),
}
"""The options of :class:`TrainOptions` that only some agents use, by those agents: :func:`refuse_unused` refuses
one given (not left out, and not at its default) for an agent that ignores it."""


def either(agents: tuple[Agent, ...]) -> str:
    """``agents`` as a refusal names them: ``famarl or hybrid``, ``famarl, figar or hybrid``."""
    return " or ".join([", ".join(agents[:-1]), agents[-1]] if len(agents) > 2 else agents)


PRIOR_OPTIONS = ("prior_guide", "prior_weight", "prior_target_kl", "prior_obs_prefix")
"""The options that say how a run uses its ``--prior``: refused, where given, for a run without one."""


@dataclass(frozen=True)
class TrainOptions(RunOptions, PPOOptions):
    """``famarl train``: PPO over FAVAE latents (FaMARL), primitive actions, FiGAR's repeated actions, or the hybrid
    of macro and primitive actions."""

    env: str = option(DEFAULT_ENV, "Environment id (famarl's or any gymnasium id with Box spaces).")
    env_kwargs: dict = same_as(MakeOptions, "env_kwargs")
    agent: Agent = option(
        Agent.FAMARL,
        "famarl: search FAVAE latents; ppo: primitive actions; figar: action + repeat count; hybrid: each decision "
        "a primitive action or a macro action.",
    )
    favae: Path | None = same_as(
        inputs.FavaeInput,
        "favae",
        help="FAVAE checkpoint whose decoder makes the macro actions (famarl and hybrid).  [default: "
        f"{inputs.FAVAE}, else the main job's {inputs.replicate(0).parent}/seed<S>/{inputs.REPLICATE_FAVAE}]",
    )
    steps: int | None = option(
        None, f"Budget in environment steps.  [default: {DEFAULT_STEPS:,}; on --resume, the run's own]", min=1
    )
    seed: int = option(0, "Seed of the networks, sampling and environments.")
    out: Path | None = option(
        None, "Run folder.  [default: data/runs/<env>-<agent>[-<favae name>]-seed<S>]", path="dir", affects=False
    )
    resume: bool = option(
        False, "Continue the run in --out from its last checkpoint (other options are the run's own)."
    )
    overwrite: bool = same_as(
        Replaceable,
        "overwrite",
        help="Start afresh where --out holds a run (made from other inputs or options, or by hand); without it, a "
        "run made from the same inputs and options continues, or is left as it is where it is complete.",
    )
    n_steps: int | None = option(
        None,
        "Decisions per environment per rollout.  [default: "
        + ", ".join(f"{agent} {n}" for agent, n in DECISIONS_PER_ROLLOUT.items())
        + "]",
        min=1,
    )
    macro_discount: MacroDiscount | None = option(
        None,
        "decision: gamma per decision, rewards summed (the paper); steps: gamma ** length, rewards scaled and "
        "discounted per step (semi-MDP).  [default: steps for hybrid, decision otherwise]",
    )
    macro_horizon: int | None = option(
        None,
        "famarl, hybrid: cut macro actions after this many steps and decide again (0: run them whole).  "
        f"[default: {HYBRID_HORIZON} for hybrid, 0 otherwise]",
        min=0,
    )
    residual: float | None = option(
        None,
        "hybrid: a macro decision adds this times the primitive output to each of its actions (0: off).  "
        f"[default: {HYBRID_RESIDUAL}]",
        min=0.0,
    )
    type_entropy_floor: float | None = option(
        None,
        "hybrid: keep the type head's entropy above this many nats early in training (0: off).  "
        f"[default: {HYBRID_ENTROPY_FLOOR}]",
        min=0.0,
    )
    checkpoint_every: int = option(20, "Save the run every this many updates (and at the end).", min=1)
    label: str | None = option(None, "Name of this kind of run in plots.  [default: agent (favae name)]")
    tensorboard: Path | None = option(
        None,
        "Also write the training log as TensorBoard scalars (CleanRL's names) into this folder; needs the "
        "tensorboard extra.",
        path="dir",
    )
    success_return: float | None = same_as(SuccessOptions, "success_return")

    @property
    def destination(self) -> Path:
        if self.out is not None:
            return self.out
        env_name = self.env.split("/")[-1].rsplit("-v", 1)[0].lower()
        suffix = f"-{inputs.named_after(self.favae_file)}" if self.agent.decodes_macros else ""
        if self.agent.decodes_macros and self.prior is not None:
            suffix += ("-prior" if self.prior_guide else "") + ("-closed" if self.loop == MacroDecoder.CLOSED else "")
        return Path("data/runs") / f"{env_name}-{self.agent}{suffix}-seed{self.seed}"

    @property
    def favae_file(self) -> Path:
        """--favae, else the manual chain's FAVAE, else the main job's of this seed
        (:mod:`famarl_cli.stages.defaults`)."""
        return self.favae or inputs.favae("--favae", self.seed)

    def __post_init__(self) -> None:
        if self.loop == MacroDecoder.CLOSED and not self.agent.decodes_macros:
            raise UsageError(
                f"--loop closed goes with --agent {either(MACRO_AGENTS)}, not {self.agent}: {self.agent} has no macro "
                "actions"
            )
        if self.loop == MacroDecoder.CLOSED and self.prior is None:
            raise UsageError("--loop closed needs --prior: the closed-loop decoder is in the prior file")
        if self.prior is not None and not self.agent.decodes_macros:
            raise UsageError(
                f"--prior goes with --agent {either(MACRO_AGENTS)}, not {self.agent}: {self.agent} has no latent"
            )


RENAMED = {
    "env_id": "env",
    "ppo.total_steps": "steps",
    "ppo.learning_rate": "lr",
    "ppo.normalize_obs": "normalize",
    "ppo.scale_rewards": "normalize",
}
"""A run's settings (RunSpec's, PPOConfig's under ``ppo.``) set by an option of another name; every other setting
an option of :class:`TrainOptions` has is set by the option of its own name."""


def run_spec(options: TrainOptions):
    """The RunSpec that ``famarl train``'s options describe (shared with ``famarl sweep train``): each setting is
    its option's (:data:`RENAMED`), and those the user left out that depend on the agent are the agent's."""
    from famarl_cli.rl.ppo import PPOConfig
    from famarl_cli.rl.spec import RunSpec, default_label

    left_out = {name: value for name, value in agent_defaults(options.agent).items() if getattr(options, name) is None}
    o = replace(options, steps=options.steps or DEFAULT_STEPS, **left_out)
    renamed = {setting: getattr(o, name) for setting, name in RENAMED.items()}
    try:
        ppo = pick(PPOConfig, o, **{k.removeprefix("ppo."): v for k, v in renamed.items() if k.startswith("ppo.")})
    except ValueError as exc:
        raise UsageError(str(exc)) from exc
    favae = o.favae_file if o.agent.decodes_macros else None
    label = o.label or default_label(o.agent, favae, o.prior is not None and o.prior_guide, o.loop)
    return pick(RunSpec, o, ppo=ppo, favae=favae, label=label, env_id=renamed["env_id"])


def new_run(options: TrainOptions):
    """The run ``famarl train`` would start from ``options``, built (its options and input files checked) before
    anything is written; None where ``--resume`` continues the one in the run folder instead."""
    from famarl_cli.rl.training import Run

    if options.resume:
        return None
    refuse_unused(options)
    return Run.start(run_spec(options))


def refuse_unused(options: TrainOptions) -> None:
    """A usage error naming the first option given that the run does not use: one of :data:`AGENT_OPTIONS` that
    ``options.agent`` ignores, or one of :data:`PRIOR_OPTIONS` without ``--prior``. ``famarl train`` alone refuses
    them: a sweep's options are every run's, and ``--favae`` beside ``--over agent=famarl,ppo`` is the famarl runs'
    (the pipelines')."""
    flags = option_names(TrainOptions)

    def given(name: str) -> bool:
        value = getattr(options, name)
        return value is not None and value != default_of(TrainOptions, name)

    def typed(name: str) -> str:  # a switch turned off is typed --no-<name>
        return flags[name].replace("--", "--no-", 1) if getattr(options, name) is False else flags[name]

    for name, agents in AGENT_OPTIONS.items():
        if given(name) and options.agent not in agents:
            raise UsageError(
                f"{typed(name)} goes with --agent {either(agents)}, not {options.agent}, which does not use it"
            )
    for name in PRIOR_OPTIONS:
        if given(name) and options.prior is None:
            raise UsageError(f"{typed(name)} says how a run uses its --prior: give --prior, or leave it out")


@contextlib.contextmanager
def claimed_run(options: TrainOptions, fresh) -> Iterator:
    """The run to train in ``options.destination``, its folder held against a second ``famarl train`` meanwhile:
    ``fresh`` (from :func:`new_run`) where it starts afresh, else the one there continued, under the rule of every
    command for an output made from other options (:mod:`famarl_cli.artifacts.made`). A fresh run replaces the old
    run's files only once it has started, so a bad option never costs the user the old run."""
    from famarl_cli.artifacts.lock import claim_folder
    from famarl_cli.artifacts.made import claim_output
    from famarl_cli.artifacts.runs import CHECKPOINT_FILE, EVAL_FILE, LOG_FILE, ROLLOUTS_FILE, RUN_FILE
    from famarl_cli.rl.training import Run

    out = options.destination
    with claim_folder(out):
        if fresh is None:
            run = Run.resume(out, options.steps)
        else:
            made, instead = fresh.provenance["made_from"], "--resume to continue it as it was made"
            afresh = claim_output([out / RUN_FILE], made, options.overwrite, instead=instead, names=setting_options())
            run = fresh if afresh else Run.resume(out)
        if run is fresh:
            for name in (RUN_FILE, CHECKPOINT_FILE, LOG_FILE, EVAL_FILE, ROLLOUTS_FILE):
                (out / name).unlink(missing_ok=True)
        yield run


def board(path: Path | None):
    """The TensorBoard log ``--tensorboard`` asks for (each update's row), or None."""
    if path is None:
        return None
    from famarl_cli.rl.tensorboard import TensorBoardLog

    return TensorBoardLog(path)


def train_job(options: TrainOptions) -> JobRecipe:
    """``famarl sweep train``: each run of the sweep is what ``famarl train`` with the same options would do; the
    seeds of one setting train together in batches (famarl sweep --batch), each run in its own folder."""
    from famarl_cli.rl.training import run_jobs

    spec = run_spec(options)
    return JobRecipe(
        run_jobs,
        {"spec": spec.to_dict(), "checkpoint_every": options.checkpoint_every},
        inputs=tuple(path for path in (spec.favae, spec.prior) if path),
        resumable=True,
        batched=True,
    )


def setting_options() -> dict[str, str]:
    """Each setting of a run (run.json's spec, dotted: ``ppo.epochs``) by the ``famarl train`` option that sets it
    (``--update-epochs``): how a refusal names a change in the options the user types. Settings no option sets
    (``ppo.vf_coef``) keep their own names."""
    from dataclasses import fields

    from famarl_cli.core.declare import declared
    from famarl_cli.rl.ppo import PPOConfig
    from famarl_cli.rl.spec import RunSpec

    flags = option_names(TrainOptions)
    # a run recorded before a setting was renamed names it by its former name (``decoder``, now ``loop``)
    former = {old: declaration.flag for declaration in declared(TrainOptions) for old in declaration.former}
    settings = [f.name for f in fields(RunSpec) if f.name != "ppo"] + [f"ppo.{f.name}" for f in fields(PPOConfig)]
    named = {setting: RENAMED.get(setting, setting.removeprefix("ppo.")) for setting in settings}
    return {**former, **{setting: flags[option] for setting, option in named.items() if option in flags}}
