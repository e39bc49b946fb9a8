"""``famarl train``'s options, declared once (:mod:`famarl_cli.core.declare`), and the run they describe.

The command, ``famarl sweep train``'s jobs and the run's ``run.json`` all come from :class:`TrainOptions`;
:func:`run_spec` fills in what depends on the agent (:func:`famarl_cli.rl.agent_defaults`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from famarl_cli.artifacts.made import Replaceable
from famarl_cli.core.declare import option, same_as
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
from famarl_cli.stages import defaults as inputs

DEFAULT_ENV = "famarl/ContinuousWorld-Maze-v0"
DEFAULT_STEPS = 1_000_000


@dataclass(frozen=True)
class TrainOptions:
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
    prior: Path | None = option(
        None,
        "famarl, hybrid: a prior file of famarl prior fit on this FAVAE's latents: the latent policy starts at its "
        "p(z | s) and pays its KL (see --prior-weight), and --loop closed uses its closed-loop decoder.",
    )
    prior_guide: bool = option(
        True, "With --prior: start the latent policy at p(z | s) and regularise it towards it (off: decoder only)."
    )
    prior_weight: float = option(
        0.1, "With --prior: the KL's weight; with --prior-target-kl, its starting value.", min=0.0
    )
    prior_target_kl: float = option(
        0.0, "With --prior: tune the KL's weight so that the KL stays near this many nats (0: keep it fixed).", min=0.0
    )
    prior_obs_prefix: bool = option(
        False,
        "With --prior: its networks read the first values of the env's observation, as many as the demos' had (the "
        "demos were recorded in another env whose observation begins this one's: ContinuousWorld Base's 8 values "
        "begin the Maze's 12).",
    )
    loop: MacroDecoder = option(
        MacroDecoder.OPEN,
        "famarl, hybrid: open: the FAVAE's decoder, fixed when the macro starts (the paper's); closed: the "
        "closed-loop decoder of --prior, which chooses each action from the state reached.",
        renamed=("--decoder",),
        former=("decoder",),
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
    n_envs: int = option(16, "Environments stepped together.", min=1)
    n_steps: int | None = option(
        None,
        "Decisions per environment per rollout.  [default: "
        + ", ".join(f"{agent} {n}" for agent, n in DECISIONS_PER_ROLLOUT.items())
        + "]",
        min=1,
    )
    epochs: int = option(
        10,
        "PPO epochs per rollout (passes over its minibatches).",
        min=1,
        flags=("--update-epochs",),
        renamed=("--epochs",),
    )
    minibatches: int = option(8, "Minibatches per epoch.", min=1)
    lr: float = option(3e-4, "Adam learning rate (annealed linearly to 0 over the budget).", min=0.0)
    gamma: float = option(0.99, "Discount per decision (or per step with --macro-discount steps).", min=0.0, max=1.0)
    gae_lambda: float = option(0.95, "GAE lambda.", min=0.0, max=1.0)
    clip: float = option(0.2, "PPO clip range (policy ratio and value).", min=0.0)
    ent_coef: float = option(0.0, "Entropy bonus weight.", min=0.0)
    macro_discount: MacroDiscount | None = option(
        None,
        "decision: gamma per decision, rewards summed (the paper); steps: gamma ** length, rewards scaled and "
        "discounted per step (semi-MDP).  [default: steps for hybrid, decision otherwise]",
    )
    latent_bound: float = option(3.0, "famarl, hybrid: clip latents to [-bound, bound] before decoding.", min=0.0)
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
    type_entropy_until: float = option(
        0.25, "hybrid: share of the budget during which the floor holds.", min=0.0, max=1.0
    )
    max_repeat: int = option(32, "figar: the largest repeat count J.", min=1)
    normalize: bool = option(True, "Normalise observations and scale rewards by the return's std.")
    clip_value: bool = option(True, "Clip the value loss like the policy ratio (CleanRL's default).")
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
        if self.loop == MacroDecoder.CLOSED and self.prior is None:
            raise UsageError("--loop closed needs --prior: the closed-loop decoder is in the prior file")
        if self.prior is not None and not self.agent.decodes_macros:
            raise UsageError(
                f"--prior goes with --agent famarl or hybrid, not {self.agent}: {self.agent} has no latent"
            )


def run_spec(options: TrainOptions):
    """The RunSpec that ``famarl train``'s options describe (shared with ``famarl sweep train``): the options the
    user left out take the agent's defaults."""
    from famarl_cli.rl.ppo import PPOConfig
    from famarl_cli.rl.training import RunSpec, default_label

    o, defaults = options, agent_defaults(options.agent)

    def given(value, name: str):
        return defaults[name] if value is None else value

    favae = o.favae_file if o.agent.decodes_macros else None

    try:
        ppo = PPOConfig(
            total_steps=o.steps or DEFAULT_STEPS,
            n_envs=o.n_envs,
            n_steps=o.n_steps or defaults["n_steps"],
            epochs=o.epochs,
            minibatches=o.minibatches,
            learning_rate=o.lr,
            gamma=o.gamma,
            gae_lambda=o.gae_lambda,
            clip=o.clip,
            clip_value=o.clip_value,
            ent_coef=o.ent_coef,
            macro_discount=str(given(o.macro_discount, "macro_discount")),
            type_entropy_floor=given(o.type_entropy_floor, "type_entropy_floor"),
            type_entropy_until=o.type_entropy_until,
            normalize_obs=o.normalize,
            scale_rewards=o.normalize,
        )
    except ValueError as exc:
        raise UsageError(str(exc)) from exc
    return RunSpec(
        env_id=o.env,
        env_kwargs=o.env_kwargs,
        agent=o.agent,
        seed=o.seed,
        ppo=ppo,
        latent_bound=o.latent_bound,
        macro_horizon=given(o.macro_horizon, "macro_horizon"),
        residual=given(o.residual, "residual"),
        max_repeat=o.max_repeat,
        favae=None if favae is None else str(favae),
        prior=None if o.prior is None else str(o.prior),
        prior_guide=o.prior_guide,
        prior_weight=o.prior_weight,
        prior_target_kl=o.prior_target_kl,
        prior_obs_prefix=o.prior_obs_prefix,
        loop=o.loop,
        label=o.label
        or default_label(
            o.agent, o.favae_file if o.agent.decodes_macros else None, o.prior is not None and o.prior_guide, o.loop
        ),
        success_return=o.success_return,
    )
