"""Reinforcement learning: one PPO over four action modes (FaMARL's latent macro actions, primitive actions,
FiGAR's repeated actions, and the hybrid of macro and primitive actions), all executed through the same open-loop
path and budgeted in environment steps, on the batched environments of :mod:`famarl_cli.envs.vector`.

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
    HYBRID = "hybrid"

    @property
    def decodes_macros(self) -> bool:
        """Whether the agent needs a FAVAE to decode its macro actions."""
        return self in (Agent.FAMARL, Agent.HYBRID)


class MacroDecoder(StrEnum):
    """What turns a latent into actions: the FAVAE's decoder, fixed when the macro starts (the paper's), or the
    closed-loop decoder pi(a | s, z) of a prior file, which looks at the state every step."""

    OPEN = "open"
    CLOSED = "closed"


class MacroDiscount(StrEnum):
    """How a macro action's rewards are discounted: per decision (the paper), or per environment step (the
    semi-MDP form, :mod:`famarl_cli.rl.semi_mdp`)."""

    DECISION = "decision"
    STEPS = "steps"


HYBRID_HORIZON = 10
"""The hybrid's execution horizon: deciding again after 10 steps of a macro action started higher, learned sooner
and ended with a better return than running whole macros, on the Maze and on Reaching (docs/hybrid.md)."""
HYBRID_RESIDUAL = 0.25
"""The hybrid's residual scale: the correction improved the final return on the Maze and on Reaching."""
HYBRID_ENTROPY_FLOOR = 0.3
"""The hybrid's floor on its type head's entropy, in nats (p(type) stays above about 0.08)."""


DECISIONS_PER_ROLLOUT = {Agent.FAMARL: 16, Agent.FIGAR: 32, Agent.PPO: 128, Agent.HYBRID: 32}
"""Default decisions per environment per rollout: a FaMARL decision lasts ~25 steps and a FiGAR one ~15, so
fewer decisions give them rollouts (and updates per environment step) of a similar size to PPO's. A hybrid
decision lasts 1 step or a macro's length: 32 keeps its first rollouts, mostly macros, near FaMARL's size and
its later ones, where primitives take over, frequent enough."""


def agent_defaults(agent: Agent) -> dict:
    """The settings that depend on the agent, as ``famarl train`` fills them in: ``n_steps``, ``macro_discount``,
    ``type_entropy_floor`` (PPOConfig) and ``macro_horizon``, ``residual`` (RunSpec). A new agent is a member of
    :class:`Agent`, its settings here, an action mode (:class:`~famarl_cli.rl.action_modes.ActionMode`) and its
    branch of :func:`~famarl_cli.rl.spec.build_mode`.

    The hybrid's decisions last 1 step or a macro's length, and only the semi-MDP form values them alike
    (:mod:`famarl_cli.rl.semi_mdp`); the other agents keep the paper's convention and run whole macros.
    """
    if agent == Agent.HYBRID:
        return {
            "n_steps": DECISIONS_PER_ROLLOUT[agent],
            "macro_discount": MacroDiscount.STEPS,
            "type_entropy_floor": HYBRID_ENTROPY_FLOOR,
            "macro_horizon": HYBRID_HORIZON,
            "residual": HYBRID_RESIDUAL,
        }
    return {
        "n_steps": DECISIONS_PER_ROLLOUT[agent],
        "macro_discount": MacroDiscount.DECISION,
        "type_entropy_floor": 0.0,
        "macro_horizon": 0,
        "residual": 0.0,
    }
