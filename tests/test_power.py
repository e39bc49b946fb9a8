"""``famarl power``: the replicates an inconclusive claim's rule needs to decide at 80% power (Colas et al. 2018),
and the n and per-replicate values summary.json keeps for it."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from cli_helpers import famarl, one_line_error
from scipy import stats

from famarl_cli.core.power import (
    difference_power,
    replicates_for_difference,
    replicates_for_mean,
    resampled_power,
)
from famarl_cli.core.statistics import paired_variance, success_interval
from famarl_cli.report.power import claims
from famarl_cli.report.section import Section
from famarl_cli.report.verdicts import Claim, Verdict, beats, equivalent, fails, faster, solves

NEAR = [0.62, 0.98, 0.71, 0.9, 0.84]
"""Five replicates whose mean (0.81) lies just above 0.8, too spread to show it."""
AT = [0.7, 0.9, 0.8, 0.75, 0.85]
"""Five replicates whose mean is 0.8 to the summary's four decimals."""


def summary_of(*judgements) -> dict:
    """The summary.json ``famarl report`` would write for claims judged so."""
    section = Section("test", [Claim(f"claim {i} [wide-bowl+{i}]", "success", j) for i, j in enumerate(judgements)])
    return {"test": json.loads(json.dumps(section.summary()))}


def test_the_sample_size_is_the_textbook_one():
    # Cohen (1988), two-sided 0.05 at 80% power: 64, 26, 17 per group for effect sizes 0.5, 0.8, 1; one sample at 0.5:
    # 34. G*Power gives the power at 64 per group for 0.5 as 0.8015.
    assert [replicates_for_difference(d, 1.0, 1.0) for d in (0.5, 0.8, 1.0)] == [64, 26, 17]
    assert replicates_for_mean(0.5, 1.0) == 34
    assert difference_power(64, 0.5, 1.0, 1.0) == pytest.approx(0.8015, abs=1e-4)
    assert difference_power(63, 0.5, 1.0, 1.0) < 0.8
    # the effect is the distance to the threshold, either way; none at all needs unbounded replicates
    assert replicates_for_mean(-0.5, 1.0) == 34 and replicates_for_mean(0.0, 1.0) == math.inf


def test_the_planned_replicates_decide_the_rule_four_times_in_five():
    """At the n planned, the rule's own interval clears the threshold in about 80% of draws: one arm (the t interval
    of "mean >= tau") and two unequal arms (Welch's interval of "a beats b by delta")."""
    rng = np.random.default_rng(0)
    draws = 4000
    n = replicates_for_mean(0.1, 0.2)
    x = rng.normal(0.6, 0.2, (draws, n))
    low = x.mean(1) - stats.t.ppf(0.975, n - 1) * x.std(1, ddof=1) / np.sqrt(n)
    assert (low >= 0.5).mean() == pytest.approx(0.8, abs=0.025)

    n = replicates_for_difference(0.1, 0.1, 0.3)
    a, b = rng.normal(0.25, 0.1, (draws, n)), rng.normal(0.1, 0.3, (draws, n))  # 0.15 - delta 0.05 = 0.1
    va, vb = a.var(1, ddof=1) / n, b.var(1, ddof=1) / n
    df = (va + vb) ** 2 / (va**2 / (n - 1) + vb**2 / (n - 1))
    low = a.mean(1) - b.mean(1) - stats.t.ppf(0.975, df) * np.sqrt(va + vb)
    assert (low >= 0.05).mean() == pytest.approx(0.8, abs=0.025)


def test_an_inconclusive_claim_needs_more_replicates_than_it_has():
    base = [0.5, 0.7, 0.6, 0.8, 0.4]
    noisy = [v + d for v, d in zip(base, [0.3, 0.0, 0.25, -0.05, 0.2], strict=True)]
    judgement = beats("a", noisy, "b", base, 0.05, paired=True)
    one_arm = solves("c", NEAR, 0.8)
    assert judgement.verdict == one_arm.verdict == Verdict.INCONCLUSIVE
    found = claims(summary_of(judgement, one_arm), "summary.json")
    paired, mean = (needed.deciding for needed in found)
    assert paired.basis == "values, paired differences" and paired.side == "reproduces" and paired.n == 5
    difference = np.mean(noisy) - np.mean(base)
    assert paired.needed == replicates_for_mean(difference - 0.05, np.std(np.subtract(noisy, base), ddof=1))
    assert paired.needed > 5
    assert mean.basis == "values" and mean.needed == replicates_for_mean(np.mean(NEAR) - 0.8, np.std(NEAR, ddof=1))
    assert mean.needed > 5


