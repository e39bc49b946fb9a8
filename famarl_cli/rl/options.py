"""The settings of PPO and of a run that ``famarl train`` offers, declared once (:mod:`famarl_cli.core.declare`):
:class:`~famarl_cli.stages.train.TrainOptions` is built on them (its options), and
:class:`~famarl_cli.rl.ppo.PPOConfig` and :class:`~famarl_cli.rl.spec.RunSpec` take their defaults from them
(:func:`~famarl_cli.core.declare.default_of`), so a default changes in one line. The settings that depend on the
agent are :func:`famarl_cli.rl.agent_defaults`'.

Torch-free: the declarations are imported when the CLI starts.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from famarl_cli.core.declare import option
from famarl_cli.rl import MacroDecoder

DEFAULT_STEPS = 1_000_000
"""The budget in environment steps: ``famarl train``'s (every committed run's) and :class:`PPOConfig`'s. Not an
option's default: on ``--resume`` the budget left out is the run's own."""


@dataclass(frozen=True)
class RunOptions:
    """A run's settings beyond PPO's (:class:`~famarl_cli.rl.spec.RunSpec`'s)."""

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
    latent_bound: float = option(3.0, "famarl, hybrid: clip latents to [-bound, bound] before decoding.", min=0.0)
    max_repeat: int = option(32, "figar: the largest repeat count J.", min=1)


@dataclass(frozen=True)
class PPOOptions:
    """PPO's settings (:class:`~famarl_cli.rl.ppo.PPOConfig`'s, ``lr`` its ``learning_rate`` and ``normalize`` its
    ``normalize_obs`` and ``scale_rewards``)."""

    n_envs: int = option(16, "Environments stepped together.", min=1)
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
    type_entropy_until: float = option(
        0.25, "hybrid: share of the budget during which the floor holds.", min=0.0, max=1.0
    )
    normalize: bool = option(True, "Normalise observations and scale rewards by the return's std.")
    clip_value: bool = option(True, "Clip the value loss like the policy ratio (CleanRL's default).")
