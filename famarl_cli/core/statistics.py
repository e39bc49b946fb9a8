"""Intervals and aggregates over seeds: what every verdict of the report (:mod:`famarl_cli.report.verdicts`) is
judged on.

- :func:`mean_interval` and :func:`difference_interval`: Student and Welch t intervals of one mean and of a
  difference of means, over per-seed values. For success rates, each arm's variance is floored at the
  evaluation's binomial noise, ``p (1 - p) / K`` with ``p = (successes + 1/2) / (n K + 1)`` over its n seeds of K
  episodes each: without the floor, seeds that all score 1.00 give an interval of zero width.
  :func:`paired_difference_interval`: the t interval of the mean of per-replicate differences, where two arms share
  their replicates (the same seed's runs, evaluated on the same layouts); its variance floored, for rates, at the
  two arms' binomial noise together.
- :func:`censored_difference` and :func:`censored_ratio`: how much sooner one arm reaches a threshold than another
  (or how many times as long it takes), where a run that has not reached it by the budget is censored (its time is
  known only to be the budget or more), by medians with a bootstrap interval bounded both ways.
  :func:`ratio_interval`: a bootstrap interval of a ratio of means (one agent's cost or speed over another's).
- :func:`aggregate_interval`, :func:`iqm`, :func:`probability_of_improvement`, :func:`performance_profile`:
  aggregates over several tasks as rliable computes them (Agarwal et al. 2021), with the stratified bootstrap
  (each task's runs resampled on their own) and percentile intervals. rliable itself does not import with numpy 2,
  so this is numpy and scipy.
- :func:`success_interval`: the t interval where every replicate learned, an exact count of learners combined with
  each kind's level where some did not (a t interval over a mixture of learners and non-learners under-covers).
- :func:`normalised_auc` and :func:`steps_to_threshold` (the first step from which a level is held for a window of
  env steps): sample efficiency of a learning curve.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy import stats

LEVEL = 0.95
BOOTSTRAP_RESAMPLES = 2000
THRESHOLD = 0.5
"""The training success whose holding counts as learned, for :func:`steps_to_threshold`: half of success, a level
the learning curves of an agent that learns cross on their rise, well below any plateau that counts as learned (the
0.8 of before sat near the plateaus, where the time to it measured the plateau's height, not the speed)."""
HOLD = 0.05
"""How long, as a share of the budget, the curve must stay at or above the level to count as having reached it:
a spike is not learning, and a window in env steps (not in logged updates) is the same whatever the curve's
resolution."""
SMOOTHING = 0.02
"""The span, as a share of the budget, of the trailing mean the training success is smoothed with before the level
is looked for: one interval of the 50-point curves the pipelines commit, so a full curve smoothed and a 50-point
one read alike."""
SPLIT = 0.5
"""The per-replicate success that separates a learning replicate from one that did not learn, for
:func:`success_interval`."""


@dataclass(frozen=True)
class Interval:
    estimate: float
    low: float
    high: float
    level: float = LEVEL

    def within(self, bounds: tuple[float, float] | None) -> Interval:
        """Cut to the quantity's range (a rate's [0, 1]): a t interval does not know it, and cutting keeps its
        coverage."""
        if bounds is None:
            return self
        return Interval(self.estimate, max(self.low, bounds[0]), min(self.high, bounds[1]), self.level)

    def text(self, fmt: str = "{:.2f}") -> str:
        """``estimate [low, high]``, and the level where it is not :data:`LEVEL` (a Bonferroni share of it, say), so
        that no interval is read at a level it does not have."""
        level = "" if round(self.level, 6) == LEVEL else f" ({100 * self.level:.4g}%)"
        return f"{fmt.format(self.estimate)} [{fmt.format(self.low)}, {fmt.format(self.high)}]{level}"


def proportion_interval(successes: int, episodes: int, level: float = LEVEL) -> Interval:
    """Wilson score interval of a success rate over ``episodes`` independent episodes of one fixed policy (a
    scripted controller): the episodes, not seeds, are its replicates. Unlike the normal approximation it stays
    inside [0, 1] and is not empty at 0 or ``episodes`` successes."""
    if episodes < 1 or not 0 <= successes <= episodes:
        raise ValueError(f"{successes} successes in {episodes} episodes")
    ci = stats.binomtest(successes, episodes).proportion_ci(confidence_level=level, method="wilson")
    return Interval(successes / episodes, float(ci.low), float(ci.high), level)


def floored_variance(values: Sequence[float], episodes: int | None = None) -> float:
    """Sample variance of per-seed values; for success rates over ``episodes`` evaluation episodes each, at least
    the binomial variance of one seed's rate."""
    values = np.asarray(values, dtype=float)
    variance = float(values.var(ddof=1)) if len(values) > 1 else 0.0
    if episodes:
        n = len(values)
        p = (values.sum() * episodes + 0.5) / (n * episodes + 1)
        variance = max(variance, p * (1 - p) / episodes)
    return variance


RATE = (0.0, 1.0)
"""The range of a success rate (and of other shares: AUC, MIG, F1)."""


def mean_interval(
    values: Sequence[float], episodes: int | None = None, level: float = LEVEL, bounds: tuple | None = None
) -> Interval:
    """Interval of the mean over seeds. For success rates (``episodes`` given) :func:`success_interval`; else the
    Student t interval, cut to ``bounds``. One seed gives an unbounded interval: nothing is known of the spread."""
    if episodes:
        return success_interval(values, episodes, level)
    return _t_interval(values, None, level, bounds)


def _t_interval(values: Sequence[float], episodes: int | None, level: float, bounds: tuple | None) -> Interval:
    """Student t interval of the mean (variance floored at the binomial noise for rates over ``episodes``)."""
    values = np.asarray(values, dtype=float)
    mean = float(values.mean())
    bounds = bounds or (RATE if episodes else None)
    if len(values) < 2:
        return Interval(mean, -np.inf, np.inf, level).within(bounds)
    half = stats.t.ppf(0.5 + level / 2, len(values) - 1) * np.sqrt(floored_variance(values, episodes) / len(values))
    return Interval(mean, mean - half, mean + half, level).within(bounds)


def success_interval(values: Sequence[float], episodes: int, level: float = LEVEL, split: float = SPLIT) -> Interval:
    """Interval of the mean success rate over replicates, each a rate over ``episodes`` episodes.

    Where every replicate learned (each above ``split``) the replicates are alike and the t interval with the
    binomial floor covers (benchmarks/interval_coverage.py). Where some did not, the replicates are a mixture of
    learners and non-learners, and a t interval over a few of them under-covers badly: ten replicates at zero give
    0 [0, 0] though a quarter of the replicates there could be could learn. Then the mean is written as
    pi mu_L + (1 - pi) mu_N, pi the share of replicates that learn (above ``split``), mu_L and mu_N the mean success
    of each kind, and bounded by a Clopper-Pearson interval for pi on the count of learners (exact: the count is
    binomial, whatever the replicates' distribution) at level 1 - alpha/2, and a t interval of each kind's mean at
    1 - alpha/4 (floored, and cut to its side of ``split``; a kind with fewer than two replicates only to its side),
    Bonferroni over the three: the interval's ends are the mean's least and greatest over the three intervals. It
    is wide where little is known (ten replicates at zero over 100 episodes: 0 [0, 0.36]), and tested for coverage at
    n = 5 and 10 with 0 to 50% learners (docs/verdicts.md, "Coverage")."""
    values = np.asarray(values, dtype=float)
    n, learners = len(values), values > split
    k = int(learners.sum())
    if episodes == 1 and n > 1:  # each replicate one success or failure: its count is binomial, the interval exact
        return Interval(k / n, *_clopper_pearson(int(values.sum()), n, level), level)
    if k == n or n < 2:
        return _t_interval(values, episodes, level, RATE)
    alpha = 1 - level
    count = _clopper_pearson(k, n, 1 - alpha / 2)

    def part(kind: np.ndarray, side: tuple[float, float]) -> tuple[float, float]:
        if len(kind) < 2:
            return side
        inner = _t_interval(kind, episodes, 1 - alpha / 4, side)
        return inner.low, inner.high

    learned, unlearned = part(values[learners], (split, 1.0)), part(values[~learners], (0.0, split))
    # the mean grows with pi (learners' success lies above non-learners'): least at the low ends, greatest at the high
    low = count[0] * learned[0] + (1 - count[0]) * unlearned[0]
    high = count[1] * learned[1] + (1 - count[1]) * unlearned[1]
    return Interval(float(values.mean()), float(low), float(high), level)


@lru_cache(maxsize=1024)
def _clopper_pearson(k: int, n: int, level: float) -> tuple[float, float]:
    """The exact interval of a binomial share, k of n (cached: the coverage simulation asks the same few often)."""
    ci = stats.binomtest(k, n).proportion_ci(confidence_level=level, method="exact")
    return float(ci.low), float(ci.high)


def difference_interval(
    a: Sequence[float], b: Sequence[float], episodes: int | None = None, level: float = LEVEL
) -> Interval:
    """Welch t interval of mean(a) - mean(b), each arm's variance floored for success rates (and the interval cut
    to [-1, 1] for them)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    bounds = (-1.0, 1.0) if episodes else None
    estimate = float(a.mean() - b.mean())
    if len(a) < 2 or len(b) < 2:
        return Interval(estimate, -np.inf, np.inf, level).within(bounds)
    va, vb = floored_variance(a, episodes) / len(a), floored_variance(b, episodes) / len(b)
    se = np.sqrt(va + vb)
    if se == 0:
        return Interval(estimate, estimate, estimate, level)
    # Welch-Satterthwaite over each arm's share of the variance: the same df, without squares that underflow
    wa, wb = va / (va + vb), vb / (va + vb)
    df = 1 / (wa**2 / (len(a) - 1) + wb**2 / (len(b) - 1))
    half = stats.t.ppf(0.5 + level / 2, df) * se
    return Interval(estimate, estimate - half, estimate + half, level).within(bounds)


def paired_difference_interval(
    a: Sequence[float], b: Sequence[float], episodes: int | None = None, level: float = LEVEL
) -> Interval:
    """t interval of the mean of a_i - b_i over replicates i that pair (a_i and b_i from the same replicate). For
    success rates over ``episodes`` episodes, the differences' variance is floored at the two arms' binomial
    variances together: what each rate's own episodes add, which pairing does not remove (an upper bound of it,
    so the floor errs wide), and the interval is cut to [-1, 1]."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    _check_paired(a, b)
    differences = a - b
    estimate = float(differences.mean())
    bounds = (-1.0, 1.0) if episodes else None
    if len(differences) < 2:
        return Interval(estimate, -np.inf, np.inf, level).within(bounds)
    variance = paired_variance(a, b, episodes)
    half = stats.t.ppf(0.5 + level / 2, len(differences) - 1) * np.sqrt(variance / len(differences))
    return Interval(estimate, estimate - half, estimate + half, level).within(bounds)


