"""The action modes: what the policy outputs and how that becomes an action sequence.

- ``ppo``: a primitive action, a sequence of length 1;
- ``figar``: a primitive action and a repeat count in 1..J (FiGAR, Sharma et al. 2017), the action repeated;
- ``famarl``: a latent z of a frozen FAVAE, decoded into a macro action and cut where ``action_off`` wins; with a
  closed-loop decoder (:class:`ClosedLoopMacroActions`), each of its actions is chosen from the state reached;
- ``hybrid``: a choice k in {primitive, macro}, then a primitive action or a latent (MAPLE's atomic fallback).

Every mode takes the policy's continuous output ``u`` (N, policy_action_size) and the index chosen by the
policy's categorical head (N,) (FiGAR's repeat index, the hybrid's type; unused elsewhere), and returns
``(actions (N, L, D) or a closed-loop :class:`~famarl_cli.rl.executor.Plan`, lengths (N,))`` for
:func:`~famarl_cli.rl.executor.run_sequences`. ``macro(index)`` says
which decisions were macro actions, for the logs.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from famarl_cli.method.favae.model import Favae
from famarl_cli.rl.executor import Plan


class ActionMode(Protocol):
    """What PPO (:mod:`famarl_cli.rl.ppo`), evaluation and the gymnasium wrappers need of an action mode. A new
    agent's way of acting is a class with these members; :func:`~famarl_cli.rl.spec.build_mode` makes it from the
    run's spec."""

    policy_action_size: int
    """Outputs of the policy's Gaussian head: the size of ``u``."""
    choices: int
    """Options of the policy's categorical head (0: no such head)."""
    branches: np.ndarray | None
    """(choices, policy_action_size): which outputs each choice uses; None when every choice uses them all."""

    def to_sequences(self, u: np.ndarray, index: np.ndarray | None) -> tuple[np.ndarray | Plan, np.ndarray]:
        """(actions (N, L, D) or a closed-loop plan, lengths (N,)) of the decisions ``u`` (N, policy_action_size)
        and ``index`` (N,), for :func:`~famarl_cli.rl.executor.run_sequences`; steps past a length are not
        executed."""
        ...

    def macro(self, index: np.ndarray) -> np.ndarray:
        """(N,) bool: which decisions were macro actions (for the logs)."""
        ...


