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
- :meth:`ActorCritic.__call__` and :meth:`ActorCritic.backward` run a minibatch in torch, the two trunks as one
  batched matmul per layer, with the gradient written out instead of taken by autograd: autograd's engine alone
  took 1.6 ms of a 5 ms PPO minibatch step.

``tests/test_rl.py`` checks that both paths agree and that the written-out gradient equals autograd's. Every
parameter is a view into one flat tensor, and every gradient a view into one flat gradient, so clipping the
gradient norm and the Adam step are a handful of calls whatever the layout.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from famarl_cli.core.errors import ArtifactError

LOG_SQRT_2PI = 0.5 * math.log(2 * math.pi)
ONE, MINUS_ONE = torch.tensor(1.0), torch.tensor(-1.0)


def tanh_layer(bias: torch.Tensor, inputs: torch.Tensor, weight: torch.Tensor) -> torch.Tensor:
    """tanh(inputs @ weight + bias) for both trunks at once, (2, B, in) -> (2, B, out).

    Written as 2 sigmoid(2 a) - 1 with the doubling folded into the matmul: on CPU torch's sigmoid is about three
    times as fast as its tanh at a minibatch's size, and the tanh was the largest single cost of a PPO step.
    """
    doubled = torch.baddbmm(bias, inputs, weight, beta=2, alpha=2)
    return torch.add(MINUS_ONE, torch.sigmoid_(doubled), alpha=2, out=doubled)


