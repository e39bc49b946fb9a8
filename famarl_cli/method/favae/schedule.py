"""The progressive schedule, torch-free: each ladder's weight per epoch, and which epochs of the C_last pre-run
give C_last. (Progressive training follows pro-VLAE, Li et al. 2020: :mod:`~famarl_cli.method.favae.training`.)"""

from __future__ import annotations

import math

FADE_SHARE = 0.25
"""Share of a progressive stage over which its new ladder fades in (its weight rising from 0 to 1)."""


def ladder_weights(epoch: int, epochs: int, ladders: int, progressive: float) -> list[float]:
    """The weight of each ladder's latent in the decoder at ``epoch`` (0-based), shallowest first.

    The deepest ladder is always in. With ``progressive`` p > 0 the first p of the epochs are split into
    ``ladders - 1`` equal stages: the deepest trains alone in the first, and at the end of each stage the next
    ladder, counted from the deepest, begins to fade in, its weight rising linearly from 0 to 1 over
    :data:`FADE_SHARE` of a stage. Ladder l < ladders enters at epoch ``p * epochs * (ladders - l) / (ladders - 1)``,
    so the shallowest enters at p * epochs. p = 0: all weights 1 from the start.
    """
    if progressive <= 0 or ladders == 1:
        return [1.0] * ladders
    stage = progressive * epochs / (ladders - 1)
    fade = max(FADE_SHARE * stage, 1.0)
    starts = [stage * (ladders - ladder) for ladder in range(1, ladders)] + [-fade]
    return [min(max((epoch + 1 - start) / fade, 0.0), 1.0) for start in starts]


def pre_run_window(share: float, epochs: int, ladders: int, progressive: float) -> range:
    """The epochs of the C_last pre-run whose mean is C_last. The pre-run is the first ``share`` of the fit's
    schedule (:func:`ladder_weights` over ``epochs``, so its ladders enter when they enter in the fit), and at least
    every epoch until its last ladder is fully in (weight 1) and one more; the window is its last third, from the
    epoch every ladder is in at the earliest."""
    settled = next(
        (e for e in range(epochs) if min(ladder_weights(e, epochs, ladders, progressive)) == 1.0), epochs - 1
    )
    stop = min(epochs, max(math.ceil(share * epochs), settled + 1))
    return range(max(settled, stop - math.ceil(stop / 3)), stop)
