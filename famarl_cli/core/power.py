"""How many replicates a rule over an interval needs to decide, at a given power: the sample size of Colas, Sigaud &
Oudeyer (2018), "How many random seeds? Statistical power analysis in deep reinforcement learning experiments", from
the observed means and spreads.

A rule of :mod:`famarl_cli.report.verdicts` decides where the interval at its level lies wholly on one side of its
threshold: where the side the estimate lies on, one-sided, the test at (1 - level) / 2 of "the mean (or the
difference) is on the other side of the threshold". Its power with n replicates per arm, where the truth lies
``distance`` from the threshold:

- **one arm, or paired differences** (sd of the values, or of the per-replicate differences): the one-sample t test,
  ``P(T' > t_{(1 + level) / 2, n - 1})`` with ``T'`` noncentral t of ``n - 1`` degrees of freedom and noncentrality
  ``distance / (sd / sqrt(n))``: :func:`mean_power`;
- **two arms, unpaired** (each arm's sd; n in each, as Colas et al. plan it): Welch's t test, the same with the
  standard error ``sqrt((sd_a^2 + sd_b^2) / n)`` and the Welch-Satterthwaite degrees of freedom
  ``(n - 1) (sd_a^2 + sd_b^2)^2 / (sd_a^4 + sd_b^4)``: :func:`difference_power`.

The replicates needed are the least n >= 2 at which the power reaches ``power`` (:func:`replicates_for_mean`,
:func:`replicates_for_difference`); where the estimate sits at the threshold no n does (infinite). Where only an
interval of n replicates is known, its half-width implies the spread, ``sd = half sqrt(n) / t_{(1 + level) / 2, n -
1}`` (:func:`spread_from_interval`); where not even n is known, the normal approximation gives the needed replicates
as a multiple of today's, ``(half (z_q + z_power) / (z_q distance))^2`` with ``z_q`` the interval's normal quantile
(:func:`times_today`).

Where the rule's interval is not a t interval of the values, the t plan above is not the rule's: a success rate whose
replicates split into learners and non-learners is judged on a wider interval (a count of learners with each kind's
mean, :func:`~famarl_cli.core.statistics.success_interval`). There the need is found by resampling
(:func:`replicates_by_resampling`): the recorded values taken as the truth (the plug-in, as the t plan takes their
mean and sd), n of them drawn with replacement, the rule's own interval computed, and the power read as the share of
draws whose interval decides on the side the estimate lies on.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from scipy import stats

from famarl_cli.core.statistics import LEVEL

POWER = 0.8
"""The power at which a claim is planned (Colas et al.'s, and the usual one)."""
LIMIT = 10**7
"""The most replicates searched for; beyond it the need is reported as unbounded."""
RESAMPLED_LIMIT = 1000
"""The most replicates :func:`replicates_by_resampling` searches (each try computes the rule's interval on every
draw); beyond it the need is reported as unbounded."""
DRAWS = 1000
"""Draws per n in :func:`replicates_by_resampling`: the power read to within about 0.013 (one standard error at 0.8)."""


def mean_power(n: int, distance: float, sd: float, level: float = LEVEL) -> float:
    """Power of the one-sample t test at one-sided (1 - level) / 2, with ``n`` replicates of spread ``sd``, to show
    a mean ``distance`` from the threshold on its side: :func:`difference_power` with a second arm of no spread
    (its standard error sd / sqrt(n), its degrees of freedom n - 1)."""
    return difference_power(n, distance, sd, 0.0, level)


def difference_power(n: int, distance: float, sd_a: float, sd_b: float, level: float = LEVEL) -> float:
    """Power of Welch's t test at one-sided (1 - level) / 2, with ``n`` replicates in each arm of spreads ``sd_a`` and
    ``sd_b``, to show a difference of means ``distance`` from the threshold on its side."""
    va, vb = sd_a**2, sd_b**2
    if distance <= 0:
        return (1 - level) / 2
    if va + vb <= 0:
        return 1.0
    df = (n - 1) * (va + vb) ** 2 / (va**2 + vb**2)
    critical = stats.t.ppf(0.5 + level / 2, df)
    return float(stats.nct.sf(critical, df, distance / math.sqrt((va + vb) / n)))


def _least(power_at: Callable[[int], float], power: float, limit: int) -> float:
    """The least n in [2, limit] at which ``power_at(n) >= power`` (it grows with n), or inf where none is: n doubled
    until it reaches the power, then halved back (a need far below ``limit`` costs no try near it)."""
    high = 2
    while power_at(high) < power:
        if high >= limit:
            return math.inf
        high = min(2 * high, limit)
    low = high // 2  # power_at(low) < power <= power_at(high), or high is 2
    if high == 2:
        return 2
    while high - low > 1:
        middle = (low + high) // 2
        if power_at(middle) >= power:
            high = middle
        else:
            low = middle
    return high


def replicates_for_mean(
    distance: float, sd: float, level: float = LEVEL, power: float = POWER, limit: int = LIMIT
) -> float:
    """Replicates a one-arm (or paired) rule at ``level`` needs to decide with ``power``, where the mean lies
    ``distance`` from the threshold with spread ``sd``: the least n >= 2 of :func:`mean_power`; inf at the threshold
    (``distance`` 0) or beyond ``limit``."""
    distance = abs(distance)
    if distance == 0 or not math.isfinite(sd):
        return math.inf
    return _least(lambda n: mean_power(n, distance, sd, level), power, limit)


def replicates_for_difference(
    distance: float, sd_a: float, sd_b: float, level: float = LEVEL, power: float = POWER, limit: int = LIMIT
) -> float:
    """Replicates per arm an unpaired difference rule at ``level`` needs to decide with ``power`` (Welch, n in each
    arm), where the difference lies ``distance`` from the threshold and the arms spread ``sd_a`` and ``sd_b``; inf at
    the threshold or beyond ``limit``."""
    distance = abs(distance)
    if distance == 0 or not (math.isfinite(sd_a) and math.isfinite(sd_b)):
        return math.inf
    return _least(lambda n: difference_power(n, distance, sd_a, sd_b, level), power, limit)


def spread_from_interval(half: float, n: int, level: float = LEVEL) -> float:
    """The per-replicate sd a t interval of ``n`` replicates and half-width ``half`` at ``level`` implies."""
    if n < 2:
        return math.inf
    return half * math.sqrt(n) / float(stats.t.ppf(0.5 + level / 2, n - 1))


def times_today(half: float, distance: float, level: float = LEVEL, power: float = POWER) -> float:
    """Where an interval's n is not known: the replicates a rule needs as a multiple of those behind an interval of
    half-width ``half`` (normal approximation: the standard error shrinks as 1 / sqrt(n)); inf at the threshold."""
    distance = abs(distance)
    if distance == 0 or not math.isfinite(half):
        return math.inf
    z = float(stats.norm.ppf(0.5 + level / 2))
    return float((half * (z + stats.norm.ppf(power)) / (z * distance)) ** 2)


def resampled_power(
    values: Sequence[float], n: int, decides: Callable[[np.ndarray], bool], draws: int = DRAWS, seed: int = 0
) -> float:
    """The share of ``draws`` samples of ``n`` replicates, drawn with replacement from ``values``, on which
    ``decides`` (the rule's interval clears its threshold on the estimate's side) holds. The same ``seed`` draws the
    same random numbers at every n, so the power read at neighbouring n differs by n, not by chance."""
    values = np.asarray(values, dtype=float)
    picks = np.random.default_rng(seed).random((draws, n))
    return float(np.mean([decides(values[(row * len(values)).astype(int)]) for row in picks]))


def replicates_by_resampling(
    values: Sequence[float],
    decides: Callable[[np.ndarray], bool],
    power: float = POWER,
    limit: int = RESAMPLED_LIMIT,
    draws: int = DRAWS,
) -> float:
    """Replicates a rule needs to decide with ``power`` where the recorded ``values`` are the truth: the least n >= 2
    at which :func:`resampled_power` reaches ``power``, or inf where none up to ``limit`` does (a truth at the
    threshold, or a rule too wide for any n searched)."""
    return _least(lambda n: resampled_power(values, n, decides, draws), power, limit)
