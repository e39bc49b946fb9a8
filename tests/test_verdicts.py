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
    improves,
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
    [(LOW, Verdict.REPRODUCES), (HIGH, Verdict.DOES_NOT), (SPREAD, Verdict.INCONCLUSIVE)],
)
def test_fails(values, expected):
    assert fails("b", values, 0.5, episodes=100).verdict == expected


def test_seeds_all_at_one_are_judged_with_the_evaluations_noise():
    # Without the floor the interval would be [1, 1]; with it, 3 seeds of 10 episodes are not enough for >= 0.95.
    assert solves("a", [1.0, 1.0, 1.0], 0.8, episodes=100).verdict == Verdict.REPRODUCES
    judgement = solves("a", [1.0, 1.0, 1.0], 0.95, episodes=10)
    assert judgement.estimates[0].interval.low < 0.95
    assert judgement.verdict == Verdict.INCONCLUSIVE


def test_beats_needs_the_difference_above_zero_and_denies_it_below_delta():
    assert beats("a", HIGH, "b", LOW, 0.05, episodes=100).verdict == Verdict.REPRODUCES
    assert beats("b", LOW, "a", HIGH, 0.05, episodes=100).verdict == Verdict.DOES_NOT
    # Equal arms: the difference's upper end is above 0 but below no delta of 0.5: "not better by 0.5".
    assert beats("a", HIGH, "c", HIGH, 0.5, episodes=100).verdict == Verdict.DOES_NOT
    assert beats("a", HIGH, "c", HIGH, 0.01, episodes=100).verdict == Verdict.INCONCLUSIVE


def test_best_is_bonferroni_over_the_rivals():
    judgement = best("a", HIGH, {"b": LOW, "c": LOW}, 0.05, episodes=100)
    assert judgement.verdict == Verdict.REPRODUCES
    assert "97.5%" in judgement.rule and len(judgement.estimates) == 2
    assert best("a", HIGH, {"b": LOW, "c": [0.99, 0.99, 0.98, 0.99, 1.0]}, 0.05, 100).verdict == Verdict.DOES_NOT
    assert bonferroni_level(4) == pytest.approx(1 - 0.05 / 4)


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
