"""The report: each experiment of the paper, our numbers beside the paper's claims, a three-way verdict per claim,
and the figures.

Each experiment lives in its own module of :mod:`famarl_cli.experiments`, with its claims, tables and figures; it
reads what its pipeline (``dvc.yaml`` at the root, or ``pipelines/<name>/``) left under ``data/``. A claim's
verdict comes from 95% intervals over seeds (:mod:`famarl_cli.verdicts`); its row shows the per-seed values, n,
the interval and the rule. The figures are PNG files; the learning curves are also a CSV that the pipelines
declare as DVC plots (``dvc plots show``, ``dvc plots diff``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from famarl_cli.artifacts import atomic_path
from famarl_cli.artifacts.base import write_json
from famarl_cli.errors import ArtifactError
from famarl_cli.results import Group, headline, write_curves
from famarl_cli.verdicts import Claim, Verdict

GOAL_WORDS = {Verdict.REPRODUCES: "met", Verdict.DOES_NOT: "missed", Verdict.INCONCLUSIVE: "inconclusive"}
"""How a section of goals (not the paper's claims) words the three verdicts."""


@dataclass
class Section:
    """An experiment's part of the report."""

    title: str
    claims: list[Claim]
    tables: list[str] = field(default_factory=list)
    figures: list[str] = field(default_factory=list)
    groups: list[Group] = field(default_factory=list)
    """The runs behind it: their learning curves go to ``<name>-curves.csv``, their numbers to summary.json."""
    goals: bool = False
    """Its claims are our goals beyond the paper (met, missed, inconclusive) rather than the paper's claims."""

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
            f"| {first} | per seed we measure | rule (95% intervals) | per-seed values; estimate [95% CI] | {last} |",
            "|---|---|---|---|---|",
        ]
        for c in self.claims:
            word = self.word(c.verdict)
            verdict = word if c.verdict == Verdict.REPRODUCES else f"**{word}**"
            lines.append(f"| {c.paper} | {c.measure} | {c.judgement.rule} | {c.per_seed()} | {verdict} |")
        for table in self.tables:
            lines += ["", table]
        lines += [""] + [f"![{name}]({name})" for name in self.figures]
        return "\n".join(lines).rstrip() + "\n"

    def summary(self) -> dict:
        return {
            "verdict": self.verdict,
            "claims": len(self.claims),
            "claims_reproduced": self.held,
            "claims_not_reproduced": self.count(Verdict.DOES_NOT),
            "claims_inconclusive": self.count(Verdict.INCONCLUSIVE),
            "verdicts": {c.paper: self.word(c.verdict) for c in self.claims},
            **({"headline": headline(self.groups)} if self.groups else {}),
        }


def write_report(names: list[str], data: Path, out: Path, version: str) -> dict[str, Section]:
    """Build the named experiments' sections from ``data`` into ``out``: report.md, the figures, summary.json
    (each claim's verdict and the headline numbers, for ``dvc metrics show`` and ``dvc exp show``) and, for
    experiments with runs, ``<name>-curves.csv`` (their learning curves, for ``dvc plots show``). Experiments
    without data are listed with the command that makes them; it is an error when none of them has data."""
    from famarl_cli.experiments import experiments
    from famarl_cli.plots import plot_intervals

    known = experiments()
    out.mkdir(parents=True, exist_ok=True)
    sections = {name: known[name].build(data, out) for name in names}
    built = {name: section for name, section in sections.items() if section is not None}
    if not built:
        raise ArtifactError(
            f"{data}: nothing to report for {', '.join(names)} (run `dvc repro` first, or `famarl evaluate --out`)"
        )
    for name, section in built.items():
        path = out / f"{name}-intervals.png"
        plot_intervals(section.claims, path, section.title)
        section.figures.insert(0, path.name)
        if section.groups:
            write_curves(section.groups, out / f"{name}-curves.csv")
    parts = [
        f"# famarl report\n\nfamarl {version}; numbers from `{data}`. Every verdict is reproduces, does not reproduce "
        "or inconclusive (a goal beyond the paper: met, missed or inconclusive), from 95% intervals over seeds with "
        "the rule beside it (docs/verdicts.md).\n"
    ]
    parts += [section.markdown() for section in built.values()]
    missing = [name for name in names if name not in built]
    if missing:
        parts.append(
            "## Not run yet\n\n" + "\n".join(f"- {name}: `dvc repro {known[name].pipeline}`" for name in missing) + "\n"
        )
    with atomic_path(out / "report.md") as temp:
        temp.write_text("\n".join(parts))
    write_json(out / "summary.json", {name: section.summary() for name, section in built.items()})
    return built
