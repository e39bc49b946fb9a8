"""Which judged claims are the paper's: every claim of every experiment is of one kind, decided from what
summary.json records of it (its words, rule, verdict and estimates) and from its experiment's registration
(:func:`famarl_cli.report.experiments.experiment`), in the report's order, by these rules, the first that applies:

- **duplicate**: the claim re-judges runs that an earlier experiment's claim already judged. Either its experiment
  says so (``rejudges``: a claim whose words differ from the other's, such as the scripts experiment's
  pushed-down-only claim, which reads the default pipeline's FaMARL runs), or an earlier experiment holds a claim
  that makes the same statement (the same words once :data:`VARIANT` labels are taken off, the same rule once
  confidence levels are taken off) on the same numbers (as many estimates, each with the same n and the same point
  estimate, which the level of an interval does not change): robothand-sensitivity's "[..., as
  pipelines/robothand]" claims, for one. Runs that all score zero cannot be told apart by their numbers, so the
  words and the rule must match as well; a claim without estimates (no runs, undefined) is matched only where its
  experiment says so.
- **ours**: a goal beyond the paper (its experiment is registered with ``goals``, or words a verdict "met" or
  "missed"), or a variant of the paper's claim that its words label (:data:`VARIANT`): a setting in brackets, "(ours
  ...)", "(variant: ...)", "(beyond the paper)", "(..., not the paper's)", or a leading "with <another procedure>: ".
- **paper**: every other claim: a claim the paper makes, judged on the configuration every pipeline runs by default.

The paper's tally (README) counts the claims of kind paper alone, so that no claim of the paper counts twice and
none of ours counts as the paper's.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

PAPER, OURS, DUPLICATE = "paper", "ours", "duplicate"
GOAL_VERDICTS = {"met", "missed"}
"""The verdicts only a goal beyond the paper takes (:data:`famarl_cli.report.section.GOAL_WORDS`)."""
VARIANT = re.compile(
    r"\s*\[.*\]"  # a setting of a sensitivity or calibration run: "[BallPlacing-v0, ball_reward 1000]"
    r"|\s*\((?:ours|beyond the paper|variant)\b[^)]*\)"  # "(ours: ...)", "(beyond the paper)", "(variant: ...)"
    r"|\s*\([^()]*\bnot the paper's\)"  # "(semi-MDP discounting, not the paper's)"
    r"|^with [^:]*: "  # "with the paper's FAVAE procedure: ": the same sentence judged on another procedure
)
"""The labels by which a claim's words mark it as a variant of the paper's claim."""
LEVEL = re.compile(r"\s*\d+(?:\.\d+)?%")


@dataclass(frozen=True)
class Kind:
    name: str
    """:data:`PAPER`, :data:`OURS` or :data:`DUPLICATE`."""
    of: str = ""
    """A duplicate's: the experiment whose claim it re-judges."""

    def text(self) -> str:
        return f"{self.name} (of {self.of})" if self.of else self.name


def statement(claim: str) -> str:
    """A claim's words without its variant labels: what it states."""
    return VARIANT.sub("", claim).strip()


def _key(claim: dict) -> tuple | None:
    """What two claims that re-judge the same runs by the same rule share; None for a claim without estimates."""
    estimates = claim.get("estimates") or []
    if not estimates:
        return None
    numbers = tuple((e.get("n"), e.get("estimate")) for e in estimates)
    return statement(claim["claim"]), LEVEL.sub("", claim.get("rule", "")), numbers


def kinds(sections: Sequence[tuple[str, Sequence[dict]]]) -> list[list[Kind]]:
    """The kind of each claim of ``sections`` (experiment name and its claims as summary.json's ``judged`` records
    them, in the report's order), by the module's rules: one list per section, one kind per claim."""
    from famarl_cli.report.experiments import experiments

    registered = experiments()
    seen_keys: dict[tuple, str] = {}
    seen_claims: set[tuple[str, str]] = set()
    found = []
    for name, judged in sections:
        entry = registered.get(name)
        declared = {claim: (other, theirs) for claim, other, theirs in entry.rejudges} if entry else {}
        goals = bool(entry and entry.goals) or any(c.get("verdict") in GOAL_VERDICTS for c in judged)
        mine = []
        for claim in judged:
            key, text = _key(claim), claim["claim"]
            if text in declared and declared[text] in seen_claims:
                mine.append(Kind(DUPLICATE, declared[text][0]))
            elif key is not None and key in seen_keys:
                mine.append(Kind(DUPLICATE, seen_keys[key]))
            elif goals or VARIANT.search(text):
                mine.append(Kind(OURS))
            else:
                mine.append(Kind(PAPER))
        for claim in judged:  # a section's claims are matched against earlier sections' only
            seen_claims.add((name, claim["claim"]))
            if (key := _key(claim)) is not None:
                seen_keys.setdefault(key, name)
        found.append(mine)
    return found