def paired_variance(a: np.ndarray, b: np.ndarray, episodes: int | None = None) -> float:
    """The variance of the differences a_i - b_i that :func:`paired_difference_interval` reads: for success rates
    over ``episodes`` episodes, at least both arms' binomial variances together."""
    variance = float((a - b).var(ddof=1))
    if episodes:
        variance = max(variance, _binomial(a, episodes) + _binomial(b, episodes))
    return variance


def _binomial(values: np.ndarray, episodes: int) -> float:
    """One seed's binomial variance of a rate over ``episodes`` episodes, at the arm's mean rate (shrunk off 0 and
    1 as :func:`floored_variance` shrinks it)."""
    p = (values.sum() * episodes + 0.5) / (len(values) * episodes + 1)
    return float(p * (1 - p) / episodes)


def censored_difference(
    a: Sequence[float], b: Sequence[float], paired: bool, level: float = LEVEL, seed: int = 0, budget: float = 1.0
) -> Interval:
    """How much sooner arm ``a`` reaches a threshold than arm ``b``: values are the times at which each run reached
    it, ``inf`` for a run that had not by ``budget`` (censored: it reaches it at ``budget`` or later, if ever). A
    censored time is known only to lie in [budget, inf), so the interval is bounded both ways: its lower end is that
    of the difference with every censored time of ``b`` at the budget and of ``a`` at infinity, its upper end the
    reverse (a partial-identification bound); where most runs are censored it is infinite and says nothing. The
    estimate takes each censored difference at its bound nearest 0 (two censored runs: 0). Paired, the median over
    replicates of b_i - a_i; unpaired, median(b) - median(a); either way a percentile bootstrap over replicates (pairs
    resampled together). Medians, because a mean of censored times is not defined."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    a_early, b_early = np.where(np.isinf(a), budget, a), np.where(np.isinf(b), budget, b)
    if paired:
        _check_paired(a, b)
        with np.errstate(invalid="ignore"):
            low, high = b_early - a, b - a_early  # each pair's least and greatest possible difference
            nearest = np.where(np.isinf(a) & np.isinf(b), 0.0, np.where(low > 0, low, np.where(high < 0, high, 0.0)))
        estimate = _median(nearest)
        if len(a) < 2:
            return Interval(estimate, -np.inf, np.inf, level)
        draws = _resamples(len(a), seed)
        return _bounded([_median(low[d]) for d in draws], [_median(high[d]) for d in draws], estimate, level)

    def ends(x: np.ndarray, y: np.ndarray, x_early: np.ndarray, y_early: np.ndarray) -> tuple[float, float]:
        with np.errstate(invalid="ignore"):
            return _median(y_early) - _median(x), _median(y) - _median(x_early)

    low, high = ends(a, b, a_early, b_early)
    estimate = float(low if low > 0 else high if high < 0 else 0.0)
    if len(a) < 2 or len(b) < 2:
        return Interval(estimate, -np.inf, np.inf, level)
    draws_a, draws_b = _resamples(len(a), seed), _resamples(len(b), seed + 1)
    resampled = [ends(a[da], b[db], a_early[da], b_early[db]) for da, db in zip(draws_a, draws_b, strict=True)]
    return _bounded([r[0] for r in resampled], [r[1] for r in resampled], estimate, level)


def censored_ratio(
    a: Sequence[float], b: Sequence[float], paired: bool, level: float = LEVEL, seed: int = 0, budget: float = 1.0
) -> Interval:
    """median(a) / median(b) of times to a threshold, ``inf`` for a run censored at ``budget`` (see
    :func:`censored_difference`: a censored time lies in [budget, inf), and the interval's ends are the ratio's least
    and greatest possible), with a percentile bootstrap over replicates (pairs resampled together where ``paired``):
    how many times one arm's typical time another's. The estimate takes censored times at the budget."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    a_early, b_early = np.where(np.isinf(a), budget, a), np.where(np.isinf(b), budget, b)

    def ratio(top: float, bottom: float) -> float:
        with np.errstate(divide="ignore", invalid="ignore"):
            value = top / bottom
        return float(np.inf if np.isnan(value) else value)

    def ends(i: np.ndarray, j: np.ndarray) -> tuple[float, float]:
        return ratio(_median(a_early[i]), _median(b[j])), ratio(_median(a[i]), _median(b_early[j]))

    estimate = ratio(_median(a_early), _median(b_early))
    if len(a) < 2 or len(b) < 2:
        return Interval(estimate, 0.0, np.inf, level)
    if paired:
        _check_paired(a, b)
        resampled = [ends(d, d) for d in _resamples(len(a), seed)]
    else:
        draws = zip(_resamples(len(a), seed), _resamples(len(b), seed + 1), strict=True)
        resampled = [ends(da, db) for da, db in draws]
    return _bounded([r[0] for r in resampled], [r[1] for r in resampled], estimate, level)