class PrimitiveActions:
    choices = 0
    """Options of the policy's categorical head (0: no such head)."""
    branches: np.ndarray | None = None
    """(choices, policy_action_size): which outputs each choice uses; None when every choice uses them all."""

    def __init__(self, low: np.ndarray, high: np.ndarray) -> None:
        self.low, self.high = low, high
        self.policy_action_size = len(low)

    def to_sequences(self, u: np.ndarray, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.clip(u, self.low, self.high)[:, None, :], np.ones(len(u), dtype=np.int64)

    def macro(self, index: np.ndarray) -> np.ndarray:
        return np.zeros(len(index), dtype=bool)


class RepeatedActions(PrimitiveActions):
    """FiGAR: the repeat index r in 0..J-1 means the action runs r + 1 times."""

    def __init__(self, low: np.ndarray, high: np.ndarray, max_repeat: int) -> None:
        super().__init__(low, high)
        self.choices = max_repeat

    def to_sequences(self, u: np.ndarray, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        action = np.clip(u, self.low, self.high)[:, None, :]
        return np.repeat(action, self.choices, axis=1), index.astype(np.int64) + 1


class LatentMacroActions:
    """FaMARL: the policy's output is a FAVAE latent, clipped to ``[-bound, bound]`` before decoding.

    The prior is N(0, 1), so the decoder has only seen latents within about 3 of 0; far outside that box its
    output is an extrapolation that no demonstration supports. ``horizon`` cuts every macro action after that
    many steps, so the agent decides again sooner than the decoder would stop (0: the decoder's length).
    """

    choices = 0
    branches = None

    def __init__(self, favae: Favae, low: np.ndarray, high: np.ndarray, bound: float, horizon: int = 0) -> None:
        if favae.config.action_dim != len(low):
            raise ValueError(
                f"the FAVAE decodes {favae.config.action_dim}-D actions but the environment takes {len(low)}-D ones"
            )
        self.favae, self.low, self.high, self.bound, self.horizon = favae, low, high, bound, horizon
        self.policy_action_size = favae.config.latent_size

    def decode(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The latents ``u`` clipped to the box, the FAVAE's open-loop actions for them, and their lengths (cut at
        ``horizon``)."""
        latents = np.clip(u, -self.bound, self.bound)
        actions, lengths = self.favae.decode_macro_actions(latents)
        return latents, actions, (np.minimum(lengths, self.horizon) if self.horizon else lengths)

    def to_sequences(self, u: np.ndarray, index: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        _, actions, lengths = self.decode(u)
        return np.clip(actions, self.low, self.high), lengths

    def macro(self, index: np.ndarray) -> np.ndarray:
        return np.ones(len(index), dtype=bool)


class ClosedLoopPlan:
    """The closed-loop macro decoder's plan: at step k, row i of ``rows`` plays ``decoder(s, z_i, k, open_i[k])``
    (the FAVAE's open-loop action corrected from the state) plus its ``offset`` (the hybrid's residual), clipped to
    the bounds; the other rows play ``fixed[:, 0]`` (a hybrid's primitive actions, one step long)."""

    def __init__(
        self,
        decoder,
        latents: np.ndarray,
        open_loop: np.ndarray,
        rows: np.ndarray,
        fixed: np.ndarray,
        low: np.ndarray,
        high: np.ndarray,
        offset: np.ndarray | float = 0.0,
    ) -> None:
        self.decoder, self.latents, self.open_loop, self.rows, self.fixed = decoder, latents, open_loop, rows, fixed
        self.low, self.high, self.offset = low, high, offset

    def __call__(self, k: int, obs: np.ndarray) -> np.ndarray:
        actions = self.fixed[:, 0].copy()
        decoded = self.decoder(obs[self.rows], self.latents, k, self.open_loop[:, k])
        actions[self.rows] = np.clip(decoded + self.offset, self.low, self.high)
        return actions


class ClosedLoopMacroActions(LatentMacroActions):
    """FaMARL with a closed-loop decoder pi(a | s, z, k / L) (:mod:`famarl_cli.method.prior`): the FAVAE still says
    how long the macro lasts (where ``action_off`` wins, cut at ``horizon``) and what its open-loop actions are,
    and the decoder corrects each of them from the state the step starts in, so a macro reacts to where the agent
    is."""

    def __init__(
        self, favae: Favae, decoder, low: np.ndarray, high: np.ndarray, bound: float, horizon: int = 0
    ) -> None:
        super().__init__(favae, low, high, bound, horizon)
        self.decoder = decoder

    def plan(self, u: np.ndarray, rows: np.ndarray, fixed: np.ndarray, offset: np.ndarray | float = 0.0):
        """The plan and lengths of the latents ``u`` (M, Z) played by ``rows`` (N,) of the batch."""
        latents, open_loop, lengths = self.decode(u)
        return ClosedLoopPlan(self.decoder, latents, open_loop, rows, fixed, self.low, self.high, offset), lengths

    def to_sequences(self, u: np.ndarray, index: np.ndarray | None) -> tuple[Plan, np.ndarray]:
        fixed = np.zeros((len(u), 1, len(self.low)))
        return self.plan(u, np.ones(len(u), dtype=bool), fixed)


class HybridActions:
    """Each decision is a primitive action or a macro action. The policy's output ``u`` holds both branches,
    ``[primitive (D) | latent (Z)]``; the type index (0 primitive, 1 macro) says which one runs, and only that
    branch's outputs enter the decision's log-probability (:attr:`branches`).

    ``residual`` > 0 is the residual variant: a macro decision also uses the primitive output, and adds
    ``residual`` times it to every action of the macro (an open-loop correction, learned with the macro).
    """

    PRIMITIVE, MACRO = 0, 1
    choices = 2

    def __init__(self, macros: LatentMacroActions, residual: float = 0.0) -> None:
        self.primitive, self.macros, self.residual = PrimitiveActions(macros.low, macros.high), macros, residual
        size = self.primitive.policy_action_size
        self.policy_action_size = size + macros.policy_action_size
        self.branches = np.zeros((2, self.policy_action_size), dtype=bool)
        self.branches[self.PRIMITIVE, :size] = True
        self.branches[self.MACRO, size:] = True
        self.branches[self.MACRO, :size] = residual > 0

    def to_sequences(self, u: np.ndarray, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        macro = self.macro(index)
        size = self.primitive.policy_action_size
        primitive, lengths = self.primitive.to_sequences(u[:, :size], index)
        if not macro.any():
            return primitive, lengths
        if isinstance(self.macros, ClosedLoopMacroActions):
            offset = self.residual * u[macro, :size] if self.residual > 0 else 0.0
            plan, macro_lengths = self.macros.plan(u[macro, size:], macro, primitive, offset)
            lengths[macro] = macro_lengths
            return plan, lengths
        # Only the macro decisions are decoded: the decoder is the costly part of a step.
        decoded, macro_lengths = self.macros.to_sequences(u[macro, size:], None)
        if self.residual > 0:
            decoded = np.clip(decoded + self.residual * u[macro, None, :size], self.macros.low, self.macros.high)
        actions = np.zeros((len(u), decoded.shape[1], size))
        actions[~macro, :1] = primitive[~macro]
        actions[macro] = decoded
        lengths[macro] = macro_lengths
        return actions, lengths

    def macro(self, index: np.ndarray) -> np.ndarray:
        return index == self.MACRO
