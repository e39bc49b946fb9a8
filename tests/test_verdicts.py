"""The three-way rules: each verdict on values whose interval is clearly above, clearly below, or across the line."""

from __future__ import annotations

import pytest

from famarl_cli.report.verdicts import (
    Verdict,
    all_of,
    beats,
    best,
    bonferroni_level,
    equivalent,
    fails,
    faster,
    fastest,
    improves,
    reaches,
    solves,
)

HIGH = [0.95, 0.97, 0.96, 0.98, 0.94]
LOW = [0.10, 0.12, 0.08, 0.11, 0.09]
SPREAD = [0.2, 0.9, 0.5, 1.0, 0.6]


@pytest.mark.parametrize(
    ("values", "expected"),
    [(HIGH, Verdict.REPRODUCES), (LOW, Verdict.DOES_NOT), (SPREAD, Verdict.INCONCLUSIVE)],
)
def test_solves(values, expected):
    assert solves("a", values, 0.8, episodes=100).verdict == expected


@pytest.mark.parametrize(
    ("values", "expected"),
    [(HIGH, Verdict.REPRODUCES), (LOW, Verdict.INCONCLUSIVE), (SPREAD, Verdict.INCONCLUSIVE)],
)
def test_reaches_a_lower_bound_never_refutes(values, expected):
    assert reaches("c", values, 0.8, episodes=10).verdict == expected


@pytest.mark.parametrize(
    ("values", "expected"),
    [(LOW + LOW, Verdict.REPRODUCES), (HIGH, Verdict.DOES_NOT), (SPREAD, Verdict.INCONCLUSIVE)],
)
def test_fails(values, expected):
    assert fails("b", values, 0.5, episodes=100).verdict == expected


def test_few_replicates_that_all_fail_cannot_show_that_most_would():
    # five replicates that did not learn leave up to about half of all replicates possible learners (Clopper-Pearson
    # on 0 of 5): "fails" is not shown; ten of them show it
    assert fails("b", LOW, 0.5, episodes=100).verdict == Verdict.INCONCLUSIVE
    assert fails("b", LOW + LOW, 0.5, episodes=100).verdict == Verdict.REPRODUCES


def test_seeds_all_at_one_are_judged_with_the_evaluations_noise():
    # Without the floor the interval would be [1, 1]; with it, 3 seeds of 10 episodes are not enough for >= 0.95.
    assert solves("a", [1.0, 1.0, 1.0], 0.8, episodes=100).verdict == Verdict.REPRODUCES
    judgement = solves("a", [1.0, 1.0, 1.0], 0.95, episodes=10)
    assert judgement.estimates[0].interval.low < 0.95
    assert judgement.verdict == Verdict.INCONCLUSIVE


def test_beats_needs_the_difference_shown_at_least_delta_and_denies_it_below_delta():
    assert beats("a", HIGH, "b", LOW, 0.05, episodes=100).verdict == Verdict.REPRODUCES
    assert beats("b", LOW, "a", HIGH, 0.05, episodes=100).verdict == Verdict.DOES_NOT
    # Equal arms: the difference's upper end is above 0 but below a delta of 0.5: "not better by 0.5".
    assert beats("a", HIGH, "c", HIGH, 0.5, episodes=100).verdict == Verdict.DOES_NOT
    assert beats("a", HIGH, "c", HIGH, 0.01, episodes=100).verdict == Verdict.INCONCLUSIVE


def test_an_effect_shown_smaller_than_delta_never_reproduces():
    """The overlap of the old rule: two tight arms 0.02 apart, the interval wholly above 0 and wholly below delta.
    "Better" and "not better by delta" cannot both hold; delta decides, and the verdict is "does not"."""
    a = [0.520, 0.521, 0.519, 0.520, 0.522, 0.518, 0.520, 0.521, 0.519, 0.520]
    b = [0.500, 0.501, 0.499, 0.500, 0.502, 0.498, 0.500, 0.501, 0.499, 0.500]
    judgement = beats("a", a, "b", b, 0.05)
    interval = judgement.estimates[0].interval
    assert 0 < interval.low and interval.high < 0.05
    assert judgement.verdict == Verdict.DOES_NOT
    assert beats("a", a, "b", b, 0.05, paired=True).verdict == Verdict.DOES_NOT


@pytest.mark.parametrize(
    ("shift", "expected"),
    [
        (0.10, Verdict.REPRODUCES),  # interval wholly at or above delta
        (0.05, Verdict.INCONCLUSIVE),  # estimate on delta: the interval straddles it
        (0.00, Verdict.DOES_NOT),  # wholly below delta
        (-0.10, Verdict.DOES_NOT),  # worse
    ],
)
def test_each_side_of_delta(shift, expected):
    base = [0.50, 0.52, 0.48, 0.51, 0.49, 0.50, 0.53, 0.47, 0.50, 0.50]
    better = [v + shift for v in base]
    noisy = [v + d for v, d in zip(better, [0.01, -0.01, 0.0, 0.01, -0.01, 0.0, 0.01, -0.01, 0.0, 0.0], strict=True)]
    assert beats("a", noisy, "b", base, 0.05, paired=True).verdict == expected