def test_the_paired_spread_is_the_one_the_rule_reads():
    """For rates, the paired interval's half-width is t sqrt(variance / n) with the variance power plans on."""
    from famarl_cli.core.statistics import paired_difference_interval

    a, b = np.array([1.0, 1.0, 1.0, 0.99]), np.array([0.98, 0.98, 0.98, 0.97])  # differences all but equal: floored
    interval = paired_difference_interval(a, b, episodes=100)
    half = stats.t.ppf(0.975, 3) * math.sqrt(paired_variance(a, b, 100) / 4)
    assert interval.high - interval.estimate == pytest.approx(half)
    assert paired_variance(a, b, 100) > paired_variance(a, b)


SPLIT_REACHING = [0.53, 0.58, 0.75, 0.68, 0.71, 0.43, 0.93, 0.5, 0.92, 0.3]
"""Ten replicates' success over 100 episodes, three of them non-learners (at or below 0.5), mean 0.63."""


def test_split_replicates_are_planned_on_the_rules_own_interval_by_resampling():
    """Where replicates split into learners and non-learners the rule reads the mixture interval, wider than the t
    interval: the need is found by resampling it, is more than the t plan's, and at the need fresh draws from the
    same values decide about four times in five, one replicate fewer less often."""
    judged = solves("famarl", SPLIT_REACHING, 0.8, episodes=100)
    assert judged.verdict == Verdict.INCONCLUSIVE
    (needed,) = claims(summary_of(judged), "summary.json")
    part = needed.deciding
    assert part.basis.startswith("values, resampled") and part.side == "does not"
    t_plan = replicates_for_mean(np.mean(SPLIT_REACHING) - 0.8, np.std(SPLIT_REACHING, ddof=1))
    assert math.isfinite(part.needed) and part.needed > t_plan

    def decides(sample):
        return success_interval(sample, 100).high < 0.8

    fresh = [resampled_power(SPLIT_REACHING, n, decides, draws=2000, seed=7) for n in (part.needed - 1, part.needed)]
    assert fresh[1] == pytest.approx(0.8, abs=0.04) and fresh[0] < fresh[1]


def test_replicates_all_at_zero_are_planned_on_the_count_of_learners_not_on_their_nil_sd():
    """Five replicates at zero against "fails" (<= 0.5): their sd is nil, so a t plan says two replicates, but the
    rule's interval is bounded by the exact count of learners, and only seven zeros bring its upper end under 0.5."""
    judged = fails("famarl", [0.0] * 5, 0.5, episodes=20)
    assert judged.verdict == Verdict.INCONCLUSIVE
    (needed,) = claims(summary_of(judged), "summary.json")
    assert needed.deciding.basis.startswith("values, resampled") and needed.deciding.needed == 7
    assert success_interval([0.0] * 6, 20).high >= 0.5 > success_interval([0.0] * 7, 20).high


def test_replicates_that_all_learned_are_planned_near_the_t_plan():
    """Where every replicate learned the rule's interval is the t interval, and resampling it asks about what the t
    plan asks."""
    learned = [0.62, 0.98, 0.91, 0.75, 0.99, 0.84]
    (needed,) = claims(summary_of(solves("c", learned, 0.8, episodes=100)), "summary.json")
    t_plan = replicates_for_mean(np.mean(learned) - 0.8, np.std(learned, ddof=1))
    assert needed.deciding.basis.startswith("values, resampled")
    assert 0.5 * t_plan <= needed.deciding.needed <= 2 * t_plan


def test_an_estimate_at_its_threshold_needs_unbounded_replicates():
    (needed,) = claims(summary_of(solves("a", AT, 0.8)), "summary.json")
    assert needed.deciding.needed == math.inf and needed.text() == "unbounded (at the threshold)"
    record = needed.record()
    assert record["unbounded"] and record["needed"] is None and record["parts"][0]["threshold"] == 0.8


def test_a_lower_bound_below_its_threshold_never_decides():
    from famarl_cli.report.verdicts import reaches

    (needed,) = claims(summary_of(reaches("macros", [0.1, 0.2, 0.15], 0.8, episodes=10)), "summary.json")
    assert needed.deciding.needed == math.inf and "lower bound" in needed.text()


