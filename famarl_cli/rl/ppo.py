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
from collections import deque
from collections.abc import Callable
from dataclasses import asdict, dataclass, fields

import numpy as np
import torch

from famarl_cli.rl import MacroDiscount
from famarl_cli.rl.action_modes import ActionMode
from famarl_cli.rl.executor import SequenceResult, run_sequences
from famarl_cli.rl.normalization import ObservationNormalizer, RewardScaler
from famarl_cli.rl.optimizer import FlatAdam, clip_norm
from famarl_cli.rl.policy import LOG_SQRT_2PI, ActorCritic
from famarl_cli.rl.prior_guide import PriorGuide
from famarl_cli.rl.semi_mdp import decision_reward
from famarl_cli.rl.vector import BatchedEnv

RECENT_EPISODES = 100
"""Training statistics (return, success) are means over this many most recent episodes."""


@dataclass(frozen=True)
class PPOConfig:
    total_steps: int = 2_000_000
    """Budget in environment steps (not decisions)."""
    n_envs: int = 16
    n_steps: int = 64
    """Decisions per environment per rollout."""
    epochs: int = 10
    minibatches: int = 8
    learning_rate: float = 3e-4
    anneal_lr: bool = True
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip: float = 0.2
    clip_value: bool = True
    ent_coef: float = 0.0
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    macro_discount: str = "decision"
    type_entropy_floor: float = 0.0
    """Nats below which the categorical head's entropy is pushed back up (the hybrid's type head); 0: never."""
    type_entropy_until: float = 0.25
    """Share of the budget during which the floor holds."""
    type_entropy_coef: float = 1.0
    """Weight of the floor's hinge, max(0, floor - H(choice)), in the loss."""
    hidden: int = 64
    normalize_obs: bool = True
    scale_rewards: bool = True

    def __post_init__(self) -> None:
        if self.macro_discount not in tuple(MacroDiscount):
            raise ValueError(
                f"macro_discount must be one of {tuple(map(str, MacroDiscount))}, got {self.macro_discount!r}"
            )
        if self.n_envs * self.n_steps < self.minibatches:
            raise ValueError("a rollout must hold at least one decision per minibatch")

    def to_dict(self) -> dict:
        return asdict(self)

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
    obs: torch.Tensor
    u: torch.Tensor
    index: torch.Tensor
    logp: torch.Tensor
    """(B,) log-probability of (u, index) under the policy that collected the rollout."""
    values: torch.Tensor
    """(B,) the critic's estimates when the rollout was collected."""
    advantages: torch.Tensor
    """(B,) normalised over the minibatch."""
    returns: torch.Tensor
    base_mean: torch.Tensor | None = None
    """(B, action) the prior's mean the policy's is written relative to (:mod:`~famarl_cli.rl.prior_guide`)."""
    base_log_std: torch.Tensor | None = None
    """(B, action) the prior's log std, likewise."""


