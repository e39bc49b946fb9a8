"""The actor-critic: separate 64-64 tanh networks, orthogonal initialisation, a state-independent log std,
and for FiGAR a categorical head over repeat counts on the actor's features (CleanRL's layout).

The two trunks run as one batched matmul per layer, and the gradient is written out (:meth:`ActorCritic.backward`)
instead of taken by autograd. On networks this small every torch call costs more than its arithmetic, and
autograd's engine alone took 1.6 ms of a 5 ms PPO minibatch step; the written-out pass is checked against
autograd in ``tests/test_rl.py``. Every parameter is a view into one flat tensor, and every gradient a view into
one flat gradient, so clipping the gradient norm and the Adam step are a handful of calls whatever the layout.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch import nn

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
    """(B, repeat choices) FiGAR's repeat-count logits; None for the other agents."""


class ActorCritic(nn.Module):
    def __init__(self, obs_size: int, action_size: int, repeat_choices: int = 0, hidden: int = 64) -> None:
        super().__init__()
        self.repeat_choices = repeat_choices
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
        if repeat_choices:
            shapes |= {"w_repeat": (hidden, repeat_choices), "b_repeat": (repeat_choices,)}
        size = sum(math.prod(shape) for shape in shapes.values())
        # requires_grad=False: no autograd graph is ever built; backward() fills flat.grad itself.
        self.flat = nn.Parameter(torch.zeros(size), requires_grad=False)
        self.flat.grad = torch.zeros(size)
        self.params = self._views(self.flat, shapes)
        self.grads = self._views(self.flat.grad, shapes)
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
        if self.repeat_choices:
            orthogonal(p["w_repeat"], 0.01)

    @property
    def log_std(self) -> torch.Tensor:
        return self.params["log_std"]

    def forward(self, obs: torch.Tensor) -> Heads:
        p = self.params
        hidden1 = tanh_layer(p["b1"], obs.expand(2, -1, -1), p["w1"])
        hidden2 = tanh_layer(p["b2"], hidden1, p["w2"])
        mean = torch.addmm(p["b_mean"], hidden2[0], p["w_mean"])
        value = torch.addmm(p["b_value"], hidden2[1], p["w_value"]).squeeze(1)
        logits = torch.addmm(p["b_repeat"], hidden2[0], p["w_repeat"]) if self.repeat_choices else None
        return Heads(obs, hidden1, hidden2, mean, value, logits)

    def value(self, obs: torch.Tensor) -> torch.Tensor:
        p = self.params
        hidden1 = torch.addmm(p["b1"][1], obs, p["w1"][1]).tanh_()
        hidden2 = torch.addmm(p["b2"][1], hidden1, p["w2"][1]).tanh_()
        return torch.addmm(p["b_value"], hidden2, p["w_value"]).squeeze(1)

    def sample(self, heads: Heads) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Draws ``(u, index, log_prob)``: u ~ N(mean, std), the repeat index from its categorical (0 without)."""
        noise = torch.randn_like(heads.mean)
        u = heads.mean + self.log_std.exp() * noise
        logp = (-0.5 * noise.square() - self.log_std - LOG_SQRT_2PI).sum(1)
        if heads.logits is None:
            return u, torch.zeros(len(u), dtype=torch.long), logp
        index = torch.multinomial(heads.logits.softmax(1), 1).squeeze(1)
        return u, index, logp + heads.logits.log_softmax(1).gather(1, index[:, None]).squeeze(1)

    @staticmethod
    def mode(heads: Heads) -> tuple[torch.Tensor, torch.Tensor]:
        """The most likely output: the Gaussian's mean and the likeliest repeat index."""
        if heads.logits is None:
            return heads.mean, torch.zeros(len(heads.mean), dtype=torch.long)
        return heads.mean, heads.logits.argmax(1)

    def backward(
        self,
        heads: Heads,
        d_mean: torch.Tensor,
        d_log_std: torch.Tensor,
        d_value: torch.Tensor,
        d_logits: torch.Tensor | None = None,
    ) -> None:
        """Writes into ``flat.grad`` the gradient of a loss whose gradients with respect to the heads are given:
        ``d_mean`` (B, action), ``d_log_std`` (action,), ``d_value`` (B,), ``d_logits`` (B, repeat choices)."""
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
            torch.mm(actor.T, d_logits, out=g["w_repeat"])
            torch.sum(d_logits, 0, out=g["b_repeat"])
            d_hidden2[0].addmm_(d_logits, p["w_repeat"].T)
        torch.outer(d_value, p["w_value"].view(-1), out=d_hidden2[1])
        d_pre2 = d_hidden2.mul_(torch.addcmul(ONE, heads.hidden2, heads.hidden2, value=-1))  # tanh' = 1 - tanh^2
        torch.bmm(heads.hidden1.transpose(1, 2), d_pre2, out=g["w2"])
        torch.sum(d_pre2, 1, keepdim=True, out=g["b2"])
        d_pre1 = torch.bmm(d_pre2, p["w2"].transpose(1, 2)).mul_(
            torch.addcmul(ONE, heads.hidden1, heads.hidden1, value=-1)
        )
        torch.matmul(heads.obs.T, d_pre1, out=g["w1"])
        torch.sum(d_pre1, 1, keepdim=True, out=g["b1"])
