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
- **A learns faster than B**: how many env steps sooner A's training success first holds 0.5 for 5% of the budget
  than B's, as a share of the budget (:func:`~famarl_cli.core.statistics.steps_to_threshold`); a run that never
  does is censored. The median of the paired differences with a bootstrap interval bounded both ways by what the
  censored runs leave possible (:func:`~famarl_cli.core.statistics.censored_difference`); reproduces if its lower
  end >= delta, does not if its upper end < delta. Where half or more of an arm's runs never hold the level, that
  arm has no time to it within the budget and the speed is **undefined**, a verdict of its own with its reason:
  whether it learns at all is a question of success, not of speed.
- **A performs best (learns fastest)** among m agents: "beats" ("learns faster") against every rival at level
  alpha / (m - 1) (Bonferroni); reproduces if every comparison does, does not if any does not.
- **The groups do not differ** (equivalence): every pairwise Welch interval, Bonferroni-adjusted; reproduces if
  each lies inside (-margin, margin), does not if one lies wholly outside [-margin, margin].
- **A improves on B over tasks** (aggregates): the probability of improvement's bootstrap interval; reproduces if
  its lower end > 1/2, does not if its upper end < 1/2.
- A claim made of several parts (``all_of``) reproduces when every part does and does not when any part does not.

Everything else is inconclusive: the seeds do not settle it either way.

:func:`family` states what the decisive verdicts of several claims are worth together (docs/verdicts.md, "The
family").
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum
from itertools import combinations

import numpy as np

from famarl_cli.core.errors import ArtifactError
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
    UNDEFINED = "undefined"
    """The measure does not exist for these runs (no time to a level an arm never holds): not a reading of an
    interval, so neither decisive nor a matter of more replicates of the same runs."""


@dataclass(frozen=True)
class Arm:
    """One side of a difference: its name and its per-replicate values."""

    name: str
    values: tuple[float, ...]


@dataclass(frozen=True)
class Estimate:
    """One interval a verdict read, with the per-seed values behind it, for tables, interval plots and summary.json
    (where they let the claim be analysed again: ``famarl power``)."""

    name: str
    interval: Interval
    values: tuple[float, ...] = ()
    """One arm's per-replicate values (a mean's); empty for a difference, whose values are its :attr:`arms`'."""
    reference: float | None = None
    """The threshold the interval is compared with (tau, delta, 1/2), drawn as a line."""
    arms: tuple[Arm, ...] = ()
    """A difference's two arms, the interval's first minus its second, each with its per-replicate values."""
    paired: bool | None = None
    """For a difference: whether its arms pair by replicate (index by index)."""
    episodes: int | None = None
    """Where the values are success rates: the evaluation episodes behind each (the rule floors their variance at
    the binomial noise of that many)."""
    replicates: int | None = None
    """n where no values are kept: the fewest runs of a task, for an aggregate over tasks."""

    @property
    def n(self) -> int:
        """Replicates per arm (the fewer, where a difference's arms differ); 0 where unknown."""
        if self.arms:
            return min(len(arm.values) for arm in self.arms)
        return len(self.values) if self.values else self.replicates or 0


def _floats(values: Sequence[float]) -> tuple[float, ...]:
    return tuple(float(v) for v in values)


def difference(
    name: str,
    interval: Interval,
    a: tuple[str, Sequence[float]],
    b: tuple[str, Sequence[float]],
    reference: float,
    paired: bool,
    episodes: int | None = None,
) -> Estimate:
    """The estimate of a difference ``a - b`` with both arms' per-replicate values."""
    arms = (Arm(a[0], _floats(a[1])), Arm(b[0], _floats(b[1])))
    return Estimate(name, interval, (), reference, arms, paired, episodes)


@dataclass(frozen=True)
class Judgement:
    verdict: Verdict
    rule: str
    estimates: tuple[Estimate, ...] = ()
    reason: str = ""
    """Why the measure is undefined, for :attr:`Verdict.UNDEFINED`."""


def bonferroni_level(comparisons: int, level: float = LEVEL) -> float:
    """The confidence level of each of ``comparisons`` intervals, so that all hold together at ``level``."""
    return 1 - (1 - level) / max(1, comparisons)


def three_way(reproduces: bool, does_not: bool) -> Verdict:
    if reproduces:
        return Verdict.REPRODUCES
    return Verdict.DOES_NOT if does_not else Verdict.INCONCLUSIVE


def combine(verdicts: Sequence[Verdict]) -> Verdict:
    """A claim of several parts reproduces when every part does and does not when any part does not; else it is
    undefined when a part is (no more replicates of the same runs would decide it), inconclusive otherwise."""
    verdict = three_way(bool(verdicts) and all(v == Verdict.REPRODUCES for v in verdicts), Verdict.DOES_NOT in verdicts)
    if verdict == Verdict.INCONCLUSIVE and Verdict.UNDEFINED in verdicts:
        return Verdict.UNDEFINED
    return verdict


def at_least(interval: Interval, tau: float) -> Verdict:
    return three_way(interval.low >= tau, interval.high < tau)


def at_most(interval: Interval, tau: float) -> Verdict:
    return three_way(interval.high <= tau, interval.low > tau)


def _mean(name: str, values: Sequence[float], tau: float, episodes: int | None, level: float, above: bool) -> Judgement:
    """The mean of ``values`` at least (``above``) or at most ``tau``, judged on its interval."""
    interval = mean_interval(values, episodes, level)
    rule = (
        f"mean >= {tau:g}: lower end >= {tau:g} reproduces, upper end < {tau:g} does not"
        if above
        else f"mean <= {tau:g}: upper end <= {tau:g} reproduces, lower end > {tau:g} does not"
    )
    verdict = (at_least if above else at_most)(interval, tau)
    return Judgement(verdict, rule, (Estimate(name, interval, _floats(values), tau, episodes=episodes),))


def solves(
    name: str, values: Sequence[float], tau: float, episodes: int | None = None, level: float = LEVEL
) -> Judgement:
    return _mean(name, values, tau, episodes, level, above=True)


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
    return _mean(name, values, tau, episodes, level, above=False)


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
        at_least(interval, delta),
        f"{a_name} - {b_name} ({how}, {level:.1%}): lower end >= {delta:g} reproduces, upper end < {delta:g} does not",
        (difference(f"{a_name} - {b_name}", interval, (a_name, a), (b_name, b), delta, paired, episodes),),
    )