def clipped_objective_gradient(
    policy: ActorCritic,
    batch: Minibatch,
    cfg: PPOConfig,
    entropy_floor: float = 0.0,
    prior_weight: float = 0.0,
    prior_mask: torch.Tensor | None = None,
) -> torch.Tensor:
    """Writes into ``policy.gradient`` the gradient of PPO's loss on one minibatch; returns the :data:`STATS` (and
    the prior's KL where the batch has a prior).

    loss = clipped policy loss - ent_coef * entropy + vf_coef * (clipped) value loss, each a mean over the
    minibatch, plus ``type_entropy_coef * max(0, entropy_floor - H(choice))`` where the policy has a categorical
    head. The derivative of each term with respect to the network's heads is written beside it; where a ``max``
    picks the clipped term, the clip is active and passes no gradient.

    With branches (the hybrid), only the chosen branch's outputs enter a row's log-density, and the entropy is
    H(choice) + sum_k p(k) H(branch k).

    With a prior (``batch.base_mean``), the Gaussian is N(base mean + mean, (e^(base log std + log std))^2) and the
    loss adds ``prior_weight`` times the mean KL(pi || prior) over the outputs of ``prior_mask``
    (:mod:`~famarl_cli.rl.prior_guide`).
    """
    size, log_std = len(batch.obs), policy.log_std
    heads = policy(batch.obs)
    guided = batch.base_mean is not None
    # Every torch call costs ~5 us here, more than its arithmetic: in-place where possible, nothing computed twice.
    if guided:
        row_log_std = batch.base_log_std + log_std  # (B, action): each row's own
        inv_std = row_log_std.neg().exp()
        z = (batch.u - batch.base_mean - heads.mean).mul_(inv_std)
    else:
        inv_std = log_std.neg().exp()
        z = (batch.u - heads.mean).mul_(inv_std)
    rows = None if policy.branch_mask is None else policy.branch_mask[batch.index]
    if rows is not None:
        z.mul_(rows)
    z2 = z.square()
    if rows is None:
        # sum(log_std) + const, also the entropy (a row's own, averaged, with a prior)
        gaussian_constant = (
            row_log_std.sum(1) + LOG_SQRT_2PI * len(log_std) if guided else log_std.sum() + LOG_SQRT_2PI * len(log_std)
        )
        log_ratio = z2.sum(1).mul_(-0.5).sub_(gaussian_constant).sub_(batch.logp)
    else:
        # each output's share of -log density and (+ 1/2) of the entropy; (B, action) with a prior
        per_output = (row_log_std if guided else log_std) + LOG_SQRT_2PI
        density = (rows * per_output).sum(1) if guided else rows @ per_output
        log_ratio = z2.sum(1).mul_(-0.5).sub_(density).sub_(batch.logp)
    if heads.logits is not None:
        log_p = heads.logits.log_softmax(1)
        log_ratio += log_p.gather(1, batch.index[:, None]).squeeze(1)
    ratio = log_ratio.exp()
    clipped_ratio = ratio.clamp(1 - cfg.clip, 1 + cfg.clip)
    gain, clipped_gain = batch.advantages * ratio, batch.advantages * clipped_ratio
    policy_loss = -torch.minimum(gain, clipped_gain).mean()
    # d policy_loss / d logp = -advantage * ratio / size where the unclipped term is the min, else 0
    d_logp = gain.mul_(gain <= clipped_gain).mul_(-1.0 / size)

    error = heads.value - batch.returns
    squared_error = error.square()
    if cfg.clip_value:
        # error + (clamped change - change): equal to error, to the bit, wherever the clip is inactive
        change = heads.value - batch.values
        clipped_error = change.clamp(-cfg.clip, cfg.clip).sub_(change).add_(error)
        clipped_squared_error = clipped_error.square()
        value_loss = torch.maximum(squared_error, clipped_squared_error).mean().mul_(0.5)
        d_value = error.mul_(clipped_squared_error <= squared_error)
    else:
        value_loss, d_value = squared_error.mean().mul_(0.5), error
    d_value = d_value.mul_(cfg.vf_coef / size)

    # d logp / d mean = z / std and d logp / d log_std = z^2 - 1 (on the chosen branch's outputs, 0 elsewhere)
    d_log_std = torch.mv(z2.sub_(1 if rows is None else rows).T, d_logp)
    d_mean = z.mul_(d_logp[:, None]).mul_(inv_std)
    d_logits = None
    if heads.logits is None:
        entropy = (gaussian_constant + 0.5 * len(log_std)).mean()
        d_log_std.sub_(cfg.ent_coef)
    else:
        p = log_p.exp()
        choice_entropy = -(p * log_p).sum(1)
        # d log p[index] / d logits = onehot(index) - p;  d H(choice) / d logits = -p (log p + H(choice))
        d_logits = -p * d_logp[:, None]
        d_logits.scatter_add_(1, batch.index[:, None], d_logp[:, None])
        d_choice_entropy = cfg.ent_coef / size
        if entropy_floor > 0:
            below = (choice_entropy < entropy_floor).float()
            d_choice_entropy = d_choice_entropy + below[:, None] * (cfg.type_entropy_coef / size)
        d_logits += d_choice_entropy * p * (log_p + choice_entropy[:, None])
        if rows is None:
            entropy = (gaussian_constant + 0.5 * len(log_std)).mean() + choice_entropy.mean()
            d_log_std.sub_(cfg.ent_coef)
        else:
            # sum_k p(k) H(branch k): d / d log_std = E_rows[p @ mask]; d / d logits = p (H(branch) - that sum)
            if guided:
                branch_entropy = (per_output + 0.5) @ policy.branch_mask.T  # (B, choices)
                expected = (p * branch_entropy).sum(1)
            else:
                branch_entropy = policy.branch_mask @ (per_output + 0.5)
                expected = p @ branch_entropy
            weights = p @ policy.branch_mask
            entropy = (choice_entropy + expected).mean()
            d_log_std.sub_(weights.mean(0), alpha=cfg.ent_coef)
            d_logits -= (cfg.ent_coef / size) * p * (branch_entropy - expected[:, None])
    stats = [policy_loss, value_loss, entropy]
    if guided:
        # KL(pi || prior) per guided output j: -l_j + e^(2 l_j) / 2 + m_j^2 e^(-2 base log std_j) / 2 - 1/2
        mean = heads.mean * prior_mask
        inv_prior_var = batch.base_log_std.mul(-2).exp_()
        scaled = mean * inv_prior_var
        guided_log_std = log_std * prior_mask
        variance_less_one = guided_log_std.mul(2).exp_().sub_(1).mul_(prior_mask)  # e^(2 l) - 1, also d KL / d l
        kl = (
            variance_less_one.mul(0.5).sub_(guided_log_std).mul_(prior_mask).sum() + 0.5 * (scaled * mean).sum(1).mean()
        )
        if prior_weight > 0:
            d_mean.add_(scaled, alpha=prior_weight / size)
            d_log_std.add_(variance_less_one, alpha=prior_weight)
        stats.append(kl)
    policy.backward(heads, d_mean, d_log_std, d_value, d_logits)
    approx_kl = (ratio - log_ratio).mean() - 1
    clip_fraction = (ratio != clipped_ratio).mean(dtype=torch.float32)
    stats[3:3] = [approx_kl, clip_fraction]
    return torch.stack(stats)


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


