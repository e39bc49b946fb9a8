"""PPO (Schulman et al. 2017) over decisions that may each last many environment steps.

Every detail is here, in the order it runs (CleanRL's ``ppo_continuous_action`` is the model):
observation normalisation, reward scaling by the running return std, GAE, per-minibatch advantage
normalisation, the clipped objective, a clipped value loss, gradient clipping and a learning rate annealed
linearly over the budget of environment steps.

Two things differ from a primitive-action PPO because a decision here is an open-loop sequence (a macro
action, a repeated action, or a single step):

- the reward of a decision is the sum of the rewards its steps collected (the paper's r_tot), and its discount
  is ``gamma`` per decision (``macro_discount="decision"``, the paper's t') or ``gamma ** steps`` with the
  rewards inside scaled and discounted step by step (``"steps"``, the semi-MDP form; :mod:`~famarl_cli.rl.semi_mdp`
  shows why it matters);
- a decision cut by the time limit is bootstrapped: ``V(final_obs)``, discounted, is added to its reward and
  the episode boundary stops GAE there, so a truncation is not mistaken for a terminal state.

The budget is counted in environment steps, so agents whose decisions last differently compare fairly.
"""

from __future__ import annotations

import json
import time
from collections import deque
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, fields

import numpy as np
import torch

from famarl_cli.core.declare import default_of, plain
from famarl_cli.core.replicate_adam import ReplicateAdam
from famarl_cli.core.seeding import Stream, generator, seed_of
from famarl_cli.envs.batched import ContinuousWorldBatch
from famarl_cli.envs.vector import BatchedEnv
from famarl_cli.rl import DECISIONS_PER_ROLLOUT, Agent, MacroDiscount
from famarl_cli.rl.action_modes import ActionMode
from famarl_cli.rl.executor import SequenceResult, run_sequences
from famarl_cli.rl.normalization import ObservationNormalizer, RewardScaler
from famarl_cli.rl.options import DEFAULT_STEPS, PPOOptions
from famarl_cli.rl.policy import LOG_SQRT_2PI, ActorCritic
from famarl_cli.rl.prior_guide import PriorGuide
from famarl_cli.rl.semi_mdp import decision_reward

RECENT_EPISODES = 100
"""Training statistics (return, success) are means over this many most recent episodes."""


@dataclass(frozen=True)
class PPOConfig:
    """PPO's settings; those ``famarl train`` offers take its defaults (:mod:`famarl_cli.rl.options`), so
    ``PPOConfig()`` is ``famarl train --agent ppo``'s."""

    total_steps: int = DEFAULT_STEPS
    """Budget in environment steps (not decisions)."""
    n_envs: int = default_of(PPOOptions, "n_envs")
    n_steps: int = DECISIONS_PER_ROLLOUT[Agent.PPO]
    """Decisions per environment per rollout."""
    epochs: int = default_of(PPOOptions, "epochs")
    minibatches: int = default_of(PPOOptions, "minibatches")
    learning_rate: float = default_of(PPOOptions, "lr")
    anneal_lr: bool = True
    gamma: float = default_of(PPOOptions, "gamma")
    gae_lambda: float = default_of(PPOOptions, "gae_lambda")
    clip: float = default_of(PPOOptions, "clip")
    clip_value: bool = default_of(PPOOptions, "clip_value")
    ent_coef: float = default_of(PPOOptions, "ent_coef")
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    macro_discount: MacroDiscount = MacroDiscount.DECISION
    """Given as the enum or its value (``"steps"``); held as the enum."""
    type_entropy_floor: float = 0.0
    """Nats below which the categorical head's entropy is pushed back up (the hybrid's type head); 0: never."""
    type_entropy_until: float = default_of(PPOOptions, "type_entropy_until")
    """Share of the budget during which the floor holds."""
    type_entropy_coef: float = 1.0
    """Weight of the floor's hinge, max(0, floor - H(choice)), in the loss."""
    hidden: int = 64
    normalize_obs: bool = default_of(PPOOptions, "normalize")
    scale_rewards: bool = default_of(PPOOptions, "normalize")

    def __post_init__(self) -> None:
        if self.macro_discount not in tuple(MacroDiscount):
            raise ValueError(
                f"macro_discount must be one of {tuple(map(str, MacroDiscount))}, got {self.macro_discount!r}"
            )
        object.__setattr__(self, "macro_discount", MacroDiscount(self.macro_discount))
        if self.n_envs * self.n_steps < self.minibatches:
            raise ValueError("a rollout must hold at least one decision per minibatch")

    def to_dict(self) -> dict:
        """Plain data (the enum as its value), as JSON and the safe checkpoint loader read it back."""
        return plain(asdict(self))

    @staticmethod
    def from_dict(values: dict) -> PPOConfig:
        known = {f.name for f in fields(PPOConfig)}
        return PPOConfig(**{k: v for k, v in values.items() if k in known})