def test_the_boundary_counts_as_shown():
    """Every difference exactly delta (binary fractions, so exactly): the interval is [delta, delta]. Its lower end on
    delta reproduces, as a lower end on tau solves; its upper end on delta denies nothing."""
    base = [1.0, 2.0, 3.0, 4.0]
    judgement = beats("a", [v + 0.25 for v in base], "b", base, 0.25, paired=True)
    assert (judgement.estimates[0].interval.low, judgement.estimates[0].interval.high) == (0.25, 0.25)
    assert judgement.verdict == Verdict.REPRODUCES
    assert beats("a", [v + 0.25 for v in base], "b", base, 0.5, paired=True).verdict == Verdict.DOES_NOT


def test_pairing_by_replicate_removes_what_the_replicates_share():
    """Two agents on the same replicates: a replicate effect much larger than the difference hides the difference
    from Welch's interval and not from the paired one."""
    replicate = [0.1, 0.5, 0.9, 0.3, 0.7, 0.2, 0.8, 0.4, 0.6, 0.5]
    a = [r + 0.10 for r in replicate]
    b = [r + d for r, d in zip(replicate, [0.01, -0.01, 0.0, 0.02, -0.02, 0.0, 0.01, -0.01, 0.0, 0.0], strict=True)]
    assert beats("a", a, "b", b, 0.05).verdict == Verdict.INCONCLUSIVE
    judgement = beats("a", a, "b", b, 0.05, paired=True)
    assert judgement.verdict == Verdict.REPRODUCES and "paired by replicate" in judgement.rule


def test_best_is_bonferroni_over_the_rivals():
    judgement = best("a", {"b": (HIGH, LOW, False), "c": (HIGH, LOW, False)}, 0.05, episodes=100)
    assert judgement.verdict == Verdict.REPRODUCES
    assert "97.5%" in judgement.rule and len(judgement.estimates) == 2
    near = [0.99, 0.99, 0.98, 0.99, 1.0]
    assert best("a", {"b": (HIGH, LOW, False), "c": (HIGH, near, True)}, 0.05, 100).verdict == Verdict.DOES_NOT
    assert bonferroni_level(4) == pytest.approx(1 - 0.05 / 4)


INF = float("inf")


def test_learning_faster_is_judged_on_censored_steps_to_the_threshold():
    # shares of the budget at which each replicate first reached 0.8; inf: never
    quick = [0.10, 0.12, 0.09, 0.11, 0.10, 0.13, 0.08, 0.12, 0.10, 0.11]
    slow = [0.30, 0.35, 0.28, 0.40, INF, 0.33, 0.31, INF, 0.29, 0.36]
    judgement = faster("a", quick, "b", slow, 0.05, paired=True)
    assert judgement.verdict == Verdict.REPRODUCES and "censored" in judgement.rule
    assert faster("b", slow, "a", quick, 0.05, paired=True).verdict == Verdict.DOES_NOT
    # a head start does not count: the same steps to the threshold is no faster, whatever the start
    assert faster("a", quick, "c", quick, 0.05, paired=True).verdict == Verdict.DOES_NOT
    # half or more of an arm's runs never hold the level: it has no median time within the budget, and its speed
    # is undefined (a verdict of its own, with its reason, and no interval), not infinitely slow
    never = [INF] * 10
    for judgement in (faster("a", quick, "n", never, 0.05, paired=True), faster("n", never, "m", never, 0.05, True)):
        assert judgement.verdict == Verdict.UNDEFINED and "never hold the level" in judgement.reason
        assert judgement.estimates == ()
    assert fastest("a", {"b": (quick, slow, True), "n": (quick, never, True)}, 0.05).verdict == Verdict.UNDEFINED
    assert fastest("a", {"b": (slow, quick, True), "n": (quick, never, True)}, 0.05).verdict == Verdict.DOES_NOT
    assert fastest("a", {"b": (quick, slow, True), "c": (quick, slow, True)}, 0.05).verdict == Verdict.REPRODUCES


def test_equivalence_within_and_outside_the_margin():
    close = {"10": [0.90, 0.92, 0.91, 0.93, 0.90], "30": [0.91, 0.92, 0.92, 0.90, 0.93]}
    assert equivalent(close, 0.1, episodes=1000).verdict == Verdict.REPRODUCES
    apart = {"10": LOW, "30": HIGH}
    assert equivalent(apart, 0.1, episodes=100).verdict == Verdict.DOES_NOT
    assert equivalent({"10": SPREAD, "30": HIGH}, 0.1, episodes=100).verdict == Verdict.INCONCLUSIVE


def test_all_of_needs_every_part_and_fails_on_any_failure():
    yes, no = solves("a", HIGH, 0.8, 100), solves("b", LOW, 0.8, 100)
    maybe = solves("c", SPREAD, 0.8, 100)
    assert all_of([yes, yes], "").verdict == Verdict.REPRODUCES
    assert all_of([yes, maybe], "").verdict == Verdict.INCONCLUSIVE
    assert all_of([yes, maybe, no], "").verdict == Verdict.DOES_NOT
    assert all_of([], "").verdict == Verdict.INCONCLUSIVE


def test_improvement_over_tasks():
    ours = [HIGH, [0.9, 0.85, 0.95, 0.9, 0.92]]
    theirs = [LOW, [0.1, 0.2, 0.15, 0.05, 0.1]]
    assert improves("a", ours, {"b": theirs}).verdict == Verdict.REPRODUCES
    assert improves("b", theirs, {"a": ours}).verdict == Verdict.DOES_NOT