def _check_paired(a: np.ndarray, b: np.ndarray) -> None:
    if a.shape != b.shape:
        raise ValueError(f"paired values need one value per replicate on each side, got {len(a)} and {len(b)}")


def _median(values: np.ndarray) -> float:
    """The median where values may be infinite: a middle pair of one infinite value is infinite (at least that far),
    a pair of opposite infinities has no centre and counts as 0 (no difference known)."""
    with np.errstate(invalid="ignore"):
        median = float(np.median(values))
    return 0.0 if np.isnan(median) else median


def _resamples(n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, n, (BOOTSTRAP_RESAMPLES, n))


def _bounded(lows: list[float], highs: list[float], estimate: float, level: float) -> Interval:
    """The lower percentile of the bootstrap's lower bounds and the upper percentile of its upper bounds (nearest
    rank: infinite values stay what they are)."""
    tail = (1 - level) / 2
    lows, highs = np.sort(np.asarray(lows, dtype=float)), np.sort(np.asarray(highs, dtype=float))
    low = lows[int(np.floor(tail * (len(lows) - 1)))]
    high = highs[int(np.ceil((1 - tail) * (len(highs) - 1)))]
    return Interval(estimate, float(low), float(high), level)


def ratio_interval(a: Sequence[float], b: Sequence[float], level: float = LEVEL, seed: int = 0) -> Interval:
    """mean(a) / mean(b) with a bootstrap percentile interval (each group's seeds resampled on their own): how
    many times one agent's cost or speed another's is. ``b``'s mean must be positive."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    estimate = float(a.mean() / b.mean())
    if len(a) < 2 or len(b) < 2:
        return Interval(estimate, -np.inf, np.inf, level)
    return _stratified_bootstrap((a, b), lambda x, y: float(x.mean() / y.mean()), estimate, level, seed)


def iqm(values: Sequence[float]) -> float:
    """Interquartile mean: the mean of the middle 50% of the values (rliable's robust aggregate), NaN of none.

    scipy's ``trim_mean(values, 0.25)`` step by step (the same partition and the same mean, so the same bits) without
    its array-API wrapper, which costs twenty times the arithmetic: a bootstrap calls this thousands of times."""
    values = np.asarray(values, dtype=float).ravel()
    if not len(values):
        return float("nan")
    cut = len(values) // 4
    return float(np.partition(values, (cut, len(values) - cut - 1))[cut : len(values) - cut].mean())


def aggregate_interval(
    per_task: Sequence[Sequence[float]],
    statistic: Callable[[np.ndarray], float] = iqm,
    level: float = LEVEL,
    seed: int = 0,
) -> Interval:
    """``statistic`` of every run of every task pooled, with a stratified-bootstrap percentile interval (each task's
    runs resampled with replacement on their own)."""
    samples = tuple(np.asarray(task, dtype=float) for task in per_task)
    estimate = float(statistic(np.concatenate(samples)))
    if min(len(s) for s in samples) < 2:
        return Interval(estimate, -np.inf, np.inf, level)

    def pooled(*resampled: np.ndarray) -> float:
        return float(statistic(np.concatenate(resampled)))

    return _stratified_bootstrap(samples, pooled, estimate, level, seed)


def _stratified_bootstrap(samples: tuple, statistic, estimate: float, level: float, seed: int) -> Interval:
    """Percentile interval of ``statistic(*samples)``, each sample resampled with replacement on its own."""
    result = stats.bootstrap(
        samples,
        statistic,
        vectorized=False,
        paired=False,
        method="percentile",
        confidence_level=level,
        n_resamples=BOOTSTRAP_RESAMPLES,
        rng=np.random.default_rng(seed),
    )
    return Interval(estimate, float(result.confidence_interval.low), float(result.confidence_interval.high), level)


def _p_greater(x: np.ndarray, y: np.ndarray) -> float:
    """P(X > Y) + P(X = Y) / 2 for a run X of one agent and a run Y of another (the Mann-Whitney U over n m)."""
    greater = (x[:, None] > y[None, :]).mean()
    ties = (x[:, None] == y[None, :]).mean()
    return float(greater + 0.5 * ties)


def probability_of_improvement(
    x_per_task: Sequence[Sequence[float]],
    y_per_task: Sequence[Sequence[float]],
    level: float = LEVEL,
    seed: int = 0,
) -> Interval:
    """The probability that a run of X scores higher than a run of Y on a task, averaged over tasks, with a
    stratified-bootstrap percentile interval (both agents' runs of each task resampled on their own)."""
    xs = [np.asarray(t, dtype=float) for t in x_per_task]
    ys = [np.asarray(t, dtype=float) for t in y_per_task]
    tasks = len(xs)

    def average(*samples: np.ndarray) -> float:
        return float(np.mean([_p_greater(samples[i], samples[tasks + i]) for i in range(tasks)]))

    estimate = average(*xs, *ys)
    if min(len(s) for s in xs + ys) < 2:
        return Interval(estimate, -np.inf, np.inf, level)
    return _stratified_bootstrap((*xs, *ys), average, estimate, level, seed)


def performance_profile(scores: Sequence[float], thresholds: np.ndarray) -> np.ndarray:
    """The fraction of runs (over every task) whose score exceeds each threshold."""
    scores = np.asarray(scores, dtype=float)
    return (scores[None, :] > np.asarray(thresholds, dtype=float)[:, None]).mean(axis=1)


def normalised_auc(env_steps: np.ndarray, values: np.ndarray, budget: float, points: int = 101) -> float:
    """Area under a learning curve of values in [0, 1] over a common grid of ``points`` env steps from 0 to
    ``budget``, divided by the budget: 1 is a run that succeeds from the start, 0 one that never does. Before the
    first logged value, and where nothing is known yet, the curve counts 0."""
    grid = np.linspace(0, budget, points)
    known = ~np.isnan(values)
    if not known.any():
        return 0.0
    x, y = np.asarray(env_steps, dtype=float)[known], np.asarray(values, dtype=float)[known]
    curve = np.interp(grid, x, y)
    curve[grid < x[0]] = 0.0
    return float(np.trapezoid(curve, grid) / budget)


def steps_to_threshold(
    env_steps: np.ndarray,
    values: np.ndarray,
    threshold: float = THRESHOLD,
    hold: float = HOLD,
    budget: float | None = None,
    smoothing: float = SMOOTHING,
) -> float | None:
    """The first env step from which the curve, smoothed by a trailing mean over ``smoothing`` of the budget, stays at
    or above ``threshold`` for ``hold`` of the budget (or to the end of training, where less is left); None when it
    never does (a censored run: report it, never drop it). ``budget`` defaults to the last logged step.

    Why so: the time a curve first holds a level on its rise is a speed; the time it last crosses a level near its
    plateau (the rule before) measured the plateau's height and moved with the curve's resolution. Windows are in
    env steps, so a curve logged every update and the same curve at 50 points agree within one of the coarser
    curve's intervals. A curve that starts at or above the level before any learning (the training success is a
    mean over the last episodes to end, and early on the episodes that end soonest, those that reach the goal under
    a sparse reward, fill it) and then falls has not learned until it comes back: its opening stretch above the
    level is skipped; one that never falls below it holds it from its first step. What "learns faster" is judged
    on (docs/verdicts.md), and what the benchmarks compare learning on: the package's one steps-to-threshold."""
    steps = np.asarray(env_steps, dtype=float)
    values = np.nan_to_num(np.asarray(values, dtype=float), nan=0.0)
    if not len(values):
        return None
    budget = float(budget if budget is not None else steps[-1])
    # trailing mean over the points logged within the smoothing span (at least the point itself)
    index = np.arange(len(values))
    starts = np.minimum(np.searchsorted(steps, steps - smoothing * budget, side="right"), index)
    sums = np.concatenate([[0.0], np.cumsum(values)])
    smooth = (sums[index + 1] - sums[starts]) / (index + 1 - starts)
    above = smooth >= threshold
    if above.all():
        return float(steps[0])
    first_below = int(np.argmax(~above))
    # each point's last point within the hold window; held when no point from it to there is below the level
    ends = np.searchsorted(steps, steps + hold * budget, side="right") - 1
    below_before = np.concatenate([[0], np.cumsum(~above)])
    held = above & (below_before[ends + 1] - below_before[index] == 0)
    held[:first_below] = False  # the opening stretch above the level, before the curve fell: not learning
    found = np.flatnonzero(held)
    return float(steps[found[0]]) if len(found) else None
