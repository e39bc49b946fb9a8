"""The three action modes: what the policy outputs and how that becomes an open-loop action sequence.

- ``ppo``: a primitive action, a sequence of length 1;
- ``figar``: a primitive action and a repeat count in 1..J (FiGAR, Sharma et al. 2017), the action repeated;
- ``famarl``: a latent z of a frozen FAVAE, decoded into a macro action and cut where ``action_off`` wins.

Every mode takes the policy's continuous output ``u`` (N, policy_action_size) and, for FiGAR, the chosen
repeat index (N,), and returns ``(actions (N, L, D), lengths (N,))`` for :func:`~famarl_cli.rl.executor.run_open_loop`.
"""

from __future__ import annotations

import numpy as np

from famarl_cli.favae.model import Favae


class PrimitiveActions:
    repeat_choices = 0

    def __init__(self, low: np.ndarray, high: np.ndarray) -> None:
        self.low, self.high = low, high
        self.policy_action_size = len(low)

    def to_open_loop(self, u: np.ndarray, repeat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.clip(u, self.low, self.high)[:, None, :], np.ones(len(u), dtype=np.int64)


class RepeatedActions(PrimitiveActions):
    """FiGAR: the repeat index r in 0..J-1 means the action runs r + 1 times."""

    def __init__(self, low: np.ndarray, high: np.ndarray, max_repeat: int) -> None:
        super().__init__(low, high)
        self.repeat_choices = max_repeat

    def to_open_loop(self, u: np.ndarray, repeat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        action = np.clip(u, self.low, self.high)[:, None, :]
        return np.repeat(action, self.repeat_choices, axis=1), repeat.astype(np.int64) + 1


class LatentMacroActions:
    """FaMARL: the policy's output is a FAVAE latent, clipped to ``[-bound, bound]`` before decoding.

    The prior is N(0, 1), so the decoder has only seen latents within about 3 of 0; far outside that box its
    output is an extrapolation that no demonstration supports.
    """

    repeat_choices = 0

    def __init__(self, favae: Favae, low: np.ndarray, high: np.ndarray, bound: float) -> None:
        if favae.config.action_dim != len(low):
            raise ValueError(
                f"the FAVAE decodes {favae.config.action_dim}-D actions but the environment takes {len(low)}-D ones"
            )
        self.favae, self.low, self.high, self.bound = favae, low, high, bound
        self.policy_action_size = favae.config.latent_size

    def to_open_loop(self, u: np.ndarray, repeat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        actions, lengths = self.favae.decode_macro_actions(np.clip(u, -self.bound, self.bound))
        return np.clip(actions, self.low, self.high), lengths
