"""Adam (Kingma & Ba 2015) on one flat parameter tensor, with PyTorch's defaults and update rule, and the gradient's
norm clipped by ``torch.nn.utils.clip_grad_norm_``'s rule; both per replicate, for a flat tensor that holds several
networks' parameters (:class:`~famarl_cli.rl.policy.ActorCritic` with ``replicates``).

``torch.optim.Adam`` spends about twice as long in bookkeeping as in arithmetic on the ~10k parameters of a 64-64
actor-critic, once per minibatch; here the step is a few in-place calls on the flat tensor and two multi-tensor
(``torch._foreach_*``) calls for what differs by replicate, whatever their number.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch


@dataclass(frozen=True)
class Rows:
    """Where each replicate's values lie in a flat tensor of several: ``pieces`` (offset, length), each of one
    replicate (``owners``), in the order that replicate's own flat vector concatenates them."""

    pieces: tuple[tuple[int, int], ...]
    owners: tuple[int, ...]
    replicates: int

    @staticmethod
    def single(size: int) -> Rows:
        return Rows(((0, size),), (0,), 1)

    def views(self, flat: torch.Tensor) -> list[torch.Tensor]:
        return [flat[offset : offset + length] for offset, length in self.pieces]

    def row(self, flat: torch.Tensor, replicate: int) -> torch.Tensor:
        """Replicate ``replicate``'s values, as its own flat vector (a copy)."""
        return torch.cat(
            [view for view, owner in zip(self.views(flat), self.owners, strict=True) if owner == replicate]
        )

    def set_row(self, flat: torch.Tensor, replicate: int, values: torch.Tensor) -> None:
        start = 0
        for view, owner in zip(self.views(flat), self.owners, strict=True):
            if owner == replicate:
                view.copy_(values[start : start + len(view)])
                start += len(view)

    def per_piece(self, values) -> list[float]:
        """One number per replicate, spread over its pieces (what the ``torch._foreach_*`` calls take)."""
        return [float(values[owner]) for owner in self.owners]


def clip_norms(pieces: list[torch.Tensor], rows: Rows, max_norm: float) -> None:
    """Scale each replicate's gradient in place (``pieces``: :meth:`Rows.views` of the flat gradient) so that its
    norm is at most ``max_norm``, by clip_grad_norm_'s rule: the factor is max_norm / (norm + 1e-6), applied only when
    below 1."""
    squares = torch.stack(torch._foreach_norm(pieces)).square_()
    owners = torch.tensor(rows.owners)
    norms = torch.zeros(rows.replicates).index_add_(0, owners, squares).sqrt_().add_(1e-6)
    factors = torch.where(norms > max_norm, max_norm / norms, 1.0)
    torch._foreach_mul_(pieces, rows.per_piece(factors.tolist()))


class FlatAdam:
    """One Adam per replicate over a flat tensor: each its own learning rate (:attr:`lr`, set before a step) and
    step count; without ``rows``, the whole tensor is one replicate."""

    def __init__(
        self,
        params: torch.Tensor,
        lr: float,
        betas: tuple[float, float] = (0.9, 0.999),
        eps: float = 1e-8,
        rows: Rows | None = None,
    ) -> None:
        self.params, self.betas, self.eps = params, betas, eps
        self.rows = Rows.single(len(params)) if rows is None else rows
        self.lr = np.full(self.rows.replicates, lr)
        self.steps = np.zeros(self.rows.replicates, dtype=np.int64)
        self.exp_avg = torch.zeros_like(params)
        self.exp_avg_sq = torch.zeros_like(params)
        self._denominator = torch.zeros_like(params)
        self._pieces = [self.rows.views(t) for t in (params, self.exp_avg, self._denominator)]

    def step(self, gradient: torch.Tensor) -> None:
        beta1, beta2 = self.betas
        self.steps += 1
        self.exp_avg.lerp_(gradient, 1 - beta1)
        self.exp_avg_sq.mul_(beta2).addcmul_(gradient, gradient, value=1 - beta2)
        params, exp_avg, denominator = self._pieces
        # torch's Adam, per replicate: p -= lr / (1 - b1^t) * m / (sqrt(v) / sqrt(1 - b2^t) + eps)
        torch.sqrt(self.exp_avg_sq, out=self._denominator)
        torch._foreach_div_(denominator, self.rows.per_piece(np.sqrt(1 - beta2**self.steps)))
        self._denominator.add_(self.eps)
        step_sizes = -self.lr / (1 - beta1**self.steps)
        torch._foreach_addcdiv_(params, exp_avg, denominator, self.rows.per_piece(step_sizes))

    def state_dict(self, replicate: int = 0) -> dict:
        return {
            "lr": float(self.lr[replicate]),
            "steps": int(self.steps[replicate]),
            "exp_avg": self.rows.row(self.exp_avg, replicate),
            "exp_avg_sq": self.rows.row(self.exp_avg_sq, replicate),
        }

    def load_state_dict(self, state: dict, replicate: int = 0) -> None:
        self.lr[replicate], self.steps[replicate] = float(state["lr"]), int(state["steps"])
        self.rows.set_row(self.exp_avg, replicate, state["exp_avg"])
        self.rows.set_row(self.exp_avg_sq, replicate, state["exp_avg_sq"])