def speed_undefined(arms: dict[str, Sequence[float]]) -> str:
    """Why a comparison of times to a level is undefined ("" where it is not): an arm of which half or more of the
    runs never held the level (``inf``) has no median time to it within the budget."""
    reasons = []
    for name, times in arms.items():
        never = int(np.isinf(np.asarray(times, dtype=float)).sum())
        if 2 * never >= len(times):
            reasons.append(
                f"{name}: {never} of {len(times)} runs never hold the level, so its median time to it is not within "
                "the budget; whether it learns is judged on its success"
            )
    return "; ".join(reasons)


def faster(
    a_name: str,
    a: Sequence[float],
    b_name: str,
    b: Sequence[float],
    delta: float,
    level: float = LEVEL,
    paired: bool = False,
) -> Judgement:
    """``a`` reaches the level sooner than ``b`` by at least ``delta``: ``a`` and ``b`` are each run's time to it
    as a share of the budget, ``inf`` for a run that never held it. Undefined, with its reason, where half or more of
    an arm's runs never held it: that arm's median time is beyond the budget, if it exists at all, and the interval
    would be [-inf, inf] or rest on runs that did not learn."""
    how = "median of paired differences" if paired else "difference of medians"
    rule = (
        f"{b_name} - {a_name}, steps to the level over the budget ({how}, censored runs bounded; bootstrap, "
        f"{level:.1%}): lower end >= {delta:g} reproduces, upper end < {delta:g} does not; undefined where half or "
        "more of an arm's runs never hold the level"
    )
    reason = speed_undefined({a_name: a, b_name: b})
    if reason:
        return Judgement(Verdict.UNDEFINED, rule, (), reason)
    interval = censored_difference(a, b, paired, level)
    if np.isinf(interval.low) and np.isinf(interval.high):
        reason = "the censored runs leave every difference possible"
        return Judgement(Verdict.UNDEFINED, rule, (), reason)
    return Judgement(
        at_least(interval, delta),
        rule,
        (difference(f"{b_name} - {a_name}", interval, (b_name, b), (a_name, a), delta, paired),),
    )


def all_of(parts: Sequence[Judgement], rule: str) -> Judgement:
    return Judgement(
        combine([part.verdict for part in parts]),
        rule,
        tuple(estimate for part in parts for estimate in part.estimates),
        "; ".join(part.reason for part in parts if part.reason),
    )


