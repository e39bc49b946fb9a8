"""``famarl power``: for each inconclusive claim of the committed summaries, the replicates its rule needs to decide
at 80% power (:mod:`famarl_cli.core.power`, after Colas, Sigaud & Oudeyer 2018).

A claim's summary.json record (:func:`famarl_cli.report.section.estimate_record`) gives, per estimate, its interval,
level, threshold (``reference``), n and, in summaries written since they are kept, the per-replicate values: of a
mean (``values``) or of each arm of a difference (``arms``, with ``paired``). Each estimate whose interval still holds
its threshold (a *part* that is undecided) is planned on its own:

- the distance is the estimate's from its threshold (from the nearer end of an equivalence margin, -m or m);
- the spread is the values' where recorded (each arm's sample sd for an unpaired difference: Welch; the sd of the
  per-replicate differences where paired; one arm's sd; each floored, for success rates, as the rule floors it),
  else the interval's: its wider finite side as half-width (a side cut to the quantity's range is the narrower),
  with its n (:func:`~famarl_cli.core.power.spread_from_interval`), or, where n is not recorded (differences in
  summaries written before it was), a multiple of today's replicates
  (:func:`~famarl_cli.core.power.times_today`).

An estimate at its threshold needs unbounded n; an interval that is unbounded has no spread to scale. A rule that
reads a lower bound ("never does not") can only reproduce: where its estimate lies below the threshold no n decides
it. Intervals of medians or bootstraps are planned as if they were t intervals of the same width: an approximation.

A claim of several parts decides when every part reproduces or one does not: where some undecided part's estimate
lies on its does-not side, the claim needs the fewest replicates of those parts (one deciding is enough); otherwise
the most over its undecided parts (each at 80%: together less). Summaries written before thresholds were recorded
(no ``reference``) give them in the rule's words, read back where the rule names one threshold.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from famarl_cli.core.errors import ArtifactError
from famarl_cli.core.power import (
    LIMIT,
    POWER,
    RESAMPLED_LIMIT,
    replicates_by_resampling,
    replicates_for_difference,
    replicates_for_mean,
    spread_from_interval,
    times_today,
)
from famarl_cli.core.statistics import Interval, floored_variance, paired_variance, success_interval
from famarl_cli.report.section import estimate_interval

INCONCLUSIVE, UNDEFINED = "inconclusive", "undefined"
NUMBER = r"(-?\d+(?:\.\d+)?(?:e-?\d+)?|1/2)"
THRESHOLD_WORDS = (
    rf"(?:lower|upper) end (?:>=|>|<=|<) {NUMBER}",
    rf"\bmean (?:>=|<=) {NUMBER}",
    rf"\bdelta {NUMBER}",
    rf"inside \(-{NUMBER}, ",
)
"""Where a rule's words name its threshold (summaries written before ``reference`` was recorded)."""
REPRODUCES, DOES_NOT = "reproduces", "does not"


def _number(value: float) -> float | None:
    """A JSON number, or null for an unbounded end (JSON has no infinity)."""
    return value if math.isfinite(value) else None


@dataclass(frozen=True)
class Part:
    """One undecided estimate of a claim and what it needs."""

    name: str
    interval: Interval
    threshold: float | None
    n: int
    """Today's replicates per arm (0: not recorded)."""
    needed: float | None
    """Replicates per arm at :data:`POWER`: an int, inf where no n decides it, None where unknown."""
    times: float | None = None
    """Where n is not recorded: the replicates needed as a multiple of today's."""
    basis: str = ""
    """What the spread was taken from."""
    side: str = ""
    """Which way the estimate points: :data:`REPRODUCES` or :data:`DOES_NOT` ("" at the threshold or unknown)."""
    why: str = ""
    """Why ``needed`` is unbounded or unknown."""

    @property
    def scale(self) -> float | None:
        """The need as a multiple of today's replicates (to compare parts of one claim)."""
        if self.needed is None and self.times is None:
            return None
        if self.needed is not None and (math.isinf(self.needed) or not self.n):
            return self.needed
        return self.needed / self.n if self.needed is not None else self.times

    def text(self) -> str:
        if self.needed is not None and math.isfinite(self.needed):
            return f"{int(self.needed)}"
        if self.times is not None and math.isfinite(self.times):
            return f"{self.times:.1f}x today's n"
        unbounded = self.needed is not None or self.times is not None
        return f"{'unbounded' if unbounded else 'unknown'} ({self.why})"

    def record(self) -> dict:
        finite = self.needed is not None and math.isfinite(self.needed)
        times = self.times is not None and math.isfinite(self.times)
        return {
            "name": self.name,
            "estimate": self.interval.estimate,
            "low": _number(self.interval.low),
            "high": _number(self.interval.high),
            "level": self.interval.level,
            "threshold": self.threshold,
            "n": self.n,
            "needed": int(self.needed) if finite else None,
            "times_today": round(self.times, 2) if times else None,
            "unbounded": (self.needed is not None and math.isinf(self.needed))
            or (self.times is not None and math.isinf(self.times)),
            "side": self.side or None,
            "basis": self.basis,
            "why": self.why,
        }