@dataclass
class Heads:
    """One forward pass over a batch of B observations: the heads the loss reads and the activations that
    :meth:`ActorCritic.backward` needs."""

    obs: torch.Tensor
    """(B, obs) the (normalised) observations."""
    hidden1: torch.Tensor
    """(2, B, hidden) tanh activations of the first layer: [0] actor, [1] critic."""
    hidden2: torch.Tensor
    """(2, B, hidden) tanh activations of the second layer."""
    mean: torch.Tensor
    """(B, action) mean of the Gaussian over the continuous output."""
    value: torch.Tensor
    """(B,) the critic's estimate."""
    logits: torch.Tensor | None
    """(B, choices) the categorical head's logits; None for agents without one."""


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
    primitive output to its macro actions). Without it every choice uses every output (FiGAR)."""

    def __init__(
        self,
        obs_size: int,
        action_size: int,
        choices: int = 0,
        hidden: int = 64,
        branches: np.ndarray | None = None,
    ) -> None:
        self.choices = choices
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
            "w1": (2, obs_size, hidden),
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
        """[name, shape] of each parameter, in the order they lie in :attr:`flat` (stored with it)."""
        size = sum(math.prod(shape) for shape in shapes.values())
        self.flat, self.gradient = torch.zeros(size), torch.zeros(size)
        self.params = self._views(self.flat, shapes)
        self.grads = self._views(self.gradient, shapes)
        self.arrays = {name: view.numpy() for name, view in self.params.items()}
        self._initialise()

    @staticmethod
    def _views(buffer: torch.Tensor, shapes: dict[str, tuple[int, ...]]) -> dict[str, torch.Tensor]:
        views, offset = {}, 0
        for name, shape in shapes.items():
            views[name] = buffer[offset : offset + math.prod(shape)].view(shape)
            offset += math.prod(shape)
        return views

    def _initialise(self) -> None:
        def orthogonal(weight: torch.Tensor, gain: float) -> None:
            # Drawn as (out, in) like nn.Linear's weight; ours are stored (in, out).
            weight.copy_(nn.init.orthogonal_(torch.empty(weight.shape[::-1]), gain).T)

        p = self.params
        for trunk in range(2):
            orthogonal(p["w1"][trunk], math.sqrt(2))
            orthogonal(p["w2"][trunk], math.sqrt(2))
        orthogonal(p["w_value"], 1.0)
        # Small output gains start the policy near its mean of 0 with std 1: for FaMARL, the FAVAE prior.
        orthogonal(p["w_mean"], 0.01)
        if self.choices:
            orthogonal(p["w_choice"], 0.01)

    def state_dict(self) -> dict:
        """The flat parameter vector and its layout (which parameter lies where, with its shape)."""
        return {"flat": self.flat.clone(), "layout": self.layout}

    def load_state_dict(self, state: dict) -> None:
        flat, layout = state.get("flat"), state.get("layout")
        if not isinstance(flat, torch.Tensor) or flat.shape != self.flat.shape:
            found = "none" if not isinstance(flat, torch.Tensor) else f"{flat.numel()} values"
            raise ArtifactError(f"the stored policy ({found}) does not fit this network ({self.flat.numel()} values)")
        # Checkpoints written before the layout was stored have none; their size was checked above.
        if layout is not None and layout != self.layout:
            raise ArtifactError(f"the stored policy's layout {layout} is not this network's {self.layout}")
        # In place: the views in params, grads and arrays stay valid.
        self.flat.copy_(flat)

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
        """The policy on (B, obs) float32 observations: a sample drawn with ``rng``, or without it the mode (the
        Gaussian's mean and the likeliest choice).

        ``base`` (mean, log std), each (B, action), is a prior the Gaussian is written relative to
        (:mod:`famarl_cli.rl.prior_guide`): its mean is added to the actor's and its log std to the policy's.

        With branches, the choice is drawn from ``choice_rng`` (``rng`` where not given) and the noise of a
        group of outputs only when some row chose a branch that uses it. A hybrid that always picks one branch
        therefore draws from ``rng`` exactly what the agent with that branch alone draws (``tests/test_hybrid.py``
        relies on it).
        """
        p = self.arrays
        hidden = np.tanh(obs @ p["w1"] + p["b1"])
        hidden = np.tanh(hidden @ p["w2"] + p["b2"])
        mean = hidden[0] @ p["w_mean"] + p["b_mean"]
        value = hidden[1] @ p["w_value"][:, 0] + p["b_value"]
        log_p = None
        if self.choices:
            logits = hidden[0] @ p["w_choice"] + p["b_choice"]
            shifted = logits - logits.max(1, keepdims=True)
            log_p = shifted - np.log(np.exp(shifted).sum(1, keepdims=True))
        log_std = p["log_std"]
        if base is not None:
            mean, log_std = mean + base[0], log_std + base[1]
        if rng is None:
            index = log_p.argmax(1) if log_p is not None else np.zeros(len(obs), dtype=np.int64)
            return Action(mean, index, None, value)
        if self.branches is not None:
            return self._act_on_branches(mean, value, log_p, rng, choice_rng or rng, log_std)
        noise = rng.standard_normal(mean.shape, dtype=np.float32)
        u = mean + np.exp(log_std) * noise
        logp = -0.5 * np.square(noise).sum(1) - (log_std.sum(-1) + LOG_SQRT_2PI * mean.shape[1])
        if log_p is None:
            return Action(u, np.zeros(len(obs), dtype=np.int64), logp, value)
        index = self._draw(log_p, rng)
        return Action(u, index, logp + log_p[np.arange(len(obs)), index], value)

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
        p = self.params
        hidden1 = tanh_layer(p["b1"], obs.expand(2, -1, -1), p["w1"])
        hidden2 = tanh_layer(p["b2"], hidden1, p["w2"])
        mean = torch.addmm(p["b_mean"], hidden2[0], p["w_mean"])
        value = torch.addmm(p["b_value"], hidden2[1], p["w_value"]).squeeze(1)
        logits = torch.addmm(p["b_choice"], hidden2[0], p["w_choice"]) if self.choices else None
        return Heads(obs, hidden1, hidden2, mean, value, logits)

    def backward(
        self,
        heads: Heads,
        d_mean: torch.Tensor,
        d_log_std: torch.Tensor,
        d_value: torch.Tensor,
        d_logits: torch.Tensor | None = None,
    ) -> None:
        """Writes into ``gradient`` the gradient of a loss whose gradients with respect to the heads are given:
        ``d_mean`` (B, action), ``d_log_std`` (action,), ``d_value`` (B,), ``d_logits`` (B, choices)."""
        p, g = self.params, self.grads
        actor, critic = heads.hidden2.unbind()
        torch.mm(actor.T, d_mean, out=g["w_mean"])
        torch.sum(d_mean, 0, out=g["b_mean"])
        torch.mv(critic.T, d_value, out=g["w_value"].view(-1))
        torch.sum(d_value, 0, keepdim=True, out=g["b_value"])
        g["log_std"].copy_(d_log_std)
        d_hidden2 = torch.empty_like(heads.hidden2)
        torch.mm(d_mean, p["w_mean"].T, out=d_hidden2[0])
        if d_logits is not None:
            torch.mm(actor.T, d_logits, out=g["w_choice"])
            torch.sum(d_logits, 0, out=g["b_choice"])
            d_hidden2[0].addmm_(d_logits, p["w_choice"].T)
        torch.outer(d_value, p["w_value"].view(-1), out=d_hidden2[1])
        d_pre2 = d_hidden2.mul_(torch.addcmul(ONE, heads.hidden2, heads.hidden2, value=-1))  # tanh' = 1 - tanh^2
        torch.bmm(heads.hidden1.transpose(1, 2), d_pre2, out=g["w2"])
        torch.sum(d_pre2, 1, keepdim=True, out=g["b2"])
        d_pre1 = torch.bmm(d_pre2, p["w2"].transpose(1, 2)).mul_(
            torch.addcmul(ONE, heads.hidden1, heads.hidden1, value=-1)
        )
        torch.matmul(heads.obs.T, d_pre1, out=g["w1"])
        torch.sum(d_pre1, 1, keepdim=True, out=g["b1"])
