"""An experiment's part of the report: its claims with their three-way verdicts (from 95% intervals over seeds,
:mod:`famarl_cli.report.verdicts`; each row shows the per-seed values, n, the interval and the rule), its tables,
figures and the runs behind them.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

from famarl_cli.core.statistics import LEVEL, Interval
from famarl_cli.report.results import Group, head, headline, scores
from famarl_cli.report.verdicts import Claim, Estimate, Verdict, family

GOAL_WORDS = {
    Verdict.REPRODUCES: "met",
    Verdict.DOES_NOT: "missed",
    Verdict.INCONCLUSIVE: "inconclusive",
    Verdict.UNDEFINED: "undefined",
}
"""How a section of goals (not the paper's claims) words the three verdicts."""


@dataclass
class Section:
    """An experiment's part of the report."""

    title: str
    claims: list[Claim]
    tables: list[str | None] = field(default_factory=list)
    """Tables and figures (file names in the report's folder); None for one there is nothing to make of."""
    figures: list[str | None] = field(default_factory=list)
    groups: list[Group] = field(default_factory=list)
    """The runs behind it: their learning curves go to ``<name>-curves.csv``, their numbers to summary.json."""
    goals: bool = False
    """Its claims are our goals beyond the paper (met, missed, inconclusive) rather than the paper's claims."""
    instruments: dict[str, dict] = field(default_factory=dict)
    """What the experiment's instruments measured, by name: ``controls`` (per task, what a scripted controller
    reaches there: the task can be solved in its own physics and time limit), ``oracle`` (per task and agent, the
    share of layouts a search in the agent's action space solved). No verdicts; summary.json keeps each beside the
    claims."""

    def __post_init__(self) -> None:
        self.tables = [t for t in self.tables if t]
        self.figures = [f for f in self.figures if f]

    def word(self, verdict: Verdict) -> str:
        return GOAL_WORDS[verdict] if self.goals else verdict.value

    def count(self, verdict: Verdict) -> int:
        return sum(claim.verdict == verdict for claim in self.claims)

    @property
    def held(self) -> int:
        """How many of the claims reproduce."""
        return self.count(Verdict.REPRODUCES)

    @property
    def verdict(self) -> str:
        n = len(self.claims)
        counts = {v: self.count(v) for v in Verdict}
        if not self.goals and counts[Verdict.REPRODUCES] == n:
            return "reproduces"
        if not self.goals and counts[Verdict.DOES_NOT] == n:
            return "does not reproduce"
        return ", ".join(f"{counts[v]} of {n} {self.word(v)}" for v in Verdict if counts[v])

    def markdown(self) -> str:
        first, last = ("goal", "met?") if self.goals else ("the paper says", "verdict")
        lines = [
            f"## {self.title}: {self.verdict}",
            "",
            *head(f"{first} | per seed we measure | rule | per-seed values; estimate [95% CI unless marked] | {last}"),
        ]
        for c in self.claims:
            word = self.word(c.verdict)
            verdict = word if c.verdict == Verdict.REPRODUCES else f"**{word}**"
            lines.append(f"| {c.paper} | {c.measure} | {c.judgement.rule} | {c.per_seed()} | {verdict} |")
        lines += ["", family(self.judged()).text()]
        for table in self.tables:
            lines += ["", table]
        lines += [""] + [f"![{name}]({name})" for name in self.figures]
        return "\n".join(lines).rstrip() + "\n"

    def judged(self) -> list[dict]:
        """Each claim as summary.json records it: its verdict, rule, the reason where undefined, every estimate
        (:func:`estimate_record`) and its measure (what one seed contributes, for the table of every claim that
        ``famarl docs`` writes)."""
        return [
            {
                "claim": c.paper,
                "verdict": self.word(c.verdict),
                "rule": c.judgement.rule,
                **({"reason": c.judgement.reason} if c.judgement.reason else {}),
                **({"look": list(c.look)} if c.look else {}),
                "estimates": [estimate_record(e) for e in c.judgement.estimates],
                "measure": c.measure,
            }
            for c in self.claims
        ]

    def summary(self) -> dict:
        return {
            "verdict": self.verdict,
            "claims": len(self.claims),
            "claims_reproduced": self.held,
            "claims_not_reproduced": self.count(Verdict.DOES_NOT),
            # not decisive either way: inconclusive or undefined (the three counts add up to the claims, as readers
            # of earlier summaries expect); how many of them are undefined is counted apart
            "claims_inconclusive": self.count(Verdict.INCONCLUSIVE) + self.count(Verdict.UNDEFINED),
            "claims_undefined": self.count(Verdict.UNDEFINED),
            "verdicts": {c.paper: self.word(c.verdict) for c in self.claims},
            "judged": self.judged(),
            "family": asdict(family(self.judged())),
            **({"headline": headline(self.groups), "scores": scores(self.groups)} if self.groups else {}),
            **self.instruments,
        }


COUNTS = ("claims", "claims_reproduced", "claims_not_reproduced", "claims_inconclusive")
"""What every experiment's part of a summary holds (:meth:`Section.summary`), in the verdicts table's order."""
VALUE_DIGITS = 6
"""Per-replicate values are kept to this many decimals in summary.json (the interval to 4, as shown)."""


def _values(values: tuple[float, ...]) -> list[float]:
    return [round(v, VALUE_DIGITS) for v in values]


def estimate_interval(record: dict) -> Interval:
    """The interval of an estimate as summary.json records it (:func:`estimate_record`; 95% where a record is older
    than its level); KeyError where a number is missing, TypeError or ValueError where one is no number."""
    numbers = (record["estimate"], record["low"], record["high"], record.get("level", LEVEL))
    return Interval(*map(float, numbers))


def estimate_record(e: Estimate) -> dict:
    """An estimate as summary.json records it: its n (replicates per arm; the fewer, where a difference's arms
    differ; 0 where unknown), interval, level and threshold; the per-replicate values of a mean (``values``) or of
    each arm of a difference (``arms``: name, n, values; the interval's first minus its second) with whether they
    pair by replicate (``paired``); and, for success rates, the evaluation episodes behind each value
    (``episodes``). A censored time (never reached) is ``Infinity``. Summaries written before the values were kept
    hold only name, n (0 for a difference), interval and level: readers take what is there."""
    record = {
        "name": e.name,
        "n": e.n,
        "estimate": round(e.interval.estimate, 4),
        "low": round(e.interval.low, 4),
        "high": round(e.interval.high, 4),
        "level": e.interval.level,
        "reference": e.reference,
    }
    if e.values:
        record["values"] = _values(e.values)
    if e.arms:
        record["arms"] = [{"name": a.name, "n": len(a.values), "values": _values(a.values)} for a in e.arms]
    if e.paired is not None:
        record["paired"] = e.paired
    if e.episodes:
        record["episodes"] = e.episodes
    return record
