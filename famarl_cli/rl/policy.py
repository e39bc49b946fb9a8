"""The actor-critic: separate 64-64 tanh networks, orthogonal initialisation, a state-independent log std,
and a categorical head on the actor's features where the action mode has one (FiGAR's repeat counts, the
hybrid's action type; CleanRL's layout).

The hybrid's choice decides which outputs of the Gaussian it uses (``branches``): a decision's log-probability is
log pi(k) plus the log-density of the chosen branch's outputs only, so the other branch's outputs get no
gradient from it.

Acting and learning take different paths through the same parameters, each the fastest for its batch:

- :meth:`ActorCritic.act` runs in numpy. A rollout step's batch is one row per environment, and there every call
  costs more than its arithmetic: a numpy call costs about a fifth of a torch call, and the observations, the
  chosen actions and the environments are numpy already.
- :meth:`ActorCritic.__call__` runs a minibatch in torch, differentiable: PPO's loss
  (:func:`~famarl_cli.rl.ppo.ppo_loss`) takes its gradient by autograd.

A network holds ``replicates`` copies (K), one per seed of a batch of runs (:class:`~famarl_cli.rl.ppo.PPOTrainer`):
:attr:`ActorCritic.flat` is (K, P), row k replicate k's parameters in the order of :attr:`ActorCritic.layout` (a
checkpoint stores a row), and every call of either path runs all K at once, one batched matmul per layer, so K seeds
pay the per-call cost that dominates at these sizes once (PureJaxRL's idea). Replicate k's numbers are its own:
nothing mixes rows, so the gradient of the sum of the replicates' losses is each replicate's own gradient, in its
row, and one :class:`~famarl_cli.core.replicate_adam.ReplicateAdam` steps the rows. ``tests/test_rl.py`` checks that
both paths agree and that K replicates batched compute what each computes alone.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from famarl_cli.core import flat_parameters
from famarl_cli.core.errors import ArtifactError

LOG_SQRT_2PI = 0.5 * math.log(2 * math.pi)


@dataclass
class Heads:
    """The heads on K replicates' batches of B observations; called without the replicate axis (K = 1), its fields
    have none either."""

    mean: torch.Tensor
    """(K, B, action) mean of the Gaussian over the continuous output."""
    log_std: torch.Tensor
    """(K, 1, action) the state-independent log std."""
    value: torch.Tensor
    """(K, B) the critic's estimate."""
    logits: torch.Tensor | None
    """(K, B, choices) the categorical head's logits; None for agents without one."""

    def alone(self) -> Heads:
        """The heads of a single replicate without the replicate axis (mean (B, action), value (B,), ...)."""
        return Heads(self.mean[0], self.log_std[0, 0], self.value[0], None if self.logits is None else self.logits[0])


@dataclass
class Action:
    """What the policy chose for a batch of B observations (numpy)."""

    u: np.ndarray
    """(B, action) the continuous output: sampled, or the Gaussian's mean."""
    index: np.ndarray
    """(B,) the categorical head's choice (0 for agents without one)."""
    logp: np.ndarray | None
    """(B,) log-probability of (u, index); None for the mode."""
    value: np.ndarray
    """(B,) the critic's estimate."""


