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

A network holds ``replicates`` copies (K), one per seed of a batch of runs (:class:`~famarl_cli.rl.ppo.PPOTrainer`):
every parameter has a leading replicate axis and every call of either path runs all K at once, one batched matmul
per layer, so K seeds pay the per-call cost that dominates at these sizes once (PureJaxRL's idea). Replicate k's
numbers are its own: nothing mixes rows. With K = 1, :attr:`params` and :attr:`grads` have each parameter's own
shape, and the batch axis may be left out of the calls.

``tests/test_rl.py`` checks that both paths agree, that the written-out gradient equals autograd's, and that K
replicates batched compute what each computes alone. Every parameter is a view into one flat tensor (parameter by
parameter, each holding its K replicates in turn), and every gradient a view into one flat gradient, so clipping the
gradient norm and the Adam step are a handful of calls whatever the layout; :attr:`ActorCritic.rows` says where each
replicate's values lie.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from famarl_cli.core.errors import ArtifactError
from famarl_cli.rl.optimizer import Rows

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
    """One forward pass over K replicates' batches of B observations: the heads the loss reads and the activations
    that :meth:`ActorCritic.backward` needs. Called without the replicate axis (K = 1), its fields have none either."""

    obs: torch.Tensor
    """(K, B, obs) the (normalised) observations."""
    hidden1: torch.Tensor
    """(2K, B, hidden) tanh activations of the first layer: [2k] replicate k's actor, [2k + 1] its critic."""
    hidden2: torch.Tensor
    """(2K, B, hidden) tanh activations of the second layer."""
    mean: torch.Tensor
    """(K, B, action) mean of the Gaussian over the continuous output."""
    value: torch.Tensor
    """(K, B) the critic's estimate."""
    logits: torch.Tensor | None
    """(K, B, choices) the categorical head's logits; None for agents without one."""

    def alone(self) -> Heads:
        """The heads of a single replicate without the replicate axis (mean (B, action), value (B,), ...)."""
        return Heads(
            self.obs[0],
            self.hidden1,
            self.hidden2,
            self.mean[0],
            self.value[0],
            None if self.logits is None else self.logits[0],
        )


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
        self.choices, self.replicates = choices, replicates
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
        """[name, shape] of each parameter of one replicate, in the order they lie in its row (stored with it)."""
        k = replicates
        sizes = [math.prod(shape) for shape in shapes.values()]
        self.size = sum(sizes)
        """Values of one replicate."""
        self.flat, self.gradient = torch.zeros(k * self.size), torch.zeros(k * self.size)
        # The shapes the batched paths compute with: both trunks of every replicate along one batch axis, the heads'
        # biases with a row axis to broadcast over.
        batched = {
            "w1": (2 * k, obs_size, hidden),
            "b1": (2 * k, 1, hidden),
            "w2": (2 * k, hidden, hidden),
            "b2": (2 * k, 1, hidden),
            "w_mean": (k, hidden, action_size),
            "b_mean": (k, 1, action_size),
            "w_value": (k, hidden, 1),
            "b_value": (k, 1, 1),
            "log_std": (k, 1, action_size),
        }
        if choices:
            batched |= {"w_choice": (k, hidden, choices), "b_choice": (k, 1, choices)}
        own = {name: (shape if k == 1 else (k, *shape)) for name, shape in shapes.items()}
        self.batched = self._views(self.flat, batched)
        self.batched_grads = self._views(self.gradient, batched)
        self.params = self._views(self.flat, own)
        """Each parameter: its own shape for one replicate, (K, *shape) for several."""
        self.grads = self._views(self.gradient, own)
        self.arrays = {name: view.numpy() for name, view in self.batched.items()}
        offsets = np.cumsum([0, *[k * n for n in sizes[:-1]]])
        self.rows = Rows(
            tuple((int(o) + r * n, n) for o, n in zip(offsets, sizes, strict=True) for r in range(k)),
            tuple(r for _ in sizes for r in range(k)),
            k,
        )
        """Where each replicate's values lie in :attr:`flat` (and in the gradient and Adam's moments)."""
        self.gradient_pieces = self.rows.views(self.gradient)
        for replicate in range(k):
            self.initialise(replicate)

    @staticmethod
    def _views(buffer: torch.Tensor, shapes: dict[str, tuple[int, ...]]) -> dict[str, torch.Tensor]:
        views, offset = {}, 0
        for name, shape in shapes.items():
            views[name] = buffer[offset : offset + math.prod(shape)].view(shape)
            offset += math.prod(shape)
        return views

    def initialise(self, replicate: int) -> None:
        """Draw replicate ``replicate``'s initial weights from torch's global generator (orthogonal, CleanRL's gains;
        the biases stay 0), in the order a network of one replicate draws them."""

        def orthogonal(name: str, index: int, gain: float) -> None:
            weight = self.batched[name][index]
            # Drawn as (out, in) like nn.Linear's weight; ours are stored (in, out).
            weight.copy_(nn.init.orthogonal_(torch.empty(weight.shape[::-1]), gain).T)

        k = replicate
        for trunk in range(2):
            orthogonal("w1", 2 * k + trunk, math.sqrt(2))
            orthogonal("w2", 2 * k + trunk, math.sqrt(2))
        orthogonal("w_value", k, 1.0)
        # Small output gains start the policy near its mean of 0 with std 1: for FaMARL, the FAVAE prior.
        orthogonal("w_mean", k, 0.01)
        if self.choices:
            orthogonal("w_choice", k, 0.01)

    def state_dict(self, replicate: int = 0) -> dict:
        """One replicate's flat parameter vector and its layout (which parameter lies where, with its shape)."""
        return {"flat": self.rows.row(self.flat, replicate), "layout": self.layout}

    def load_state_dict(self, state: dict, replicate: int = 0) -> None:
        flat, layout = state.get("flat"), state.get("layout")
        if not isinstance(flat, torch.Tensor) or flat.shape != (self.size,):
            found = "none" if not isinstance(flat, torch.Tensor) else f"{flat.numel()} values"
            raise ArtifactError(f"the stored policy ({found}) does not fit this network ({self.size} values)")
        # Checkpoints written before the layout was stored have none; their size was checked above.
        if layout is not None and layout != self.layout:
            raise ArtifactError(f"the stored policy's layout {layout} is not this network's {self.layout}")
        # In place: the views in params, grads and arrays stay valid.
        self.rows.set_row(self.flat, replicate, flat)

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
        p, k, batch = self.arrays, self.replicates, obs.shape[1]
        hidden = np.tanh(obs[:, None] @ p["w1"].reshape(k, 2, *p["w1"].shape[1:]) + p["b1"].reshape(k, 2, 1, -1))
        hidden = np.tanh(hidden @ p["w2"].reshape(k, 2, *p["w2"].shape[1:]) + p["b2"].reshape(k, 2, 1, -1))
        means = hidden[:, 0] @ p["w_mean"] + p["b_mean"]
        values = (hidden[:, 1] @ p["w_value"])[..., 0] + p["b_value"][..., 0]
        log_ps = None
        if self.choices:
            logits = hidden[:, 0] @ p["w_choice"] + p["b_choice"]
            shifted = logits - logits.max(2, keepdims=True)
            log_ps = shifted - np.log(np.exp(shifted).sum(2, keepdims=True))
        actions = []
        for r, (rng, choice_rng, base) in enumerate(zip(rngs, choice_rngs, bases, strict=True)):
            mean, log_std, log_p = means[r], p["log_std"][r, 0], None if log_ps is None else log_ps[r]
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
        axis)."""
        if obs.dim() == 2:
            return self.forward(obs[None]).alone()
        return self.forward(obs)

    def forward(self, obs: torch.Tensor) -> Heads:
        p, k, batch = self.batched, self.replicates, obs.shape[1]
        trunks = obs[:, None].expand(k, 2, batch, obs.shape[2]).reshape(2 * k, batch, obs.shape[2])
        hidden1 = tanh_layer(p["b1"], trunks, p["w1"])
        hidden2 = tanh_layer(p["b2"], hidden1, p["w2"])
        actor, critic = hidden2[0::2], hidden2[1::2]
        mean = torch.baddbmm(p["b_mean"], actor, p["w_mean"])
        value = torch.baddbmm(p["b_value"], critic, p["w_value"]).squeeze(2)
        logits = torch.baddbmm(p["b_choice"], actor, p["w_choice"]) if self.choices else None
        return Heads(obs, hidden1, hidden2, mean, value, logits)

    def backward(
        self,
        heads: Heads,
        d_mean: torch.Tensor,
        d_log_std: torch.Tensor,
        d_value: torch.Tensor,
        d_logits: torch.Tensor | None = None,
    ) -> None:
        """Writes into ``gradient`` the gradient of a loss whose gradients with respect to the heads are given, for
        K replicates at once: ``d_mean`` (K, B, action), ``d_log_std`` (K, action), ``d_value`` (K, B),
        ``d_logits`` (K, B, choices); ``heads`` from :meth:`forward`."""
        p, g = self.batched, self.batched_grads
        actor, critic = heads.hidden2[0::2], heads.hidden2[1::2]
        torch.bmm(actor.transpose(1, 2), d_mean, out=g["w_mean"])
        torch.sum(d_mean, 1, keepdim=True, out=g["b_mean"])
        torch.bmm(critic.transpose(1, 2), d_value[..., None], out=g["w_value"])
        torch.sum(d_value[..., None], 1, keepdim=True, out=g["b_value"])
        g["log_std"].copy_(d_log_std[:, None])
        d_actor = torch.bmm(d_mean, p["w_mean"].transpose(1, 2))
        if d_logits is not None:
            torch.bmm(actor.transpose(1, 2), d_logits, out=g["w_choice"])
            torch.sum(d_logits, 1, keepdim=True, out=g["b_choice"])
            d_actor.baddbmm_(d_logits, p["w_choice"].transpose(1, 2))
        d_critic = d_value[..., None] * p["w_value"].transpose(1, 2)
        d_hidden2 = torch.stack((d_actor, d_critic), 1).view_as(heads.hidden2)
        d_pre2 = d_hidden2.mul_(torch.addcmul(ONE, heads.hidden2, heads.hidden2, value=-1))  # tanh' = 1 - tanh^2
        torch.bmm(heads.hidden1.transpose(1, 2), d_pre2, out=g["w2"])
        torch.sum(d_pre2, 1, keepdim=True, out=g["b2"])
        d_pre1 = torch.bmm(d_pre2, p["w2"].transpose(1, 2)).mul_(
            torch.addcmul(ONE, heads.hidden1, heads.hidden1, value=-1)
        )
        k, batch = heads.obs.shape[:2]
        w1 = g["w1"].view(k, 2, *g["w1"].shape[1:])
        torch.matmul(heads.obs.transpose(1, 2)[:, None], d_pre1.view(k, 2, batch, -1), out=w1)
        torch.sum(d_pre1, 1, keepdim=True, out=g["b1"])