@dataclass(frozen=True)
class Needed:
    """An inconclusive claim of one summary, its undecided parts and what the claim needs; or an undefined one
    (``undefined``), whose measure has no value, so that no number of replicates is named for it."""

    summary: str
    experiment: str
    claim: str
    rule: str
    parts: tuple[Part, ...]
    deciding: Part | None
    """The part whose need is the claim's (None where no part's need is known)."""
    why: str = ""
    undefined: bool = False

    def text(self) -> str:
        if self.undefined:
            return f"undefined ({self.why}): more replicates alone do not give its measure a value"
        if self.deciding is None:
            return f"unknown ({self.why})"
        return self.deciding.text()

    def record(self) -> dict:
        deciding = self.deciding.record() if self.deciding else None
        return {
            "summary": self.summary,
            "experiment": self.experiment,
            "claim": self.claim,
            "verdict": UNDEFINED if self.undefined else INCONCLUSIVE,
            "rule": self.rule,
            "needed": deciding["needed"] if deciding else None,
            "times_today": deciding["times_today"] if deciding else None,
            "unbounded": deciding["unbounded"] if deciding else False,
            "deciding_part": deciding["name"] if deciding else None,
            "why": self.why if deciding is None else deciding["why"],
            "parts": [part.record() for part in self.parts],
        }


def threshold_in_words(rule: str) -> float | None:
    """The one threshold a rule's words name, or None where they name none or several."""
    found = {match for words in THRESHOLD_WORDS for match in re.findall(words, rule)}
    values = {0.5 if found_ == "1/2" else float(found_) for found_ in found}
    return values.pop() if len(values) == 1 else None


def sense(rule: str) -> str:
    """Which side of its threshold a rule reproduces on: ``above``, ``below`` or ``inside`` (an equivalence
    margin), from its words."""
    if "inside (-" in rule:
        return "inside"
    if re.search(r"upper end <=? \S+ (?:reproduces|met)", rule) or re.search(r"\bmean <= ", rule):
        return "below"
    return "above"