class ActorCritic:
    """``choices`` options in the categorical head (0: none). ``branches`` (choices, action_size), where given,
    says which Gaussian outputs each choice uses (they may share outputs: the hybrid's residual variant adds its
    primitive output to its macro actions). Without it every choice uses every output (FiGAR). ``replicates``
    independent copies (K) of the network, initialised one after the other from torch's global generator."""

    def __init__(
        self,
        obs_size: int,
        action_size: int,
        choices: int = 0,
        hidden: int = 64,
        branches: np.ndarray | None = None,
        replicates: int = 1,
    ) -> None:
        self.obs_size, self.action_size, self.choices, self.replicates = obs_size, action_size, choices, replicates
        self.branches = None if branches is None else np.asarray(branches, dtype=bool)
        self.branch_mask = None
        if self.branches is not None:
            if self.branches.shape != (choices, action_size):
                raise ValueError(f"branches must be {choices} masks over {action_size} outputs")
            self.branch_mask = torch.from_numpy(self.branches.astype(np.float32))
            # Outputs that the same choices use draw their noise together, in the order of their first output.
            patterns, first = np.unique(self.branches.T, axis=0, return_index=True)
            self.noise_groups = [np.all(self.branches.T == patterns[i], axis=1) for i in np.argsort(first)]
        shapes = {
            "w1": (2, obs_size, hidden),  # [0] the actor's trunk, [1] the critic's
            "b1": (2, 1, hidden),
            "w2": (2, hidden, hidden),
            "b2": (2, 1, hidden),
            "w_mean": (hidden, action_size),
            "b_mean": (action_size,),
            "w_value": (hidden, 1),
            "b_value": (1,),
            "log_std": (action_size,),
        }
        if choices:
            shapes |= {"w_choice": (hidden, choices), "b_choice": (choices,)}
        self.layout = [[name, list(shape)] for name, shape in shapes.items()]
        """[name, shape] of each parameter of one replicate, in the order they lie in its row (stored with it)."""
        k = replicates
        self.shapes = shapes
        self.size = flat_parameters.size(shapes)
        """Values of one replicate."""
        self.flat = torch.zeros(k, self.size)
        """(K, P): row k is replicate k's parameters, what :class:`~famarl_cli.core.replicate_adam.ReplicateAdam`
        steps."""
        # Views of the rows: the leaves that autograd differentiates (K, *shape); the same values as plain tensors
        # to read and edit (their own shape for one replicate); and as numpy arrays for acting.
        self.leaves = {n: v.requires_grad_() for n, v in flat_parameters.views(self.flat, shapes).items()}
        views = flat_parameters.views(self.flat, shapes).items()
        self.params = {n: v[0] if k == 1 else v for n, v in views}
        """Each parameter: its own shape for one replicate, (K, *shape) for several."""
        self.arrays = {n: v.numpy() for n, v in flat_parameters.views(self.flat, shapes).items()}
        for replicate in range(k):
            self.initialise(replicate)

    def initialise(self, replicate: int) -> None:
        """Draw replicate ``replicate``'s initial weights from torch's global generator (orthogonal, CleanRL's gains;
        the biases stay 0), in the order a network of one replicate draws them."""

        def orthogonal(weight: torch.Tensor, gain: float) -> None:
            # Drawn as (out, in) like nn.Linear's weight; ours are stored (in, out).
            weight.copy_(nn.init.orthogonal_(torch.empty(weight.shape[::-1]), gain).T)

        p = self.named(self.flat[replicate])
        for trunk in range(2):
            orthogonal(p["w1"][trunk], math.sqrt(2))
            orthogonal(p["w2"][trunk], math.sqrt(2))
        orthogonal(p["w_value"], 1.0)
        # Small output gains start the policy near its mean of 0 with std 1: for FaMARL, the FAVAE prior.
        orthogonal(p["w_mean"], 0.01)
        if self.choices:
            orthogonal(p["w_choice"], 0.01)

    def named(self, row: torch.Tensor) -> dict[str, torch.Tensor]:
        """A replicate's (P,) values (its parameters, or their gradient) as views, parameter by parameter."""
        return {name: view[0] for name, view in flat_parameters.views(row[None], self.shapes).items()}

    def state_dict(self, replicate: int = 0) -> dict:
        """One replicate's flat parameter vector and its layout (which parameter lies where, with its shape)."""
        return {"flat": self.flat[replicate].clone(), "layout": self.layout}

    def load_state_dict(self, state: dict, replicate: int = 0) -> None:
        flat, layout = state.get("flat"), state.get("layout")
        if not isinstance(flat, torch.Tensor) or flat.shape != (self.size,):
            found = "none" if not isinstance(flat, torch.Tensor) else f"{flat.numel()} values"
            raise ArtifactError(f"the stored policy ({found}) does not fit this network ({self.size} values)")
        # Checkpoints written before the layout was stored have none; their size was checked above.
        if layout is not None and layout != self.layout:
            raise ArtifactError(f"the stored policy's layout {layout} is not this network's {self.layout}")
        # In place: the views in leaves, params and arrays stay valid.
        with torch.no_grad():
            self.flat[replicate] = flat

    @property
    def log_std(self) -> torch.Tensor:
        return self.params["log_std"]

    def act(
        self,
        obs: np.ndarray,
        rng: np.random.Generator | None = None,
        choice_rng: np.random.Generator | None = None,
        base: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> Action:
        """The policy (of one replicate) on (B, obs) float32 observations: a sample drawn with ``rng``, or without
        it the mode (the Gaussian's mean and the likeliest choice).

        ``base`` (mean, log std), each (B, action), is a prior the Gaussian is written relative to
        (:mod:`famarl_cli.rl.prior_guide`): its mean is added to the actor's and its log std to the policy's.

        With branches, the choice is drawn from ``choice_rng`` (``rng`` where not given) and the noise of a
        group of outputs only when some row chose a branch that uses it. A hybrid that always picks one branch
        therefore draws from ``rng`` exactly what the agent with that branch alone draws (``tests/test_hybrid.py``
        relies on it).
        """
        return self.act_replicates(obs[None], [rng], [choice_rng], [base])[0]

    def act_replicates(
        self,
        obs: np.ndarray,
        rngs: list[np.random.Generator | None],
        choice_rngs: list[np.random.Generator | None],
        bases: list[tuple[np.ndarray, np.ndarray] | None],
    ) -> list[Action]:
        """:meth:`act` of every replicate at once: ``obs`` (K, B, obs), replicate k drawing from ``rngs[k]`` and
        ``choice_rngs[k]`` relative to ``bases[k]``; the networks run batched, the draws one replicate at a time."""
        p, batch = self.arrays, obs.shape[1]
        hidden = np.tanh(obs[:, None] @ p["w1"] + p["b1"])  # (K, 2, B, hidden): the actor's trunk, the critic's
        hidden = np.tanh(hidden @ p["w2"] + p["b2"])
        means = hidden[:, 0] @ p["w_mean"] + p["b_mean"][:, None]
        values = (hidden[:, 1] @ p["w_value"])[..., 0] + p["b_value"]
        log_ps = None
        if self.choices:
            logits = hidden[:, 0] @ p["w_choice"] + p["b_choice"][:, None]
            shifted = logits - logits.max(2, keepdims=True)
            log_ps = shifted - np.log(np.exp(shifted).sum(2, keepdims=True))
        actions = []
        for r, (rng, choice_rng, base) in enumerate(zip(rngs, choice_rngs, bases, strict=True)):
            mean, log_std, log_p = means[r], p["log_std"][r], None if log_ps is None else log_ps[r]
            if base is not None:
                mean, log_std = mean + base[0], log_std + base[1]
            actions.append(self._draw_action(mean, values[r], log_p, log_std, batch, rng, choice_rng))
        return actions

    def _draw_action(
        self,
        mean: np.ndarray,
        value: np.ndarray,
        log_p: np.ndarray | None,
        log_std: np.ndarray,
        batch: int,
        rng: np.random.Generator | None,
        choice_rng: np.random.Generator | None,
    ) -> Action:
        if rng is None:
            index = log_p.argmax(1) if log_p is not None else np.zeros(batch, dtype=np.int64)
            return Action(mean, index, None, value)
        if self.branches is not None:
            return self._act_on_branches(mean, value, log_p, rng, choice_rng or rng, log_std)
        noise = rng.standard_normal(mean.shape, dtype=np.float32)
        u = mean + np.exp(log_std) * noise
        logp = -0.5 * np.square(noise).sum(1) - (log_std.sum(-1) + LOG_SQRT_2PI * mean.shape[1])
        if log_p is None:
            return Action(u, np.zeros(batch, dtype=np.int64), logp, value)
        index = self._draw(log_p, rng)
        return Action(u, index, logp + log_p[np.arange(batch), index], value)

    def _draw(self, log_p: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        # Inverse CDF; the minimum guards against a cumulative sum that rounds to just below 1.
        below = np.exp(log_p).cumsum(1) < rng.random((len(log_p), 1), dtype=np.float32)
        return np.minimum(below.sum(1), self.choices - 1)

    def _act_on_branches(
        self,
        mean: np.ndarray,
        value: np.ndarray,
        log_p: np.ndarray,
        rng: np.random.Generator,
        choice_rng: np.random.Generator,
        log_std: np.ndarray,
    ) -> Action:
        index = self._draw(log_p, choice_rng)
        rows = self.branches[index]
        noise = np.zeros_like(mean)
        for columns in self.noise_groups:
            if rows[:, columns].any():
                noise[:, columns] = rng.standard_normal((len(mean), int(columns.sum())), dtype=np.float32)
        noise *= rows
        u = mean + np.exp(log_std) * noise
        per_output = log_std + LOG_SQRT_2PI
        density = rows @ per_output if per_output.ndim == 1 else (rows * per_output).sum(1)
        logp = -0.5 * np.square(noise).sum(1) - density
        return Action(u, index, logp + log_p[np.arange(len(mean)), index], value)

    def __call__(self, obs: torch.Tensor) -> Heads:
        """The heads on (K, B, obs) observations, or on (B, obs) for one replicate (heads without the replicate
        axis), as functions of :attr:`leaves`: a loss of them has its gradient in :meth:`gradient` after
        ``backward()``."""
        if obs.dim() == 2:
            return self(obs[None]).alone()
        p, (k, batch, size) = self.leaves, obs.shape
        hidden = torch.tanh(obs[:, None].expand(k, 2, batch, size) @ p["w1"] + p["b1"])  # the actor's, the critic's
        hidden = torch.tanh(hidden @ p["w2"] + p["b2"])
        actor, critic = hidden.unbind(1)
        mean = torch.baddbmm(p["b_mean"][:, None], actor, p["w_mean"])
        value = torch.baddbmm(p["b_value"][:, None], critic, p["w_value"]).squeeze(2)
        logits = torch.baddbmm(p["b_choice"][:, None], actor, p["w_choice"]) if self.choices else None
        return Heads(mean, p["log_std"][:, None], value, logits)

    def gradient(self) -> torch.Tensor:
        """(K, P) the gradient that ``backward()`` left in :attr:`leaves`, each row in its replicate's layout; the
        leaves are cleared for the next one."""
        found = flat_parameters.gather([leaf.grad for leaf in self.leaves.values()], torch.empty_like(self.flat))
        for leaf in self.leaves.values():
            leaf.grad = None
        return found
