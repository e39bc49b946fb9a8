"""The action spaces of FaMARL and FiGAR as gymnasium wrappers, for any agent: Stable-Baselines3, CleanRL, your own.

>>> env = MacroActionWrapper(gymnasium.make("famarl/ContinuousWorld-Maze-v0"), "data/maze/macros/seed0/favae.pt")
>>> obs, info = env.reset(seed=0)
>>> obs, reward, terminated, truncated, info = env.step(env.action_space.sample())  # one whole macro action

One ``step`` is one decision: the action is turned into an open-loop sequence by the same action mode that
``famarl train`` uses (:mod:`famarl_cli.rl.action_modes`) and run by the same loop
(:func:`famarl_cli.rl.executor.run_sequences`), which stops at termination or truncation. The reward is the
semi-MDP discounted sum ``sum_j gamma**j r_j`` over the steps run (``reward="discounted"``) or the plain sum
(``reward="sum"``, the paper's r_tot). ``info`` adds, to the last step's own info:

- ``steps``: environment steps run; count your budget in these, not in calls to ``step``;
- ``discount``: ``gamma ** steps``, the factor to bootstrap the next decision's value with under semi-MDP
  discounting (an agent with one gamma per decision ignores it);
- ``sequence_length``: the length of the decoded sequence (``steps`` is shorter where the episode ended first);
- ``success``: whether the episode succeeded, by :mod:`famarl_cli.envs.success` (the env's report, else its
  ``reward_threshold`` on the episode's return; None where neither exists); False while the episode goes on.

Observations are the wrapped environment's own, unchanged.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable
from typing import Literal

import gymnasium
import numpy as np

from famarl_cli.envs.success import as_bool
from famarl_cli.envs.vector import GymBatch
from famarl_cli.method.favae.checkpoint import load_favae
from famarl_cli.method.prior.checkpoint import load_skills
from famarl_cli.rl.action_modes import ClosedLoopMacroActions, LatentMacroActions, RepeatedActions
from famarl_cli.rl.executor import discounted_sum, run_sequences

Reward = Literal["discounted", "sum"]


class OpenLoopWrapper(gymnasium.Wrapper):
    """A decision is an open-loop action sequence made by an action mode from the agent's action; ``make_mode``
    builds that mode from the environment's action bounds, and subclasses say how their action space maps to the
    mode's input ``(u, repeat index)``."""

    def __init__(
        self,
        env: gymnasium.Env,
        make_mode: Callable[[np.ndarray, np.ndarray], object],
        reward: Reward = "discounted",
        gamma: float = 0.99,
    ) -> None:
        super().__init__(env)
        if reward not in ("discounted", "sum"):
            raise ValueError(f"reward must be 'discounted' or 'sum', got {reward!r}")
        if not 0.0 < gamma <= 1.0:
            raise ValueError(f"gamma must be in (0, 1], got {gamma}")
        self._batch = GymBatch([env], seed=0, autoreset=False)
        self._mode = make_mode(*self._batch.action_bounds)
        self.reward_kind, self.gamma = reward, gamma

    def _mode_input(self, action) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        return self._batch.reset_one(0, seed=seed, options=options)

    def step(self, action):
        u, repeat = self._mode_input(action)
        actions, lengths = self._mode.to_sequences(u, repeat)
        result = run_sequences(self._batch, self._batch.obs, actions, lengths)
        reward = discounted_sum(result.rewards, self.gamma)[0] if self.reward_kind == "discounted" else result.reward[0]
        steps = int(result.steps[0])
        info = {
            **self._batch.last_info[0],
            "steps": steps,
            "discount": self.gamma**steps,
            "sequence_length": int(lengths[0]),
            "success": as_bool(result.success[0]),
        }
        return self._batch.raw_obs[0], float(reward), bool(result.terminated[0]), bool(result.truncated[0]), info


