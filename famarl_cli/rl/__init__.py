"""Reinforcement learning: one PPO over three action modes (FaMARL's latent macro actions, primitive actions,
FiGAR's repeated actions), all executed through the same open-loop path and budgeted in environment steps.

- :mod:`~famarl_cli.rl.vector`: batched environments (ContinuousWorld natively, any gymnasium id by a loop);
- :mod:`~famarl_cli.rl.executor`: runs a batch of open-loop action sequences of different lengths;
- :mod:`~famarl_cli.rl.action_modes`: what the policy outputs and how it becomes an action sequence;
- :mod:`~famarl_cli.rl.policy`: the actor-critic networks and their distributions;
- :mod:`~famarl_cli.rl.normalization`: running observation and reward statistics;
- :mod:`~famarl_cli.rl.ppo`: GAE, the clipped update and the training loop;
- :mod:`~famarl_cli.rl.evaluation`: deterministic rollouts and their metrics;
- :mod:`~famarl_cli.rl.tensorboard`: the training log as TensorBoard scalars (optional).

:mod:`famarl_cli.wrappers` offers the same action modes, run by the same executor, as gymnasium wrappers for other
agents.
"""

from enum import StrEnum


class Agent(StrEnum):
    """What the policy searches over. Defined here, apart from the torch code, so the CLI starts without torch."""

    FAMARL = "famarl"
    PPO = "ppo"
    FIGAR = "figar"


class MacroDiscount(StrEnum):
    """How a macro action's rewards are discounted: per decision (the paper), or per environment step."""

    DECISION = "decision"
    STEPS = "steps"
