"""A trained run as an agent: loaded from its folder and acting on its env's observations, as Stable-Baselines3's
models ``load`` and ``predict`` (:class:`TrainedAgent`); what ``famarl evaluate`` and ``famarl oracle`` act with."""

from __future__ import annotations

import functools
import os
from collections.abc import Mapping
from dataclasses import dataclass, field

import gymnasium as gym
import numpy as np

from famarl_cli.artifacts.runs import read_run_checkpoint
from famarl_cli.core.errors import UsageError
from famarl_cli.envs.vector import BatchedEnv, make_batch
from famarl_cli.method.favae.model import Favae
from famarl_cli.method.prior.checkpoint import Skills
from famarl_cli.rl import MacroDecoder
from famarl_cli.rl.action_modes import ActionMode
from famarl_cli.rl.normalization import ObservationNormalizer
from famarl_cli.rl.policy import ActorCritic
from famarl_cli.rl.spec import RunSpec, build_guide, build_mode
from famarl_cli.rl.training import mode_from_state


@dataclass(frozen=True)
class RunActionSpace:
    """What a run folder's decisions act through, without its policy (:meth:`load`): its spec, a batch of its env,
    the mode that decodes its decisions and the networks the mode decodes with. ``famarl oracle`` searches this
    space; :class:`TrainedAgent` adds the policy that acts in it."""

    spec: RunSpec
    env: BatchedEnv
    mode: ActionMode
    favae: Favae | None
    skills: Skills | None
    payload: dict = field(repr=False, compare=False)
    """The checkpoint it was read from (:func:`~famarl_cli.artifacts.runs.read_run_checkpoint`)."""

    @classmethod
    def load(cls, run_dir: str | os.PathLike, n_envs: int = 1, seed: int | None = None) -> RunActionSpace:
        """The action space of the run folder ``run_dir`` on a batch of ``n_envs`` of its envs, made from ``seed``
        (default: the run's own)."""
        payload = read_run_checkpoint(run_dir)
        spec = RunSpec.from_dict(payload["config"])
        favae, skills = mode_from_state(payload["mode"])
        seed = spec.seed if seed is None else seed
        env = make_batch(spec.env_id, n_envs, seed, spec.env_kwargs, spec.success_return)
        return cls(spec, env, build_mode(spec, env, favae, skills), favae, skills, payload)