Pairs = dict[str, tuple[Sequence[float], Sequence[float], bool]]
"""Per rival: the candidate's values, the rival's, and whether they pair by replicate (index by index)."""


def best(name: str, rivals: Pairs, delta: float, episodes: int | None = None) -> Judgement:
    level = bonferroni_level(len(rivals))
    parts = [beats(name, mine, rival, theirs, delta, episodes, level, paired) for rival, (mine, theirs, paired) in
             rivals.items()]  # fmt: skip
    return all_of(parts, _each_rival(name, "beats", rivals, level, delta))


def fastest(name: str, rivals: Pairs, delta: float) -> Judgement:
    level = bonferroni_level(len(rivals))
    parts = [faster(name, mine, rival, theirs, delta, level, paired) for rival, (mine, theirs, paired) in
             rivals.items()]  # fmt: skip
    return all_of(parts, _each_rival(name, "learns faster than", rivals, level, delta))


def _each_rival(name: str, how: str, rivals: Pairs, level: float, delta: float) -> str:
    return f"{name} {how} each of {len(rivals)} rivals at {level:.1%} (Bonferroni), delta {delta:g}"


def equivalent(groups: dict[str, Sequence[float]], margin: float, episodes: int | None = None) -> Judgement:
    pairs = list(combinations(groups, 2))
    level = bonferroni_level(len(pairs))
    verdicts, estimates = [], []
    for a, b in pairs:
        interval = difference_interval(groups[a], groups[b], episodes, level)
        inside = -margin < interval.low and interval.high < margin
        outside = interval.low > margin or interval.high < -margin
        verdicts.append(three_way(inside, outside))
        estimates.append(difference(f"{a} - {b}", interval, (a, groups[a]), (b, groups[b]), margin, False, episodes))
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
        runs = min(len(task) for task in (*per_task, *theirs))
        estimates.append(Estimate(f"P({name} > {rival})", interval, (), 0.5, replicates=runs))
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
    look: tuple[int, int] | None = None
    """(look, looks) where replicates were added in blocks and this is a later look (:class:`Looks`)."""

    @property
    def verdict(self) -> Verdict:
        return self.judgement.verdict

    def per_seed(self) -> str:
        """Each estimate's per-seed values and its interval, as the report's table shows them; an undefined
        measure's reason in place of an interval."""
        parts = []
        for estimate in self.judgement.estimates:
            values = " ".join(f"{v:.2f}" for v in estimate.values)
            n = f"n={len(estimate.values)}: {values}; " if estimate.values else ""
            parts.append(f"{estimate.name}: {n}{estimate.interval.text()}")
        if self.judgement.reason:
            parts.append(f"undefined: {self.judgement.reason}")
        return "<br>".join(parts)


