"""Three-way verdicts: each claim of the paper *reproduces*, *does not reproduce*, or is *inconclusive*, judged from
95% intervals over seeds (:mod:`famarl_cli.core.statistics`) and a smallest effect of interest fixed in advance.

The rules (docs/verdicts.md shows why point comparisons of a few seeds are not enough):

- **A solves the task** (mean >= tau): reproduces if the interval's lower end >= tau, does not if its upper end
  < tau.
- **B fails** (mean <= tau): reproduces if the upper end <= tau, does not if the lower end > tau.
- **A beats B** by the smallest effect that matters, delta: the interval of mean(A) - mean(B), paired by replicate
  where A and B share their replicates (the t interval of the per-replicate differences), else Welch's;
  reproduces if its lower end >= delta (A is shown better by at least delta), does not if its upper end < delta
  (A is shown not to be better by that much). A minimum-effect test (Murphy & Myors 1999) with its mirror: delta
  is the one threshold on both sides, so an effect shown to be smaller than delta can never reproduce
  (docs/verdicts.md).
- **A learns faster than B**: how many env steps sooner A's training success reaches 0.8 and holds it than B's, as a
  share of the budget; a run that has not by the budget is censored (it gets there at the budget or later, if
  ever). The median of the paired differences with a bootstrap interval bounded both ways by what the censored runs
  leave possible (:func:`~famarl_cli.core.statistics.censored_difference`); reproduces if its lower end >= delta,
  does not if its upper end < delta; where most runs of both arms are censored it is inconclusive.
- **A performs best (learns fastest)** among m agents: "beats" ("learns faster") against every rival at level
  alpha / (m - 1) (Bonferroni); reproduces if every comparison does, does not if any does not.
- **The groups do not differ** (equivalence): every pairwise Welch interval, Bonferroni-adjusted; reproduces if
  each lies inside (-margin, margin), does not if one lies wholly outside [-margin, margin].
- **A improves on B over tasks** (aggregates): the probability of improvement's bootstrap interval; reproduces if
  its lower end > 1/2, does not if its upper end < 1/2.
- A claim made of several parts (``all_of``) reproduces when every part does and does not when any part does not.

Everything else is inconclusive: the seeds do not settle it either way.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from itertools import combinations

from famarl_cli.core.statistics import (
    LEVEL,
    Interval,
    censored_difference,
    difference_interval,
    mean_interval,
    paired_difference_interval,
    probability_of_improvement,
)


class Verdict(StrEnum):
    REPRODUCES = "reproduces"
    DOES_NOT = "does not reproduce"
    INCONCLUSIVE = "inconclusive"


@dataclass(frozen=True)
class Estimate:
    """One interval a verdict read, with the per-seed values behind it, for tables and interval plots."""

    name: str
    interval: Interval
    values: tuple[float, ...] = ()
    reference: float | None = None
    """The threshold the interval is compared with (tau, delta, 1/2), drawn as a line."""


@dataclass(frozen=True)
class Judgement:
    verdict: Verdict
    rule: str
    estimates: tuple[Estimate, ...] = ()


def bonferroni_level(comparisons: int) -> float:
    """The confidence level of each of ``comparisons`` intervals, so that all hold together at LEVEL."""
    return 1 - (1 - LEVEL) / max(1, comparisons)


def three_way(reproduces: bool, does_not: bool) -> Verdict:
    if reproduces:
        return Verdict.REPRODUCES
    return Verdict.DOES_NOT if does_not else Verdict.INCONCLUSIVE


def combine(verdicts: Sequence[Verdict]) -> Verdict:
    """A claim of several parts reproduces when every part does and does not when any part does not."""
    return three_way(bool(verdicts) and all(v == Verdict.REPRODUCES for v in verdicts), Verdict.DOES_NOT in verdicts)


def solves(
    name: str, values: Sequence[float], tau: float, episodes: int | None = None, level: float = LEVEL
) -> Judgement:
    interval = mean_interval(values, episodes, level)
    return Judgement(
        three_way(interval.low >= tau, interval.high < tau),
        f"mean >= {tau:g}: lower end >= {tau:g} reproduces, upper end < {tau:g} does not",
        (Estimate(name, interval, tuple(values), tau),),
    )


def reaches(
    name: str, values: Sequence[float], tau: float, episodes: int | None = None, level: float = LEVEL
) -> Judgement:
    """:func:`solves` for a measure that is a lower bound (a search's share of solved layouts): the lower end at or
    above ``tau`` reproduces; a bound under ``tau`` says only that the search found less, so nothing does not."""
    judged = solves(name, values, tau, episodes, level)
    return Judgement(
        three_way(judged.verdict == Verdict.REPRODUCES, False),
        f"mean >= {tau:g}: lower end >= {tau:g} reproduces; a lower bound cannot show less, so never does not",
        judged.estimates,
    )


def fails(
    name: str, values: Sequence[float], tau: float, episodes: int | None = None, level: float = LEVEL
) -> Judgement:
    interval = mean_interval(values, episodes, level)
    return Judgement(
        three_way(interval.high <= tau, interval.low > tau),
        f"mean <= {tau:g}: upper end <= {tau:g} reproduces, lower end > {tau:g} does not",
        (Estimate(name, interval, tuple(values), tau),),
    )


def beats(
    a_name: str,
    a: Sequence[float],
    b_name: str,
    b: Sequence[float],
    delta: float,
    episodes: int | None = None,
    level: float = LEVEL,
    paired: bool = False,
) -> Judgement:
    """``a`` beats ``b`` by at least ``delta``; ``paired``: a[i] and b[i] are one replicate's."""
    if paired:
        interval, how = paired_difference_interval(a, b, episodes, level), "paired by replicate"
    else:
        interval, how = difference_interval(a, b, episodes, level), "Welch"
    return Judgement(
        three_way(interval.low >= delta, interval.high < delta),
        f"{a_name} - {b_name} ({how}, {level:.1%}): lower end >= {delta:g} reproduces, upper end < {delta:g} does not",
        (Estimate(f"{a_name} - {b_name}", interval, (), delta),),
    )


def faster(
    a_name: str,
    a: Sequence[float],
    b_name: str,
    b: Sequence[float],
    delta: float,
    level: float = LEVEL,
    paired: bool = False,
) -> Judgement:
    """``a`` reaches the threshold sooner than ``b`` by at least ``delta``: ``a`` and ``b`` are each run's time to it
    as a share of the budget, ``inf`` for a run that never reached it."""
    interval = censored_difference(a, b, paired, level)
    how = "median of paired differences" if paired else "difference of medians"
    return Judgement(
        three_way(interval.low >= delta, interval.high < delta),
        f"{b_name} - {a_name}, steps to the threshold over the budget ({how}, censored runs bounded; bootstrap, "
        f"{level:.1%}): lower end >= {delta:g} reproduces, upper end < {delta:g} does not",
        (Estimate(f"{b_name} - {a_name}", interval, (), delta),),
    )


def all_of(parts: Sequence[Judgement], rule: str) -> Judgement:
    return Judgement(
        combine([part.verdict for part in parts]),
        rule,
        tuple(estimate for part in parts for estimate in part.estimates),
    )


Pairs = dict[str, tuple[Sequence[float], Sequence[float], bool]]
"""Per rival: the candidate's values, the rival's, and whether they pair by replicate (index by index)."""


def best(name: str, rivals: Pairs, delta: float, episodes: int | None = None) -> Judgement:
    level = bonferroni_level(len(rivals))
    parts = [beats(name, mine, rival, theirs, delta, episodes, level, paired) for rival, (mine, theirs, paired) in
             rivals.items()]  # fmt: skip
    return all_of(parts, f"{name} beats each of {len(rivals)} rivals at {level:.1%} (Bonferroni), delta {delta:g}")


def fastest(name: str, rivals: Pairs, delta: float) -> Judgement:
    level = bonferroni_level(len(rivals))
    parts = [faster(name, mine, rival, theirs, delta, level, paired) for rival, (mine, theirs, paired) in
             rivals.items()]  # fmt: skip
    return all_of(
        parts, f"{name} learns faster than each of {len(rivals)} rivals at {level:.1%} (Bonferroni), delta {delta:g}"
    )


def equivalent(groups: dict[str, Sequence[float]], margin: float, episodes: int | None = None) -> Judgement:
    pairs = list(combinations(groups, 2))
    level = bonferroni_level(len(pairs))
    verdicts, estimates = [], []
    for a, b in pairs:
        interval = difference_interval(groups[a], groups[b], episodes, level)
        inside = -margin < interval.low and interval.high < margin
        outside = interval.low > margin or interval.high < -margin
        verdicts.append(three_way(inside, outside))
        estimates.append(Estimate(f"{a} - {b}", interval, (), margin))
    verdict = combine(verdicts)
    rule = (
        f"every pairwise difference (Welch, {level:.1%}, Bonferroni over {len(pairs)}) inside "
        f"(-{margin:g}, {margin:g}) reproduces; one wholly outside does not"
    )
    return Judgement(verdict, rule, tuple(estimates))


def improves(
    name: str,
    per_task: Sequence[Sequence[float]],
    rivals: dict[str, Sequence[Sequence[float]]],
) -> Judgement:
    """``name`` improves on every rival over the tasks: probability of improvement > 1/2 for each (Bonferroni)."""
    level = bonferroni_level(len(rivals))
    verdicts, estimates = [], []
    for rival, theirs in rivals.items():
        interval = probability_of_improvement(per_task, theirs, level)
        verdicts.append(three_way(interval.low > 0.5, interval.high < 0.5))
        estimates.append(Estimate(f"P({name} > {rival})", interval, (), 0.5))
    verdict = combine(verdicts)
    rule = (
        f"probability of improvement over each rival (stratified bootstrap, {level:.1%}, Bonferroni): lower end "
        "> 1/2 reproduces, upper end < 1/2 does not"
    )
    return Judgement(verdict, rule, tuple(estimates))


@dataclass
class Claim:
    """One statement of the paper, what we measure per seed, and the judgement."""

    paper: str
    measure: str
    """What each seed contributes (e.g. "success of the sampled policy over 100 evaluation episodes")."""
    judgement: Judgement
    notes: list[str] = field(default_factory=list)

    @property
    def verdict(self) -> Verdict:
        return self.judgement.verdict

    def per_seed(self) -> str:
        """Each estimate's per-seed values and its interval, as the report's table shows them."""
        parts = []
        for estimate in self.judgement.estimates:
            values = " ".join(f"{v:.2f}" for v in estimate.values)
            n = f"n={len(estimate.values)}: {values}; " if estimate.values else ""
            parts.append(f"{estimate.name}: {n}{estimate.interval.text()}")
        return "<br>".join(parts)


def not_run(paper: str, measure: str) -> Claim:
    return Claim(paper, measure, Judgement(Verdict.INCONCLUSIVE, "no runs of this variant"))