@dataclass
class TrainedAgent:
    """A trained run (:meth:`load`): the policy, its frozen observation statistics and its action mode.

    It acts on the observations of its env (the env's own, unnormalised; a Dict observation as the env gives it)
    in two ways: :meth:`predict`, as Stable-Baselines3's models do, one action per env step, and :meth:`act`, one
    decision at a time, a macro action's whole sequence at once. Both draw the actions as in training, the policy
    whose success the verdicts judge, unless asked for its mode with ``deterministic=True``."""

    spec: RunSpec
    policy: ActorCritic
    mode: ActionMode
    """How its decisions become actions (:func:`~famarl_cli.rl.spec.build_mode`): the same for any batch of
    its env."""
    env: BatchedEnv = field(repr=False, compare=False)
    """One env of its kind: the shape and space of the observations it takes."""
    obs_norm_state: dict
    favae: Favae | None
    env_steps: int
    skills: Skills | None = None
    rng: np.random.Generator = field(default_factory=np.random.default_rng, repr=False, compare=False)
    """Where :meth:`act` and :meth:`predict` draw from when not given a generator (seed one for repeatable draws)."""
    _pending: list[np.ndarray] = field(default_factory=list, init=False, repr=False, compare=False)
    """:meth:`predict`: per env of the batch, the actions of its decision in progress still to run."""

    @functools.cached_property
    def _actor(self) -> FrozenActor:
        return FrozenActor(self)

    @classmethod
    def load(cls, run_dir: str | os.PathLike) -> TrainedAgent:
        """The agent a run folder (``famarl train``) holds, as its checkpoint left it."""
        space = RunActionSpace.load(run_dir)
        spec, env, mode, trainer = space.spec, space.env, space.mode, space.payload["trainer"]
        policy = ActorCritic(
            env.observation_size, mode.policy_action_size, mode.choices, spec.ppo.hidden, mode.branches
        )
        policy.load_state_dict(trainer["policy"])
        counters = trainer["counters"]
        return cls(spec, policy, mode, env, trainer["obs_norm"], space.favae, int(counters["env_steps"]), space.skills)

    def act(
        self, observation: np.ndarray | dict, deterministic: bool = False, rng: np.random.Generator | None = None
    ) -> Decision:
        """The decision the policy takes at one ``observation``: the primitive actions to run, open loop, and for a
        macro action the FAVAE latent it chose. Drawn as in training, from ``rng`` (default: :attr:`rng`), or with
        ``deterministic`` the policy's mode. A run whose macros are closed-loop (``--loop closed``) chooses each
        action from the state reached: step it in :class:`~famarl_cli.wrappers.MacroActionWrapper` instead."""
        obs, one = self._observations(observation)
        if not one:
            raise UsageError(
                f"act takes one observation of shape {self._shape}, not a batch of {len(obs)}: predict takes batches"
            )
        actor = self._decide(deterministic, rng)
        actions, length = actor(obs)
        macro = bool(actor.macro[0])
        latent = actor.last_u[0, : self.favae.config.latent_size].copy() if macro and self.favae else None
        return Decision(actions[0, : int(length[0])].copy(), latent, macro)

    def predict(
        self,
        observation: np.ndarray | dict,
        state: tuple[np.ndarray, ...] | None = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = False,
    ) -> tuple[np.ndarray, tuple[np.ndarray, ...] | None]:
        """The action to take at ``observation``, as Stable-Baselines3's ``model.predict``: ``(action, state)``.

        ``observation`` is one observation of the env, or a batch of them (one row per env, as a VecEnv gives);
        the action is one action, or a batch of as many. ``state`` passes through unused (the policy has no
        recurrent state). Drawn as in training (from :attr:`rng`), or with ``deterministic`` the policy's mode.

        A decision may last several steps (a FaMARL or hybrid macro action, FiGAR's repeated action): the agent
        decides at the first step and runs the decision's actions, open loop, over the next calls, one per call;
        each env of a batch (its row) runs its own. ``episode_start`` (one bool, or one per row: the dones of the
        last step, as SB3's recurrent policies take them) drops the decision in progress where an episode began,
        so that a macro action never runs on into the next episode; pass it whenever the env was reset. A batch of
        another size than the last one's is taken as other envs: every row decides afresh.
        """
        obs, one = self._observations(observation)
        if len(self._pending) != len(obs):
            self._pending = [np.empty((0,)) for _ in obs]
        if episode_start is not None:
            starts = np.asarray(episode_start, dtype=bool)
            if starts.size != len(obs):
                raise UsageError(f"episode_start has {starts.size} values for {len(obs)} observations")
            for row in np.flatnonzero(starts.reshape(-1)):
                self._pending[row] = np.empty((0,))
        deciding = [row for row, pending in enumerate(self._pending) if not len(pending)]
        if deciding:
            actions, lengths = self._decide(deterministic, None)(obs[deciding])
            for k, row in enumerate(deciding):
                self._pending[row] = actions[k, : int(lengths[k])]
        action = np.stack([pending[0] for pending in self._pending])
        self._pending = [pending[1:] for pending in self._pending]
        return (action[0] if one else action), state

    def _decide(self, deterministic: bool, rng: np.random.Generator | None) -> FrozenActor:
        if self.spec.loop == MacroDecoder.CLOSED:
            raise UsageError("a closed-loop run decides each action from the state reached; use MacroActionWrapper")
        actor = self._actor
        actor.rng = None if deterministic else (rng if rng is not None else self.rng)
        return actor

    @property
    def _shape(self) -> tuple[int]:
        return (self.env.observation_size,)

    def _observations(self, observation: np.ndarray | dict) -> tuple[np.ndarray, bool]:
        """``observation`` as rows of flat observations (N, size), and whether it was one observation."""
        size, space = self.env.observation_size, getattr(self.env, "observation_space", None)
        expected = f"{self.spec.env_id} observations have shape {self._shape}, or (N, {size}) for a batch"
        if isinstance(observation, Mapping):
            observation = _flatten_dict(observation, space, expected)
        try:
            obs = np.asarray(observation, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise UsageError(f"{expected}; got {type(observation).__name__} that is no array of numbers") from exc
        if obs.shape == (size,):
            return obs[None], True
        if obs.ndim == 2 and obs.shape[1] == size and len(obs):
            return obs, False
        raise UsageError(f"{expected}, not {obs.shape}")


def _flatten_dict(observation: Mapping, space: object, expected: str) -> np.ndarray:
    """A Dict observation, or a batch of them (each entry with a leading row axis), flattened as training
    flattened it (:class:`~famarl_cli.envs.vector.GymBatch`)."""
    if not isinstance(space, gym.spaces.Dict):
        raise UsageError(f"{expected}; got a dict")
    shapes = {key: sub.shape for key, sub in space.spaces.items()}
    try:
        entries = {key: np.asarray(observation[key]) for key in space.spaces}
        if all(entries[key].shape == shape for key, shape in shapes.items()):
            return gym.spaces.flatten(space, entries)
        rows = len(next(iter(entries.values())))
        if all(entries[key].shape == (rows, *shape) for key, shape in shapes.items()):
            return np.stack([gym.spaces.flatten(space, {k: v[i] for k, v in entries.items()}) for i in range(rows)])
    except (KeyError, TypeError, ValueError):
        pass  # refused below, with the shapes it takes
    given = {key: np.shape(value) for key, value in observation.items()}
    raise UsageError(f"{expected}; a dict observation holds {shapes} (a batch: one row more each), not {given}")


@dataclass(frozen=True)
class Decision:
    """One decision of a trained agent (:meth:`TrainedAgent.act`)."""

    actions: np.ndarray
    """(n, D): the primitive actions it runs, in order (one for PPO, a repeated one for FiGAR, a macro's)."""
    latent: np.ndarray | None
    """The FAVAE latent z of a macro action (FaMARL, the hybrid's macro decisions), else None."""
    macro: bool
    """Whether it is a macro action (FaMARL always; the hybrid where its type head chose one)."""


class FrozenActor:
    """The trained policy on observations normalised with the statistics frozen at the end of training: acting
    with its mode, or sampling as it did in training when given a generator. Returns each decision's open-loop
    actions (N, L, D) and lengths (N,); ``macro`` is which of the last decisions were macro actions."""

    def __init__(self, agent: TrainedAgent, rng: np.random.Generator | None = None) -> None:
        self.agent, self.rng, self.mode = agent, rng, agent.mode
        self.guide = build_guide(agent.spec, self.mode, agent.skills)
        self.normalize = ObservationNormalizer((agent.policy.obs_size,), agent.spec.ppo.normalize_obs)
        self.normalize.load_state_dict(agent.obs_norm_state)

    def __call__(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        base = None if self.guide is None else self.guide.base(obs)
        action = self.agent.policy.act(self.normalize(obs.astype(np.float32), update=False), self.rng, base=base)
        self.macro = self.mode.macro(action.index)
        self.last_u = action.u
        return self.mode.to_sequences(action.u.astype(np.float64), action.index)


load_agent = TrainedAgent.load
"""A run folder's agent: :meth:`TrainedAgent.load` (the name docs/api.md gives it)."""