def compute_gae(
    rewards: np.ndarray,
    values: np.ndarray,
    dones: np.ndarray,
    discounts: np.ndarray,
    next_value: np.ndarray,
    lam: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Generalised advantage estimates and returns; all arrays (T, N) but ``next_value`` (N,).

    ``dones[t]``: the episode ended during decision t, so nothing after it is bootstrapped into it (a
    truncation's bootstrap is already inside ``rewards[t]``). ``discounts[t]`` is decision t's own discount.
    """
    advantages = np.zeros_like(rewards)
    running = np.zeros_like(next_value)
    for t in reversed(range(len(rewards))):
        following = next_value if t == len(rewards) - 1 else values[t + 1]
        carry = discounts[t] * (1.0 - dones[t])
        delta = rewards[t] + carry * following - values[t]
        running = delta + carry * lam * running
        advantages[t] = running
    return advantages, advantages + values


STATS = ("policy_loss", "value_loss", "entropy", "approx_kl", "clip_fraction")
"""What every minibatch step reports, averaged over an update."""


@dataclass
class Minibatch:
    """A minibatch of K replicates, B rows each: every field (K, B, ...), or without the replicate axis for one."""

    obs: torch.Tensor
    u: torch.Tensor
    index: torch.Tensor
    logp: torch.Tensor
    """(K, B) log-probability of (u, index) under the policy that collected the rollout."""
    values: torch.Tensor
    """(K, B) the critic's estimates when the rollout was collected."""
    advantages: torch.Tensor
    """(K, B) normalised over the minibatch."""
    returns: torch.Tensor
    base_mean: torch.Tensor | None = None
    """(K, B, action) the prior's mean the policy's is written relative to (:mod:`~famarl_cli.rl.prior_guide`)."""
    base_log_std: torch.Tensor | None = None
    """(K, B, action) the prior's log std, likewise."""

    def with_replicate_axis(self) -> Minibatch:
        return Minibatch(**{f.name: None if (v := getattr(self, f.name)) is None else v[None] for f in fields(self)})


def ppo_loss(
    policy: ActorCritic,
    batch: Minibatch,
    cfg: PPOConfig,
    entropy_floor: float | torch.Tensor = 0.0,
    prior_weight: float | torch.Tensor = 0.0,
    prior_mask: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """PPO's loss on one minibatch of each replicate, (K,), a function of ``policy.leaves``, and the :data:`STATS`
    (and the prior's KL where the batch has a prior), (K, stats); without the replicate axis in the minibatch, a
    scalar and (stats,). Replicates share nothing, so the gradient of the losses' sum is each one's own.

    loss = clipped policy loss - ent_coef * entropy + vf_coef * (clipped) value loss, each a mean over the
    minibatch, plus ``type_entropy_coef * max(0, entropy_floor - H(choice))`` where the policy has a categorical
    head (``entropy_floor``: a number, or one per replicate).

    With branches (the hybrid), only the chosen branch's outputs enter a row's log-density, and the entropy is
    H(choice) + sum_k p(k) H(branch k).

    With a prior (``batch.base_mean``), the Gaussian is N(base mean + mean, (e^(base log std + log std))^2) and the
    loss adds ``prior_weight`` (a number, or one per replicate) times the mean KL(pi || prior) over the outputs of
    ``prior_mask`` (:mod:`~famarl_cli.rl.prior_guide`).
    """
    alone = batch.obs.dim() == 2
    if alone:
        batch = batch.with_replicate_axis()
    heads = policy(batch.obs)
    mean, log_std = heads.mean, heads.log_std  # (K, B, action), (K, 1, action)
    guided = batch.base_mean is not None
    if guided:
        mean, log_std = mean + batch.base_mean, log_std + batch.base_log_std  # each row its own std
    z = (batch.u - mean) * torch.exp(-log_std)
    log_density = -0.5 * z.square() - log_std - LOG_SQRT_2PI  # per output
    output_entropy = log_std + (0.5 + LOG_SQRT_2PI)
    if policy.branch_mask is None:
        logp, entropy = log_density.sum(2), output_entropy.sum(2)
    else:
        logp = (log_density * policy.branch_mask[batch.index]).sum(2)
    hinge = 0.0
    if heads.logits is not None:
        log_p = heads.logits.log_softmax(2)
        logp = logp + log_p.gather(2, batch.index[..., None]).squeeze(2)
        p = log_p.exp()
        choice_entropy = -(p * log_p).sum(2)
        if policy.branch_mask is None:
            entropy = entropy + choice_entropy
        else:
            entropy = choice_entropy + (p * (output_entropy @ policy.branch_mask.T)).sum(2)
        floors = torch.as_tensor(entropy_floor, dtype=torch.float32).reshape(-1, 1)  # one, or one per replicate
        if bool((floors > 0).any()):
            hinge = cfg.type_entropy_coef * (floors - choice_entropy).clamp(min=0).mean(1)

    log_ratio = logp - batch.logp
    ratio = log_ratio.exp()
    clipped_ratio = ratio.clamp(1 - cfg.clip, 1 + cfg.clip)
    policy_loss = torch.maximum(-batch.advantages * ratio, -batch.advantages * clipped_ratio).mean(1)

    squared_error = (heads.value - batch.returns).square()
    if cfg.clip_value:
        clipped_value = batch.values + (heads.value - batch.values).clamp(-cfg.clip, cfg.clip)
        squared_error = torch.maximum(squared_error, (clipped_value - batch.returns).square())
    value_loss = 0.5 * squared_error.mean(1)

    entropy = entropy.mean(1)
    loss = policy_loss - cfg.ent_coef * entropy + cfg.vf_coef * value_loss + hinge
    stats = [policy_loss, value_loss, entropy]
    if guided:
        # KL(pi || prior) per guided output: -log std + (e^(2 log std) + mean^2 e^(-2 base log std)) / 2 - 1/2
        own_log_std = heads.log_std * prior_mask
        spread = ((0.5 * torch.exp(2 * own_log_std) - own_log_std - 0.5) * prior_mask).sum((1, 2))
        shift = 0.5 * ((heads.mean * prior_mask).square() * torch.exp(-2 * batch.base_log_std)).sum(2).mean(1)
        kl = spread + shift
        loss = loss + torch.as_tensor(prior_weight, dtype=torch.float32) * kl
        stats.append(kl)
    with torch.no_grad():
        approx_kl = (ratio - log_ratio).mean(1) - 1
        clip_fraction = (ratio != clipped_ratio).mean(1, dtype=torch.float32)
        found = torch.stack([*stats[:3], approx_kl, clip_fraction, *stats[3:]], 1)
    return (loss[0], found[0]) if alone else (loss, found)


def clip_rows(gradient: torch.Tensor, max_norm: float) -> torch.Tensor:
    """Each row of a (K, P) gradient scaled in place by ``torch.nn.utils.clip_grad_norm_``'s rule, as if each
    replicate were clipped alone: by max_norm / (norm + 1e-6) where that is below 1."""
    return gradient.mul_((max_norm / (gradient.norm(dim=1, keepdim=True) + 1e-6)).clamp(max=1.0))


@dataclass
class Rollout:
    obs: np.ndarray
    u: np.ndarray
    index: np.ndarray
    logp: np.ndarray
    values: np.ndarray
    rewards: np.ndarray
    """(T, N) the rewards PPO learns from: scaled, with truncations' bootstrap added."""
    dones: np.ndarray
    advantages: np.ndarray
    returns: np.ndarray
    macro_lengths: np.ndarray
    """(T, N) lengths of the sequences chosen (before an episode end cut them)."""
    macro: np.ndarray
    """(T, N) which decisions were macro actions (all for FaMARL, none for PPO and FiGAR)."""
    steps: np.ndarray
    """(T, N) environment steps each decision ran."""
    base_mean: np.ndarray | None = None
    """(T, N, action) the prior's mean at each decision's state (:mod:`~famarl_cli.rl.prior_guide`); None without."""
    base_log_std: np.ndarray | None = None

    @property
    def env_steps(self) -> int:
        return int(self.steps.sum())


class EpisodeTracker:
    """Per-environment running sums of the episode in progress, and the most recent finished episodes."""

    FIELDS = ("return", "length", "decisions", "success")

    def __init__(self, n_envs: int) -> None:
        self.current = {name: np.zeros(n_envs) for name in self.FIELDS[:-1]}
        self.recent: deque[tuple[float, ...]] = deque(maxlen=RECENT_EPISODES)
        self.finished = 0

    def record(self, result: SequenceResult) -> None:
        self.current["return"] += result.reward
        self.current["length"] += result.steps
        self.current["decisions"] += 1
        for i in np.flatnonzero(result.terminated | result.truncated):
            self.recent.append(tuple(float(self.current[k][i]) for k in self.FIELDS[:-1]) + (float(result.success[i]),))
            self.finished += 1
            for values in self.current.values():
                values[i] = 0.0

    def summary(self) -> dict[str, float]:
        if not self.recent:
            return {f"episode_{k}": float("nan") for k in self.FIELDS}
        means = np.mean(np.array(self.recent), axis=0)
        return {f"episode_{k}": float(v) for k, v in zip(self.FIELDS, means, strict=True)}

    def state_dict(self) -> dict:
        return {
            **{k: v.copy() for k, v in self.current.items()},
            "recent": np.array(self.recent).reshape(-1, len(self.FIELDS)),
            "finished": self.finished,
        }

    def load_state_dict(self, state: dict) -> None:
        self.current = {k: np.asarray(state[k]) for k in self.FIELDS[:-1]}
        self.recent = deque((tuple(row) for row in np.asarray(state["recent"]).tolist()), maxlen=RECENT_EPISODES)
        self.finished = int(state["finished"])


@dataclass
class Member:
    """Everything of one run (one seed) in a :class:`PPOTrainer`, but its network and optimiser rows."""

    env: BatchedEnv
    mode: ActionMode
    seed: int
    guide: PriorGuide | None
    rng: np.random.Generator
    """The rollouts' sampling."""
    choice_rng: np.random.Generator
    """The hybrid's type choices (ActorCritic.act)."""
    shuffles: torch.Generator
    """The minibatch shuffles: torch's global generator as the network's initialisation left it."""
    obs_norm: ObservationNormalizer
    reward_scaler: RewardScaler
    episodes: EpisodeTracker
    obs: np.ndarray
    env_steps: int = 0
    decisions: int = 0
    updates: int = 0
    log: list[dict[str, float]] = field(default_factory=list)
    seconds: float = 0.0
    """This run's share of the time spent training it in this process: each iteration's time split evenly among the
    runs it served (not saved; the run's record sums it across resumes)."""


class PPOTrainer:
    """Owns everything that changes while training; :meth:`state_dict` captures all of it for exact resumes.

    One trainer may train several runs of one agent at once, one per seed (:meth:`together`): their networks are
    the replicates of one :class:`ActorCritic` and one :class:`ReplicateAdam`, so that every call of acting and
    learning serves all of them, and all else (environments, random generators, statistics, logs) is each run's
    own. A run's numbers are those it computes alone, up to the rounding of batched kernels. Runs that reach their
    budget leave the batch; the others go on.
    """

    def __init__(
        self, env: BatchedEnv, mode: ActionMode, config: PPOConfig, seed: int, guide: PriorGuide | None = None
    ) -> None:
        self.config = config
        torch.manual_seed(seed_of(seed, Stream.NETWORK))  # initialisation, then the minibatch shuffles
        rng, choice_rng = generator(seed, Stream.ACTIONS), generator(seed, Stream.CHOICES)
        self.policy = ActorCritic(
            env.observation_size, mode.policy_action_size, mode.choices, config.hidden, mode.branches
        )
        if guide is not None:
            # The latent head starts at 0 relative to the prior: the policy starts exactly at p(z | s).
            self.policy.params["w_mean"][:, guide.columns] = 0.0
        shuffles = torch.Generator()
        shuffles.set_state(torch.get_rng_state())
        self.optimizer = ReplicateAdam(self.policy.flat, lr=config.learning_rate, eps=1e-5)
        member = Member(
            env,
            mode,
            seed,
            guide,
            rng,
            choice_rng,
            shuffles,
            ObservationNormalizer((env.observation_size,), config.normalize_obs),
            RewardScaler(config.n_envs, config.scale_rewards),
            EpisodeTracker(config.n_envs),
            env.reset(),
        )
        self.members = [member]
        self.worlds: ContinuousWorldBatch | None = None
        """The members' worlds joined into one batch, stepped in one call (ContinuousWorld only; else None)."""
        self.active = [0]
        """Indices of the members still training, in the order of the network's replicates."""
        self.finished: dict[int, dict] = {}
        """The final state of each member that left the batch."""

    @staticmethod
    def together(trainers: list[PPOTrainer]) -> PPOTrainer:
        """One trainer of the members of ``trainers`` (each of one seed, same config and network shape), their
        networks and optimisers copied into replicates; the members keep everything else."""
        first = trainers[0]
        if any(trainer.config != first.config for trainer in trainers):
            raise ValueError("runs trained together must share their PPO config (budget included)")
        joint = object.__new__(PPOTrainer)
        joint.config = first.config
        joint.members = [member for trainer in trainers for member in trainer.members]
        joint.finished = {}
        joint.active = list(range(len(joint.members)))
        joint._rebuild([(trainer, 0) for trainer in trainers])
        joint.worlds = joint._joined()
        return joint

    def _joined(self) -> ContinuousWorldBatch | None:
        """The active members' worlds as one batch, where they are ContinuousWorld batches of one setting."""
        envs = [self.members[i].env for i in self.active]
        if len(envs) < 2 or not all(isinstance(env, ContinuousWorldBatch) for env in envs):
            return None
        if len({(env.task, env.goal_rows, env.max_episode_steps) for env in envs}) > 1:
            return None
        return ContinuousWorldBatch.join(envs)

    def _rebuild(self, sources: list[tuple[PPOTrainer, int]]) -> None:
        """A network and optimiser with one replicate per ``(trainer, replicate)`` of ``sources``, copied."""
        first = sources[0][0].policy
        self.policy = ActorCritic(
            first.obs_size,
            first.action_size,
            first.choices,
            self.config.hidden,
            first.branches,
            replicates=len(sources),
        )
        policy = self.policy
        self.optimizer = ReplicateAdam(policy.flat, self.config.learning_rate, eps=1e-5)
        for k, (trainer, replicate) in enumerate(sources):
            policy.load_state_dict(trainer.policy.state_dict(replicate), k)
            self.optimizer.load_state_dict(trainer.optimizer.state_dict(replicate), k)

    def member_done(self, index: int) -> bool:
        return self.members[index].env_steps >= self.config.total_steps

    @property
    def done(self) -> bool:
        return all(self.member_done(i) for i in range(len(self.members)))

    def collect_rollouts(self) -> list[Rollout]:
        """One rollout of every active member, their networks acting in one call per decision."""
        cfg, n = self.config, self.config.n_envs
        members = [self.members[i] for i in self.active]
        obs = np.zeros((len(members), cfg.n_steps, n, members[0].env.observation_size), np.float32)
        u = np.zeros((len(members), cfg.n_steps, n, members[0].mode.policy_action_size), np.float32)
        index, steps = (np.zeros((len(members), cfg.n_steps, n), np.int64) for _ in range(2))
        macro = np.zeros((len(members), cfg.n_steps, n), bool)
        logp, values, rewards, dones, discounts, lengths = (np.zeros((len(members), cfg.n_steps, n)) for _ in range(6))
        guided = members[0].guide is not None
        base_mean = base_log_std = None
        if guided:
            base_mean, base_log_std = (np.zeros_like(u) for _ in range(2))
        bases = [None] * len(members)
        for t in range(cfg.n_steps):
            for k, member in enumerate(members):
                if guided:
                    bases[k] = base_mean[k, t], base_log_std[k, t] = member.guide.base(member.obs)
                obs[k, t] = member.obs_norm(member.obs, update=True)
            actions = self.policy.act_replicates(
                obs[:, t], [m.rng for m in members], [m.choice_rng for m in members], bases
            )
            sequences = []
            for k, (member, action) in enumerate(zip(members, actions, strict=True)):
                u[k, t], index[k, t], logp[k, t], values[k, t] = action.u, action.index, action.logp, action.value
                decisions, lengths[k, t] = member.mode.to_sequences(u[k, t].astype(np.float64), index[k, t])
                sequences.append(decisions)
                macro[k, t] = member.mode.macro(index[k, t])
            finals = self._run(members, sequences, lengths[:, t].astype(np.int64))
            for k, (member, result) in enumerate(zip(members, finals, strict=True)):
                dones[k, t] = result.terminated | result.truncated
                rewards[k, t], discounts[k, t] = decision_reward(
                    result, cfg.macro_discount, cfg.gamma, member.reward_scaler
                )
                member.episodes.record(result)
                steps[k, t] = result.steps
                member.env_steps += int(result.steps.sum())
                member.decisions += n
                member.obs = result.obs
            self._bootstrap_truncations(members, finals, rewards[:, t], discounts[:, t])
        next_values = self._values(members, [m.obs for m in members])
        stacked = {"obs": obs, "u": u, "index": index, "logp": logp, "values": values, "rewards": rewards}
        stacked |= {"dones": dones, "macro_lengths": lengths, "macro": macro, "steps": steps}
        stacked |= {"base_mean": base_mean, "base_log_std": base_log_std}
        rollouts = []
        for k in range(len(members)):
            advantages, returns = compute_gae(
                rewards[k], values[k], dones[k], discounts[k], next_values[k], cfg.gae_lambda
            )
            own = {name: None if array is None else array[k] for name, array in stacked.items()}
            rollouts.append(Rollout(**own, advantages=advantages, returns=returns))
        return rollouts

    def _run(self, members: list[Member], sequences: list, lengths: np.ndarray) -> list[SequenceResult]:
        """Each member's decisions in its environments: in one batch where the worlds are joined and the sequences
        open-loop, else member by member."""
        if self.worlds is None or not all(isinstance(s, np.ndarray) for s in sequences):
            return [run_sequences(m.env, m.obs, s, n) for m, s, n in zip(members, sequences, lengths, strict=True)]
        longest = max(s.shape[1] for s in sequences)
        padded = [np.pad(s, ((0, 0), (0, longest - s.shape[1]), (0, 0))) for s in sequences]
        obs = np.concatenate([m.obs for m in members])
        result = run_sequences(self.worlds, obs, np.concatenate(padded), lengths.reshape(-1))
        return [result.rows(part) for part, _ in self.worlds.groups]

    def _values(self, members: list[Member], states: list[np.ndarray]) -> list[np.ndarray]:
        """Each member's critic on its raw states (normalised by its frozen statistics)."""
        rows = max(len(state) for state in states)
        obs = np.zeros((len(members), rows, members[0].env.observation_size), np.float32)
        for k, (member, state) in enumerate(zip(members, states, strict=True)):
            obs[k, : len(state)] = member.obs_norm(state, update=False)
        actions = self.policy.act_replicates(obs, [None] * len(members), [None] * len(members), [None] * len(members))
        return [action.value[: len(state)] for action, state in zip(actions, states, strict=True)]

    def _bootstrap_truncations(self, members, results, rewards: np.ndarray, discounts: np.ndarray) -> None:
        """A decision cut by the time limit gets V(final obs), discounted, added to its reward."""
        cut = [result.truncated for result in results]
        if not any(c.any() for c in cut):
            return
        finals = [result.final_obs[c] for result, c in zip(results, cut, strict=True)]
        for k, value in enumerate(self._values(members, finals)):
            rewards[k, cut[k]] += discounts[k, cut[k]] * value

    def collect_rollout(self) -> Rollout:
        """The rollout of a trainer of one seed."""
        [rollout] = self.collect_rollouts()
        return rollout

    def update(self, rollouts: list[Rollout] | Rollout) -> list[dict[str, float]] | dict[str, float]:
        """PPO's epochs on every active member's rollout (one rollout for a trainer of one seed); the stats of each."""
        alone = isinstance(rollouts, Rollout)
        rollouts = [rollouts] if alone else rollouts
        cfg, size = self.config, rollouts[0].index.size
        members = [self.members[i] for i in self.active]
        guides = [member.guide for member in members]
        guided = guides[0] is not None
        # One table per member, so that an epoch's shuffle is one gather; the repeat index rides along as a float.
        names = ("obs", "u", "logp", "values", "advantages", "returns", "index")
        if guided:
            names += ("base_mean", "base_log_std")
        tables, split = [], None
        for rollout in rollouts:
            arrays = [getattr(rollout, name).reshape(size, -1) for name in names]
            tables.append(np.concatenate(arrays, axis=1, dtype=np.float32))
            split = [array.shape[1] for array in arrays]
        data = torch.from_numpy(np.stack(tables))
        minibatch = size // cfg.minibatches
        used = minibatch * cfg.minibatches
        stat_names = STATS if not guided else (*STATS, "prior_kl")
        totals = torch.zeros(len(members), len(stat_names))
        policy = self.policy
        mask = None if not guided else torch.from_numpy(guides[0].mask.astype(np.float32))
        floor = torch.tensor(
            [
                cfg.type_entropy_floor if m.env_steps <= cfg.type_entropy_until * cfg.total_steps else 0.0
                for m in members
            ]
        )
        for _ in range(cfg.epochs):
            order = torch.stack([torch.randperm(size, generator=m.shuffles) for m in members])[:, :used]
            shuffled = data.gather(1, order[..., None].expand(-1, -1, data.shape[2]))
            columns = dict(zip(names, shuffled.split(split, dim=2), strict=True))
            for name in ("logp", "values", "advantages", "returns", "index"):
                columns[name] = columns[name].squeeze(2)
            columns["index"] = columns["index"].long()
            # Advantages are normalised per member and minibatch; all of an epoch's minibatches at once.
            advantages = columns["advantages"].view(len(members), cfg.minibatches, minibatch)
            advantages.sub_(advantages.mean(2, keepdim=True)).div_(advantages.std(2, keepdim=True).add_(1e-8))
            minibatches = {name: column.split(minibatch, dim=1) for name, column in columns.items()}
            for i in range(cfg.minibatches):
                batch = Minibatch(**{name: parts[i] for name, parts in minibatches.items()})
                if not guided:
                    losses, stats = ppo_loss(policy, batch, cfg, floor)
                else:
                    weights = torch.tensor([guide.weight for guide in guides], dtype=torch.float32)
                    losses, stats = ppo_loss(policy, batch, cfg, floor, weights, mask)
                    for guide, kl in zip(guides, stats[:, -1].tolist(), strict=True):
                        guide.tune(kl)
                totals += stats
                losses.sum().backward()
                self.optimizer.step(clip_rows(policy.gradient(), cfg.max_grad_norm))
        found = []
        for k, rollout in enumerate(rollouts):
            stats = dict(zip(stat_names, (totals[k] / (cfg.epochs * cfg.minibatches)).tolist(), strict=True))
            if guided:
                stats["prior_weight"] = guides[k].weight
            variance = np.var(rollout.returns)
            stats["explained_variance"] = (
                float(1 - np.var(rollout.returns - rollout.values) / variance) if variance else float("nan")
            )
            found.append(stats)
        return found[0] if alone else found

    def train(
        self,
        on_update: Callable[[PPOTrainer, dict[str, float]], None] | None = None,
        on_member_update: Callable[[int, dict[str, float]], None] | None = None,
        on_finish: Callable[[int], None] | None = None,
    ) -> None:
        """Rollout and update until every member has spent its budget of environment steps. ``on_update`` sees
        every log row of a trainer of one seed, ``on_member_update(member, row)`` every member's; ``on_finish(member)``
        is called as a member reaches its budget, before it leaves the batch."""
        cfg = self.config
        while True:
            leaving = [index for index in self.active if self.member_done(index)]
            for index in leaving:
                if on_finish is not None:
                    on_finish(index)
                self.finished[index] = self.state_dict(index)
            if leaving:
                self._leave(leaving)
            if not self.active:
                return
            started = time.perf_counter()
            members = [self.members[i] for i in self.active]
            rates = [
                cfg.learning_rate * (1.0 - m.env_steps / cfg.total_steps if cfg.anneal_lr else 1.0) for m in members
            ]
            self.optimizer.set_lr(rates)
            rollouts = self.collect_rollouts()
            found = self.update(rollouts)
            share = (time.perf_counter() - started) / len(members)
            for index, member, rollout, stats, learning_rate in zip(
                list(self.active), members, rollouts, found, rates, strict=True
            ):
                member.updates += 1
                member.seconds += share
                row = {
                    "update": member.updates,
                    "env_steps": member.env_steps,
                    "decisions": member.decisions,
                    "episodes": member.episodes.finished,
                    **member.episodes.summary(),
                    "macro_length": float(rollout.macro_lengths.mean()),
                    "steps_per_decision": rollout.env_steps / rollout.macro_lengths.size,
                    "macro_share": float(rollout.macro.mean()),
                    "macro_step_share": float(rollout.steps[rollout.macro].sum() / max(rollout.env_steps, 1)),
                    "learning_rate": learning_rate,
                    **stats,
                }
                member.log.append(row)
                if on_update is not None:
                    on_update(self, row)
                if on_member_update is not None:
                    on_member_update(index, row)

    def _leave(self, leaving: list[int]) -> None:
        """Take the members ``leaving`` out of the batch: the network and optimiser keep only the others' rows."""
        staying = [index for index in self.active if index not in leaving]
        if staying:
            old = object.__new__(PPOTrainer)
            old.policy, old.optimizer = self.policy, self.optimizer
            self._rebuild([(old, self.active.index(index)) for index in staying])
        if self.worlds is not None:
            self.worlds.write_back()
        self.active = staying
        self.worlds = self._joined()

    def state_dict(self, member: int = 0) -> dict:
        """Everything of one member (in the format of a trainer of one seed, which a resume loads)."""
        if member in self.finished:
            return self.finished[member]
        if self.worlds is not None:
            self.worlds.write_back()
        m, row = self.members[member], self.active.index(member)
        return {
            "policy": self.policy.state_dict(row),
            "optimizer": self.optimizer.state_dict(row),
            "torch_rng": m.shuffles.get_state(),
            "sampling_rng": json.dumps(m.rng.bit_generator.state),
            "choice_rng": json.dumps(m.choice_rng.bit_generator.state),
            "obs_norm": m.obs_norm.state_dict(),
            "reward_scaler": m.reward_scaler.state_dict(),
            "episodes": m.episodes.state_dict(),
            "env": m.env.state_dict(),
            "obs": m.obs.copy(),
            "counters": {"env_steps": m.env_steps, "decisions": m.decisions, "updates": m.updates},
            "log": list(m.log),
            **({} if m.guide is None else {"guide": m.guide.state_dict()}),
        }

    def load_state_dict(self, state: dict, member: int = 0) -> None:
        m, row = self.members[member], self.active.index(member)
        self.policy.load_state_dict(state["policy"], row)
        self.optimizer.load_state_dict(state["optimizer"], row)
        m.shuffles.set_state(state["torch_rng"])
        m.rng.bit_generator.state = json.loads(state["sampling_rng"])
        if "choice_rng" in state:  # checkpoints from before the hybrid agent have none; only the hybrid uses it
            m.choice_rng.bit_generator.state = json.loads(state["choice_rng"])
        if m.guide is not None:
            m.guide.load_state_dict(state["guide"])
        m.obs_norm.load_state_dict(state["obs_norm"])
        m.reward_scaler.load_state_dict(state["reward_scaler"])
        m.log = list(state["log"])
        counters = state["counters"]
        m.env_steps, m.decisions, m.updates = counters["env_steps"], counters["decisions"], counters["updates"]
        if state["env"] is not None:
            m.env.load_state_dict(state["env"])
            m.obs = np.asarray(state["obs"], dtype=np.float32)
            m.episodes.load_state_dict(state["episodes"])
        else:
            # An environment without a snapshot restarts its episodes; the ones in progress are not counted.
            m.obs = m.env.reset()
            m.episodes.load_state_dict(
                {**state["episodes"], **{k: np.zeros(self.config.n_envs) for k in EpisodeTracker.FIELDS[:-1]}}
            )
        if self.worlds is not None:
            self.worlds = self._joined()  # the worlds as the member's env now has them