class PPOTrainer:
    """Owns everything that changes while training; :meth:`state_dict` captures all of it for exact resumes."""

    def __init__(
        self, env: BatchedEnv, mode: ActionMode, config: PPOConfig, seed: int, guide: PriorGuide | None = None
    ) -> None:
        self.env, self.mode, self.config, self.guide = env, mode, config, guide
        torch.manual_seed(seed)  # initialisation and the minibatch shuffles
        self.rng = np.random.default_rng(seed)  # the rollouts' sampling
        self.choice_rng = np.random.default_rng([1, seed])  # the hybrid's type choices (ActorCritic.act)
        self.policy = ActorCritic(
            env.observation_size, mode.policy_action_size, mode.choices, config.hidden, mode.branches
        )
        if guide is not None:
            # The latent head starts at 0 relative to the prior: the policy starts exactly at p(z | s).
            self.policy.params["w_mean"][:, guide.columns] = 0.0
        self.optimizer = FlatAdam(self.policy.flat, lr=config.learning_rate, eps=1e-5)
        self.obs_norm = ObservationNormalizer((env.observation_size,), config.normalize_obs)
        self.reward_scaler = RewardScaler(config.n_envs, config.scale_rewards)
        self.episodes = EpisodeTracker(config.n_envs)
        self.obs = env.reset()
        self.env_steps = 0
        self.decisions = 0
        self.updates = 0
        self.log: list[dict[str, float]] = []

    @property
    def done(self) -> bool:
        return self.env_steps >= self.config.total_steps

    def collect_rollout(self) -> Rollout:
        cfg, n = self.config, self.config.n_envs
        obs = np.zeros((cfg.n_steps, n, self.env.observation_size), np.float32)
        u = np.zeros((cfg.n_steps, n, self.mode.policy_action_size), np.float32)
        index, steps = (np.zeros((cfg.n_steps, n), np.int64) for _ in range(2))
        macro = np.zeros((cfg.n_steps, n), bool)
        logp, values, rewards, dones, discounts, lengths = (np.zeros((cfg.n_steps, n)) for _ in range(6))
        base_mean = base_log_std = base = None
        if self.guide is not None:
            base_mean, base_log_std = (np.zeros_like(u) for _ in range(2))
        for t in range(cfg.n_steps):
            if self.guide is not None:
                base = base_mean[t], base_log_std[t] = self.guide.base(self.obs)
            obs[t] = self.obs_norm(self.obs, update=True)
            action = self.policy.act(obs[t], self.rng, self.choice_rng, base)
            u[t], index[t], logp[t], values[t] = action.u, action.index, action.logp, action.value
            actions, lengths[t] = self.mode.to_sequences(u[t].astype(np.float64), index[t])
            macro[t] = self.mode.macro(index[t])
            result = run_sequences(self.env, self.obs, actions, lengths[t].astype(np.int64))
            dones[t] = result.terminated | result.truncated
            rewards[t], discounts[t] = decision_reward(result, cfg.macro_discount, cfg.gamma, self.reward_scaler)
            if result.truncated.any():
                cut = result.truncated
                final = self.obs_norm(result.final_obs[cut], update=False)
                rewards[t, cut] += discounts[t, cut] * self.policy.act(final).value
            self.episodes.record(result)
            steps[t] = result.steps
            self.env_steps += int(result.steps.sum())
            self.decisions += n
            self.obs = result.obs
        next_value = self.policy.act(self.obs_norm(self.obs, update=False)).value
        advantages, returns = compute_gae(rewards, values, dones, discounts, next_value, cfg.gae_lambda)
        return Rollout(
            obs,
            u,
            index,
            logp,
            values,
            rewards,
            dones,
            advantages,
            returns,
            lengths,
            macro,
            steps,
            base_mean,
            base_log_std,
        )

    # inference_mode: no autograd bookkeeping on any tensor (the gradient is written out), a third off every call.
    @torch.inference_mode()
    def update(self, rollout: Rollout) -> dict[str, float]:
        cfg, size = self.config, rollout.index.size
        # One table, so that an epoch's shuffle is one gather; the repeat index rides along as a float.
        names = ("obs", "u", "logp", "values", "advantages", "returns", "index")
        if self.guide is not None:
            names += ("base_mean", "base_log_std")
        arrays = [getattr(rollout, name).reshape(size, -1) for name in names]
        data = torch.from_numpy(np.concatenate(arrays, axis=1, dtype=np.float32))
        split = [array.shape[1] for array in arrays]
        minibatch = size // cfg.minibatches
        stat_names = STATS if self.guide is None else (*STATS, "prior_kl")
        totals = torch.zeros(len(stat_names))
        gradient = self.policy.gradient
        mask = None if self.guide is None else torch.from_numpy(self.guide.mask.astype(np.float32))
        early = self.env_steps <= cfg.type_entropy_until * cfg.total_steps
        floor = cfg.type_entropy_floor if early else 0.0
        for _ in range(cfg.epochs):
            shuffled = data[torch.randperm(size)][: minibatch * cfg.minibatches]
            columns = dict(zip(names, shuffled.split(split, dim=1), strict=True))
            for name in ("logp", "values", "advantages", "returns", "index"):
                columns[name] = columns[name].view(-1)
            columns["index"] = columns["index"].long()
            # Advantages are normalised per minibatch; all of an epoch's minibatches at once.
            advantages = columns["advantages"].view(cfg.minibatches, minibatch)
            advantages.sub_(advantages.mean(1, keepdim=True)).div_(advantages.std(1, keepdim=True).add_(1e-8))
            minibatches = {name: column.split(minibatch) for name, column in columns.items()}
            for i in range(cfg.minibatches):
                batch = Minibatch(**{name: parts[i] for name, parts in minibatches.items()})
                if self.guide is None:
                    totals += clipped_objective_gradient(self.policy, batch, cfg, floor)
                else:
                    step = clipped_objective_gradient(self.policy, batch, cfg, floor, self.guide.weight, mask)
                    totals += step
                    self.guide.tune(float(step[-1]))
                clip_norm(gradient, cfg.max_grad_norm)
                self.optimizer.step(gradient)
        stats = dict(zip(stat_names, (totals / (cfg.epochs * cfg.minibatches)).tolist(), strict=True))
        if self.guide is not None:
            stats["prior_weight"] = self.guide.weight
        variance = np.var(rollout.returns)
        stats["explained_variance"] = (
            float(1 - np.var(rollout.returns - rollout.values) / variance) if variance else float("nan")
        )
        return stats

    def train(self, on_update: Callable[[PPOTrainer, dict[str, float]], None] | None = None) -> None:
        """Rollout and update until the budget of environment steps is spent; ``on_update`` sees every log row."""
        cfg = self.config
        while not self.done:
            learning_rate = cfg.learning_rate * (1.0 - self.env_steps / cfg.total_steps if cfg.anneal_lr else 1.0)
            self.optimizer.lr = learning_rate
            rollout = self.collect_rollout()
            stats = self.update(rollout)
            self.updates += 1
            row = {
                "update": self.updates,
                "env_steps": self.env_steps,
                "decisions": self.decisions,
                "episodes": self.episodes.finished,
                **self.episodes.summary(),
                "macro_length": float(rollout.macro_lengths.mean()),
                "steps_per_decision": rollout.env_steps / rollout.macro_lengths.size,
                "macro_share": float(rollout.macro.mean()),
                "macro_step_share": float(rollout.steps[rollout.macro].sum() / max(rollout.env_steps, 1)),
                "learning_rate": learning_rate,
                **stats,
            }
            self.log.append(row)
            if on_update is not None:
                on_update(self, row)

    def state_dict(self) -> dict:
        return {
            "policy": self.policy.state_dict(),
            "optimizer": self.optimizer.state_dict(),
            "torch_rng": torch.get_rng_state(),
            "sampling_rng": json.dumps(self.rng.bit_generator.state),
            "choice_rng": json.dumps(self.choice_rng.bit_generator.state),
            "obs_norm": self.obs_norm.state_dict(),
            "reward_scaler": self.reward_scaler.state_dict(),
            "episodes": self.episodes.state_dict(),
            "env": self.env.state_dict(),
            "obs": self.obs.copy(),
            "counters": {"env_steps": self.env_steps, "decisions": self.decisions, "updates": self.updates},
            "log": list(self.log),
            **({} if self.guide is None else {"guide": self.guide.state_dict()}),
        }

    def load_state_dict(self, state: dict) -> None:
        self.policy.load_state_dict(state["policy"])
        self.optimizer.load_state_dict(state["optimizer"])
        torch.set_rng_state(state["torch_rng"])
        self.rng.bit_generator.state = json.loads(state["sampling_rng"])
        if "choice_rng" in state:  # checkpoints from before the hybrid agent have none; only the hybrid uses it
            self.choice_rng.bit_generator.state = json.loads(state["choice_rng"])
        if self.guide is not None:
            self.guide.load_state_dict(state["guide"])
        self.obs_norm.load_state_dict(state["obs_norm"])
        self.reward_scaler.load_state_dict(state["reward_scaler"])
        self.log = list(state["log"])
        counters = state["counters"]
        self.env_steps, self.decisions, self.updates = counters["env_steps"], counters["decisions"], counters["updates"]
        if state["env"] is not None:
            self.env.load_state_dict(state["env"])
            self.obs = np.asarray(state["obs"], dtype=np.float32)
            self.episodes.load_state_dict(state["episodes"])
        else:
            # An environment without a snapshot restarts its episodes; the ones in progress are not counted.
            self.obs = self.env.reset()
            self.episodes.load_state_dict(
                {**state["episodes"], **{k: np.zeros(self.config.n_envs) for k in EpisodeTracker.FIELDS[:-1]}}
            )