def _finite(values) -> np.ndarray | None:
    """Per-replicate values to take a spread from: two or more, all finite (a censored time is not)."""
    try:
        array = np.asarray(values, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise ArtifactError(f"per-replicate values that are not numbers ({exc})") from exc
    return array if len(array) >= 2 and np.isfinite(array).all() else None


def _spread(
    estimate: dict, level: float, threshold: float, distance: float
) -> tuple[float | None, float | None, str, str]:
    """(needed, times_today, basis, why) of an estimate ``distance`` from its ``threshold``."""
    episodes = estimate.get("episodes")
    arms = estimate.get("arms") or []
    if not isinstance(arms, list) or not all(isinstance(arm, dict) for arm in arms):
        raise ArtifactError("its arms are not a list of records")
    if len(arms) == 2:
        a, b = (_finite(arm.get("values", [])) for arm in arms)
        if a is not None and b is not None:
            if estimate.get("paired") and len(a) == len(b):
                spread = math.sqrt(paired_variance(a, b, episodes))
                return replicates_for_mean(distance, spread, level), None, "values, paired differences", ""
            sd_a, sd_b = (math.sqrt(floored_variance(x, episodes)) for x in (a, b))
            return replicates_for_difference(distance, sd_a, sd_b, level), None, "values, Welch", ""
    values = _finite(estimate.get("values", []))
    if values is not None and episodes:
        above = estimate["estimate"] > threshold

        def decides(sample: np.ndarray) -> bool:
            interval = success_interval(sample, episodes, level)
            return interval.low >= threshold if above else interval.high < threshold

        return replicates_by_resampling(values, decides), None, "values, resampled (the rule's own interval)", ""
    if values is not None:
        return replicates_for_mean(distance, math.sqrt(floored_variance(values, episodes)), level), None, "values", ""
    sides = (estimate["estimate"] - estimate["low"], estimate["high"] - estimate["estimate"])
    sides = [side for side in sides if math.isfinite(side)]
    if not sides:
        return None, None, "interval", "interval unbounded"
    half, n = max(sides), int(estimate.get("n") or 0)
    if n >= 2:
        return replicates_for_mean(distance, spread_from_interval(half, n, level), level), None, "interval and n", ""
    return None, times_today(half, distance, level), "interval (n not recorded)", ""


def _beyond(needed: float | None, basis: str) -> str:
    limit = RESAMPLED_LIMIT if "resampled" in basis else LIMIT
    return f"more than {limit:,}" if needed is not None and math.isinf(needed) else ""


def part(estimate: dict, rule: str) -> Part | None:
    """What one estimate of an inconclusive claim needs, or None where its interval already decides it."""
    try:
        interval = estimate_interval(estimate)
        name = str(estimate["name"])
        reference = estimate.get("reference")
        threshold = float(reference) if reference is not None else threshold_in_words(rule)
        n = int(estimate.get("n") or 0)
    except (KeyError, TypeError, ValueError) as exc:
        raise ArtifactError(
            f"an estimate lacks a number among name, estimate, low, high, reference, n ({exc!r})"
        ) from exc
    if threshold is None:
        return Part(name, interval, None, n, None, why="threshold not recorded")
    way = sense(rule)
    thresholds = (-abs(threshold), abs(threshold)) if way == "inside" else (threshold,)
    lower_bound = "never does not" in rule
    below = interval.estimate < threshold
    if not any(interval.low <= t <= interval.high for t in thresholds) and not (lower_bound and below):
        return None
    nearest = min(thresholds, key=lambda t: abs(interval.estimate - t))
    distance = abs(interval.estimate - nearest)
    if way == "inside":
        side = REPRODUCES if abs(interval.estimate) < abs(threshold) else DOES_NOT
    else:
        side = REPRODUCES if (interval.estimate > threshold) == (way == "above") else DOES_NOT
    if distance == 0:
        return Part(name, interval, threshold, n, math.inf, why="at the threshold")
    if lower_bound and side == DOES_NOT:
        why = "below the threshold; a lower bound never shows less"
        return Part(name, interval, threshold, n, math.inf, side=side, why=why)
    needed, times, basis, why = _spread(estimate, interval.level, nearest, distance)
    return Part(name, interval, threshold, n, needed, times, basis, side, why or _beyond(needed, basis))


def deciding(parts: list[Part]) -> Part | None:
    """The part whose need is the claim's: of the parts on their does-not side, the one that needs least (one
    deciding does); else the one that needs most (every part must). None where that need is unknown."""
    against = [p for p in parts if p.side == DOES_NOT and p.scale is not None and math.isfinite(p.scale)]
    if against:
        return min(against, key=lambda p: p.scale)
    if not parts or any(p.scale is None for p in parts):
        return None
    return max(parts, key=lambda p: p.scale)


def claims(summary: dict, source: str) -> list[Needed]:
    """The inconclusive claims of one summary (``famarl report``'s, :func:`famarl_cli.report.docs.read_summary`),
    each with what it needs, and its undefined ones with their reason; ``source`` names the file in errors."""
    found = []
    for experiment, section in summary.items():
        judged = section.get("judged", [])
        if not isinstance(judged, list):
            raise ArtifactError(f"{source}: experiment {experiment!r}: judged is not a list of claims")
        for claim in judged:
            if not isinstance(claim, dict) or not {"claim", "verdict", "rule"} <= set(claim):
                raise ArtifactError(f"{source}: experiment {experiment!r}: a judged claim lacks claim, verdict or rule")
            if claim["verdict"] == UNDEFINED:
                reason = str(claim.get("reason") or "no reason recorded")
                found.append(Needed(source, experiment, claim["claim"], claim["rule"], (), None, reason, True))
                continue
            if claim["verdict"] != INCONCLUSIVE:
                continue
            estimates = claim.get("estimates", [])
            if not isinstance(estimates, list) or not all(isinstance(e, dict) for e in estimates):
                raise ArtifactError(f"{source}: claim {claim['claim']!r}: estimates is not a list of records")
            try:
                parts = [p for p in (part(e, str(claim["rule"])) for e in estimates) if p is not None]
            except ArtifactError as exc:
                raise ArtifactError(f"{source}: claim {claim['claim']!r}: {exc}") from exc
            chosen, why = deciding(parts), "no estimate holds its threshold" if estimates else "nothing was run"
            if chosen is None and parts:
                why = next((p.why for p in parts if p.scale is None), "")
            found.append(Needed(source, experiment, claim["claim"], claim["rule"], tuple(parts), chosen, why))
    return found


def plan(summaries: list[tuple[str, dict]]) -> list[Needed]:
    """:func:`claims` of every (source, summary)."""
    return [needed for source, summary in summaries for needed in claims(summary, source)]


def record(found: list[Needed]) -> dict:
    """What ``famarl power --json`` prints."""
    return {"power": POWER, "claims": [needed.record() for needed in found]}