@dataclass(frozen=True)
class Looks:
    """Replicates added in blocks (docs/verdicts.md, "Replicates added in blocks"): the pipeline's ``first`` replicates
    are look 1, judged at LEVEL; each block adds ``block``, up to ``most`` in all; looks 2 to :attr:`count` share
    another one-sided (1 - LEVEL) / 2 equally, so a claim decided late errs with probability at most 1 - LEVEL."""

    first: int
    block: int = 5
    most: int = 20

    @property
    def count(self) -> int:
        return 1 + -(-(self.most - self.first) // self.block)

    def look(self, n: int) -> int:
        """The look that ``n`` replicates make; more than :attr:`most` is no planned look."""
        if n > self.most:
            raise ArtifactError(f"{n} replicates, more than the {self.most} the blocks allow (docs/verdicts.md)")
        return 1 if n <= self.first else 1 + -(-(n - self.first) // self.block)

    def level(self, n: int) -> float:
        """The level at which ``n`` replicates are judged."""
        return LEVEL if self.look(n) == 1 else 1 - (1 - LEVEL) / (self.count - 1)

    def of(self, n: int) -> tuple[int, int] | None:
        """:attr:`Claim.look` of a claim judged on ``n`` replicates (None at look 1)."""
        look = self.look(n)
        return None if look == 1 else (look, self.count)


def not_run(paper: str, measure: str) -> Claim:
    return Claim(paper, measure, Judgement(Verdict.INCONCLUSIVE, "no runs of this variant"))


WRONG_PER_CLAIM = (1 - LEVEL) / 2
"""The chance that one claim's verdict is wrong, at most, whatever its truth: a claim reproduces wrongly only where
its truth lies short of the threshold and its interval lies wholly beyond it, so the interval missed the truth on
that side (at most (1 - LEVEL) / 2 of the time for an equal-tailed interval that covers at its level; a claim of
Bonferroni parts adds the parts' shares up to the same), and does not reproduce wrongly only by the mirror miss."""

DECISIVE = {"reproduces", "does not reproduce", "met", "missed"}
"""A verdict's words (a paper's claim or a goal) that decide it."""


@dataclass(frozen=True)
class Family:
    """What the verdicts of several claims are worth together: the statement docs/verdicts.md ("The family") argues
    and tests/test_verdicts_family.py checks by simulation with truths at the thresholds."""

    claims: int
    """Distinct claims with an interval: those that can be wrong (claims that re-judge identical runs by the same
    rule count once; a claim without runs, or an undefined one, reads no interval and is never wrong)."""
    duplicates: int
    """Claims left out of :attr:`claims` as re-judging another's runs by its rule."""
    decisive: int
    """Of the distinct claims, those that reproduce or do not (met or missed)."""
    near: tuple[str, ...]
    """The decisive claims whose verdict sits near its threshold (:func:`near_threshold`)."""
    late: int = 0
    """Of the distinct claims, those judged at a later look of replicates added in blocks: each errs with probability
    at most twice :data:`WRONG_PER_CLAIM` (its first look's share and the later looks' together), so counts twice."""

    @property
    def expected_wrong(self) -> float:
        return WRONG_PER_CLAIM * (self.claims + self.late)

    def text(self) -> str:
        """The statement, with its assumption, in one paragraph."""
        twice = ""
        if self.duplicates:
            twice = f" ({self.duplicates} re-judging the same runs by the same rule counted once)"
        if self.late:
            twice += f" ({self.late} judged at a later look of replicates added in blocks counted twice)"
        near = (
            f" Decisive near their thresholds (the threshold within one half-width of the interval's near end), the "
            f"verdicts a replication would most likely not repeat: {'; '.join(self.near)}."
            if self.near
            else " No decisive verdict lies near its threshold (within one half-width of the interval's near end)."
        )
        return (
            f"If every interval covers at its level with equal tails, each claim is judged wrong by chance with "
            f"probability at most {WRONG_PER_CLAIM:.1%}, whatever its truth, so among these {self.claims} distinct "
            f"claims{twice} at most {self.expected_wrong:.2g} wrong verdicts are expected, however the claims depend "
            f"on one another. That bounds the wrong verdicts, not their share of the {self.decisive} decisive ones: "
            "where a truth sits at its threshold, about half of the few decisive verdicts there are wrong "
            '(docs/verdicts.md, "The family").' + near
        )


def near_threshold(estimate: dict) -> bool:
    """A decisive estimate (``estimate``, ``low``, ``high``, ``reference`` as summary.json records them) is near its
    threshold when the threshold lies within one half-width beyond the interval's near end (the estimate within two
    half-widths of it, on the side of the threshold): an interval of the same width around a truth at the threshold
    would reach the estimate. Intervals that straddle the threshold are not decisive and not flagged."""
    reference, value = estimate.get("reference"), estimate["estimate"]
    low, high = estimate["low"], estimate["high"]
    if reference is None or not (np.isfinite(low) and np.isfinite(high)):
        return False
    if low >= reference:
        return value - reference < 2 * (value - low)
    if high <= reference:
        return reference - value < 2 * (high - value)
    return False


def family(judged: Sequence[dict]) -> Family:
    """:class:`Family` of claims as summary.json's ``judged`` records them (claim, verdict, rule, estimates)."""
    seen: set = set()
    claims = duplicates = decisive = late = 0
    near = []
    for claim in judged:
        estimates = claim.get("estimates", [])
        if not estimates:
            continue
        key = (
            claim["rule"],
            tuple((e["name"], e["estimate"], e["low"], e["high"], e.get("level")) for e in estimates),
        )
        if key in seen:
            duplicates += 1
            continue
        seen.add(key)
        claims += 1
        late += bool(claim.get("look"))
        if claim["verdict"] in DECISIVE:
            decisive += 1
            if any(near_threshold(e) for e in estimates):
                near.append(claim["claim"])
    return Family(claims, duplicates, decisive, tuple(near), late)
