"""The family statement (docs/verdicts.md, "The family") checked by simulation where it is hardest: every truth at
its threshold, where a decisive verdict is as likely wrong as right."""

from __future__ import annotations

import numpy as np
import pytest

from famarl_cli.core.errors import ArtifactError
from famarl_cli.core.statistics import LEVEL
from famarl_cli.report.verdicts import (
    WRONG_PER_CLAIM,
    Looks,
    Verdict,
    beats,
    fails,
    family,
    near_threshold,
    solves,
)

TAU, DELTA, N, FAMILIES = 0.8, 0.05, 10, 400


def judged(judgement, claim: str) -> dict:
    """A judgement as summary.json records it (what :func:`family` reads)."""
    return {
        "claim": claim,
        "verdict": judgement.verdict.value,
        "rule": judgement.rule,
        "estimates": [
            {
                "name": e.name,
                "estimate": e.interval.estimate,
                "low": e.interval.low,
                "high": e.interval.high,
                "level": e.interval.level,
                "reference": e.reference,
            }
            for e in judgement.estimates
        ],
    }


def test_with_truths_at_the_thresholds_the_wrong_verdicts_stay_within_the_statement():
    """Families of 12 claims ("solves", "fails" and "beats", four each), each truth exactly at its threshold (normal
    per-replicate values, n = 10). At the threshold "solves" and "beats" are true, so only "does not" is wrong;
    "fails" (mean <= tau) is true too, only "does not" is wrong. The count of wrong verdicts per family stays within
    the statement's bound, while half or more of the decisive verdicts are wrong: the old statement (each decisive
    verdict wrong with probability at most 5%) was false."""
    rng = np.random.default_rng(0)
    wrong, decisive, bound = [], 0, None
    for f in range(FAMILIES):
        claims, errors = [], 0
        for i in range(4):
            values = rng.normal(TAU, 0.1, N)
            for judgement, name in (
                (solves("a", values, TAU), f"solves {i}"),
                (fails("b", values, TAU), f"fails {i}"),
                (beats("a", rng.normal(DELTA, 0.1, N), "b", np.zeros(N), DELTA, paired=True), f"beats {i}"),
            ):
                claims.append(judged(judgement, f"{name} of family {f}"))
                errors += judgement.verdict == Verdict.DOES_NOT
                decisive += judgement.verdict != Verdict.INCONCLUSIVE
        stated = family(claims)
        assert stated.claims == 12 and stated.duplicates == 0
        bound = stated.expected_wrong
        wrong.append(errors)
    mean, se = np.mean(wrong), np.std(wrong) / np.sqrt(FAMILIES)
    assert bound == WRONG_PER_CLAIM * 12
    assert mean <= bound + 3 * se, (mean, bound)
    assert mean >= bound / 2  # at the threshold the bound is nearly reached: it is not loose there
    assert sum(wrong) / decisive >= 0.3  # a large share of the decisive verdicts is wrong at the threshold


def test_claims_that_rejudge_the_same_runs_count_once_and_near_verdicts_are_listed():
    values = np.array([0.84, 0.89, 0.87, 0.86, 0.90, 0.85, 0.88, 0.87, 0.86, 0.88])
    near = judged(solves("a", values, 0.85), "near")
    far = judged(solves("a", values + 0.1, 0.85), "far")
    again = {**near, "claim": "the same runs, another sentence"}
    stated = family([near, far, again, {"claim": "not run", "verdict": "inconclusive", "rule": "", "estimates": []}])
    assert (stated.claims, stated.duplicates, stated.decisive) == (2, 1, 2)
    assert stated.near == ("near",)
    assert "at most 5%" not in stated.text() and "near" in stated.text()
    # the rule: the threshold within one half-width beyond the interval's near end
    assert near_threshold({"estimate": 0.9, "low": 0.86, "high": 0.94, "reference": 0.85})
    assert not near_threshold({"estimate": 0.9, "low": 0.88, "high": 0.92, "reference": 0.85})
    assert near_threshold({"estimate": 0.1, "low": 0.06, "high": 0.14, "reference": 0.15})
    assert not near_threshold({"estimate": 0.1, "low": 0.0, "high": 0.2, "reference": 0.15})  # straddles
    assert not near_threshold({"estimate": 0.9, "low": 0.86, "high": 0.94, "reference": None})


def sequential_errors(levels, rng, runs: int = 4000) -> float:
    """The share of runs of a sequential claim ("solves", truth at its threshold, so only "does not" is wrong) that
    end wrong, replicates added 5 at a time from 5 to 20 and judged at each look at ``levels(n)`` until decided."""
    wrong = 0
    for _ in range(runs):
        values = rng.normal(TAU, 0.1, 20)
        for n in (5, 10, 15, 20):
            verdict = solves("a", values[:n], TAU, level=levels(n)).verdict
            if verdict != Verdict.INCONCLUSIVE:
                wrong += verdict == Verdict.DOES_NOT
                break
    return wrong / runs


@pytest.mark.slow  # a simulation of thousands of claims
def test_replicates_added_in_blocks_err_at_most_twice_one_look_and_count_twice():
    """The blocks' levels (docs/verdicts.md, "Replicates added in blocks") keep a claim's error, truth at its
    threshold, within twice one look's; every look at the first look's level would not."""
    looks = Looks(first=5)
    assert (looks.count, [looks.look(n) for n in (5, 6, 10, 11, 20)]) == (4, [1, 2, 2, 3, 4])
    assert looks.level(5) == LEVEL and looks.level(10) == looks.level(20) == 1 - (1 - LEVEL) / 3
    assert looks.of(5) is None and looks.of(15) == (3, 4)
    with pytest.raises(ArtifactError, match="more than the 20"):
        looks.look(21)
    rng = np.random.default_rng(1)
    planned, naive = sequential_errors(looks.level, rng), sequential_errors(lambda n: LEVEL, rng)
    se = np.sqrt(2 * WRONG_PER_CLAIM / 4000)
    assert planned <= 2 * WRONG_PER_CLAIM + 3 * se, planned
    assert naive > planned
    late = {**judged(solves("a", np.full(10, 0.9), TAU), "late"), "look": [2, 4]}
    first = judged(solves("b", np.full(5, 0.95), TAU), "first")
    stated = family([late, first])
    assert stated.late == 1 and stated.expected_wrong == WRONG_PER_CLAIM * 3 and "counted twice" in stated.text()