class MacroActionWrapper(OpenLoopWrapper, gymnasium.utils.RecordConstructorArgs):
    """FaMARL's action space: a FAVAE latent z in ``[-bound, bound]^latent_size``, decoded by the frozen FAVAE
    of ``favae_path`` (a checkpoint of ``famarl favae fit`` or ``famarl macros``) into a macro action.

    With ``loop="closed"`` (``famarl train --loop closed``), the closed-loop decoder of ``prior_path`` (``famarl
    prior fit`` on this FAVAE) corrects each of the macro's actions from the state the step starts in (its networks
    read the first values of the observation, as many as the demos had). ``decoder=`` is the former name of
    ``loop=``, still taken with a DeprecationWarning: "decoder" names a network (the FAVAE's, the prior file's).

    The environment's actions must have the size the FAVAE decodes; decoded actions are clipped to its bounds.
    """

    def __init__(
        self,
        env: gymnasium.Env,
        favae_path: str | os.PathLike,
        reward: Reward = "discounted",
        gamma: float = 0.99,
        bound: float = 3.0,
        loop: Literal["open", "closed"] = "open",
        prior_path: str | os.PathLike | None = None,
        decoder: Literal["open", "closed"] | None = None,
    ) -> None:
        if decoder is not None:
            if loop != "open":
                raise ValueError("give loop= alone: decoder= is its former name")
            warnings.warn(
                "MacroActionWrapper(decoder=...) is now loop=...; the old name goes in the next release",
                DeprecationWarning,
                stacklevel=2,
            )
            loop = decoder
        # recorded so that ``env.spec`` can remake the wrapped environment (gymnasium's check_env does)
        gymnasium.utils.RecordConstructorArgs.__init__(
            self,
            favae_path=str(favae_path),
            reward=reward,
            gamma=gamma,
            bound=bound,
            loop=loop,
            prior_path=None if prior_path is None else str(prior_path),
        )
        favae = load_favae(favae_path)[0]
        if loop not in ("open", "closed"):
            raise ValueError(f"loop must be 'open' or 'closed', got {loop!r}")
        if loop == "open":
            super().__init__(env, lambda low, high: LatentMacroActions(favae, low, high, bound), reward, gamma)
        else:
            if prior_path is None:
                raise ValueError("loop='closed' needs prior_path: the closed-loop decoder is in the prior file")
            skills = load_skills(prior_path)
            state, latent = gymnasium.spaces.flatdim(env.observation_space), favae.config.latent_size
            if skills.config.latent_size != latent or skills.config.obs_size > state:
                raise ValueError(
                    f"{prior_path} reads {skills.config.obs_size} state values and {skills.config.latent_size} "
                    f"latents, but the env has {state} and the FAVAE {latent}"
                )
            closed = skills.decoder.frozen()
            super().__init__(
                env, lambda low, high: ClosedLoopMacroActions(favae, closed, low, high, bound), reward, gamma
            )
        self.favae = favae
        self.action_space = gymnasium.spaces.Box(-bound, bound, (favae.config.latent_size,), np.float32)

    def _mode_input(self, action) -> tuple[np.ndarray, np.ndarray]:
        return np.asarray(action, dtype=np.float64).reshape(1, -1), np.zeros(1, dtype=np.int64)


class RepeatedActionWrapper(OpenLoopWrapper, gymnasium.utils.RecordConstructorArgs):
    """FiGAR's action space: ``(action, r)``, the primitive action repeated r + 1 times, r in 0..max_repeat-1.

    A Tuple space, which agents with a Box-only policy (Stable-Baselines3's PPO among them) do not take.
    """

    def __init__(
        self, env: gymnasium.Env, max_repeat: int = 32, reward: Reward = "discounted", gamma: float = 0.99
    ) -> None:
        gymnasium.utils.RecordConstructorArgs.__init__(self, max_repeat=max_repeat, reward=reward, gamma=gamma)
        super().__init__(env, lambda low, high: RepeatedActions(low, high, max_repeat), reward, gamma)
        self.action_space = gymnasium.spaces.Tuple((env.action_space, gymnasium.spaces.Discrete(max_repeat)))

    def _mode_input(self, action) -> tuple[np.ndarray, np.ndarray]:
        primitive, repeat = action
        return np.asarray(primitive, dtype=np.float64).reshape(1, -1), np.array([int(repeat)])
