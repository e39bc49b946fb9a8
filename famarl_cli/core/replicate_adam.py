"""Adam (Kingma & Ba 2015) on K replicates' flat parameters at once, each row its own optimiser.

``params`` is (K, P): row k is replicate k's parameters. Each row has its own step count and moments, and a step
may leave rows out (``active``): a replicate with fewer batches in an epoch than the others waits while they take
their extra step, exactly as if it trained alone. The rows are the parameters of one ``torch.optim.Adam`` with
``fused=True`` (one vectorised pass over each row, where the unfused step makes seven; measured 0.8 ms against 5.7
ms for 5 x 198k values on one thread), so a row follows torch's Adam to the last bit of its fused kernel.
"""

from __future__ import annotations

import torch


class ReplicateAdam:
    def __init__(
        self, params: torch.Tensor, lr: float, betas: tuple[float, float] = (0.9, 0.999), eps: float = 1e-8
    ) -> None:
        self.rows = list(params.detach().unbind(0))
        self.optimiser = torch.optim.Adam(self.rows, lr=lr, betas=betas, eps=eps, fused=True)

    def step(self, gradient: torch.Tensor, active: torch.Tensor | None = None) -> None:
        """One step of every row, or of the rows where the (K,) bool ``active`` is true (torch's Adam skips a
        parameter without a gradient, its step count and moments included)."""
        keep = [True] * len(self.rows) if active is None else active.tolist()
        for param, row, on in zip(self.rows, gradient.unbind(0), keep, strict=True):
            param.grad = row if on else None
        self.optimiser.step()