def test_every_estimate_keeps_its_n_and_per_replicate_values_and_older_summaries_still_read():
    a, b = [0.9, 0.8, 0.85, 0.95], [0.7, 0.75, 0.8, 0.6, 0.65]
    judged = summary_of(
        beats("a", a, "b", b, 0.05, episodes=100),
        equivalent({"x": a, "y": a[::-1]}, 0.1, episodes=100),
        solves("c", NEAR, 0.8, episodes=100),
        faster("f", [0.2, 0.3, np.inf], "s", [0.5, 0.6, 0.7], 0.05, paired=True),
    )["test"]["judged"]
    welch, same, mean, speed = (claim["estimates"][0] for claim in judged)
    assert welch["n"] == 4 and welch["paired"] is False and welch["episodes"] == 100
    assert [(arm["name"], arm["n"], arm["values"]) for arm in welch["arms"]] == [("a", 4, a), ("b", 5, b)]
    assert same["n"] == 4 and same["arms"][1]["values"] == a[::-1] and same["reference"] == 0.1
    assert mean["n"] == 5 and mean["values"] == NEAR and "arms" not in mean and mean["episodes"] == 100
    # a speed's difference is the rival's time minus the candidate's; a run that never held the level is infinite
    assert speed["name"] == "s - f" and speed["paired"] and speed["arms"][1]["values"][-1] == math.inf

    # a summary written before: n 0 for a difference, no values or threshold; its need is a multiple of today's
    old = summary_of(beats("a", [0.5, 0.9, 0.6, 0.8], "b", [0.5, 0.7, 0.6, 0.6], 0.05, paired=True))
    for estimate in old["test"]["judged"][0]["estimates"]:
        estimate.update(n=0)
        for key in ("arms", "paired", "reference", "values", "episodes"):
            estimate.pop(key, None)
    (needed,) = claims(old, "summary.json")
    assert needed.deciding.basis == "interval (n not recorded)" and needed.deciding.times > 1
    assert needed.text().endswith("x today's n") and needed.deciding.threshold == 0.05


@pytest.fixture
def summary_file(tmp_path):
    path = tmp_path / "summary.json"
    path.write_text(json.dumps(summary_of(solves("c", NEAR, 0.8), solves("d", [0.9, 0.95, 0.92], 0.8))))
    return path


def test_famarl_power_json_lists_each_inconclusive_claim_with_its_need(summary_file, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")  # the table's columns whole beside a long temporary path
    result = famarl("power", "--summary", summary_file, "--json")
    assert result.exit_code == 0, result.output
    found = json.loads(result.stdout)
    assert found["power"] == 0.8 and [c["claim"] for c in found["claims"]] == ["claim 0 [wide-bowl+0]"]  # 1 holds
    (claim,) = found["claims"]
    assert claim["needed"] == replicates_for_mean(round(np.mean(NEAR), 4) - 0.8, np.std(NEAR, ddof=1))
    assert claim["summary"] == str(summary_file) and claim["parts"][0]["n"] == 5
    table = famarl("power", "--summary", summary_file)
    # a claim's setting in brackets is shown as words, not taken for rich markup
    assert table.exit_code == 0 and "claim 0 [wide-bowl+0]" in table.stdout and str(claim["needed"]) in table.stdout


@pytest.mark.parametrize(
    ("content", "needle"),
    [
        (None, "missing or unreadable"),
        ("{not json", "missing or unreadable"),
        ("[1, 2]", "not a summary famarl report writes"),
        ("{}", "not a summary famarl report writes (it holds no experiment)"),
        ('{"schema": "famarl.evaluation", "schema_version": 3}', "a famarl.evaluation record, not a summary"),
        ("BROKEN", "lacks a number among"),
    ],
)
def test_famarl_power_refuses_a_missing_or_malformed_summary_in_one_line(tmp_path, summary_file, content, needle):
    path = tmp_path / "bad.json"
    if content == "BROKEN":
        summary = json.loads(summary_file.read_text())
        del summary["test"]["judged"][0]["estimates"][0]["low"]
        content = json.dumps(summary)
    if content is not None:
        path.write_text(content)
    one_line_error(famarl("power", "--summary", path), 1, needle)


def test_famarl_power_without_summaries_needs_a_project(tmp_path):
    one_line_error(famarl("power", "--root", tmp_path), 1, "no dvc.yaml here")
    (tmp_path / "dvc.yaml").write_text("stages: {}\n")
    one_line_error(famarl("power", "--root", tmp_path), 1, "no summary.json")


def test_an_undefined_claim_is_listed_with_its_reason_and_no_number(tmp_path, monkeypatch):
    never = [math.inf] * 5
    path = tmp_path / "summary.json"
    path.write_text(
        json.dumps(summary_of(faster("f", never, "p", [0.2, 0.3, 0.2, 0.4, 0.3], 0.05), solves("c", NEAR, 0.8)))
    )
    monkeypatch.setenv("COLUMNS", "200")
    result = famarl("power", "--summary", path, "--json")
    assert result.exit_code == 0, result.output
    undefined, inconclusive = json.loads(result.stdout)["claims"]
    assert undefined["verdict"] == "undefined" and undefined["needed"] is None and "never" in undefined["why"]
    assert inconclusive["verdict"] == "inconclusive" and inconclusive["needed"] > 5
    table = famarl("power", "--summary", path)
    words = " ".join(table.stdout.replace("│", " ").split())  # the table and its footer wrap at the terminal's width
    assert "1 inconclusive claim and 1 undefined" in words and "more replicates alone do not" in words
