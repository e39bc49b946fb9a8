"""report.md, summary.json, metrics.json, the interval figures and the learning curves' CSV of the named
experiments."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from famarl_cli.artifacts import atomic_path
from famarl_cli.artifacts.base import write_json
from famarl_cli.artifacts.records import REPORT_FILE
from famarl_cli.core.errors import ArtifactError
from famarl_cli.core.reproducibility import machine
from famarl_cli.report.experiments import experiments
from famarl_cli.report.plots import plot_intervals
from famarl_cli.report.results import PAPER_AGENTS, write_curves
from famarl_cli.report.section import COUNTS, Section
from famarl_cli.report.verdicts import Verdict, family


def write_report(
    names: list[str], data: Path, out: Path, version: str, summary: Path | None = None
) -> dict[str, Section]:
    """Build the named experiments' sections from ``data`` into ``out``: report.md, the figures, the summary
    (``summary``, else ``out/summary.json``: each claim's verdict, estimates, intervals and rule, the headline
    numbers, and where and when they were made, for ``famarl docs``), beside it :data:`METRICS_FILE`
    (:func:`compared`, for ``dvc metrics show`` and ``dvc metrics diff``) and, for experiments with runs,
    ``<name>-curves.csv`` (their learning curves, for ``dvc plots show``: committed beside the summary, so that a
    fresh clone draws every pipeline's curves before running any). Experiments without data are listed with the
    command that makes them; it is an error when none of them has data."""
    known = experiments()
    # No mkdir: each file makes its folder as it is written (atomic_path), so a report of nothing leaves nothing.
    sections = {name: known[name].build(data, out) for name in names}
    built = {name: section for name, section in sections.items() if section is not None}
    if not built:
        repro = "; ".join(dict.fromkeys(f"`dvc repro {known[name].pipeline}`" for name in names))
        raise ArtifactError(
            f"{data}: nothing to report for {', '.join(names)} (run {repro} first, or `famarl evaluate --out`)"
        )
    summary = summary or out / "summary.json"
    for name, section in built.items():
        path = out / f"{name}-intervals.png"
        # the figure colours the three readings of an interval; an undefined claim's defined parts (a "fastest" with
        # one rival undefined) are drawn grey, as not decisive
        drawn = [
            replace(c, judgement=replace(c.judgement, verdict=Verdict.INCONCLUSIVE))
            if c.verdict == Verdict.UNDEFINED
            else c
            for c in section.claims
        ]
        plot_intervals(drawn, path, section.title)
        section.figures.insert(0, path.name)
        if section.groups:
            write_curves(section.groups, summary.with_name(f"{name}-curves.csv"))
    parts = [
        f"# famarl report\n\nfamarl {version}; numbers from `{data}`. Every verdict is reproduces, does not reproduce "
        "or inconclusive (a goal beyond the paper: met, missed or inconclusive), from 95% intervals over seeds with "
        "the rule beside it (docs/verdicts.md).\n"
    ]
    parts += [section.markdown() for section in built.values()]
    # the family over the whole report: a claim of one experiment that re-judges another's runs counts once
    every = family([claim for section in built.values() for claim in section.judged()])
    parts.append(f"## The family\n\nOver the {len(built)} experiments above: {every.text()}\n")
    missing = [name for name in names if name not in built]
    if missing:
        parts.append(
            "## Not run yet\n\n" + "\n".join(f"- {name}: `dvc repro {known[name].pipeline}`" for name in missing) + "\n"
        )
    with atomic_path(out / REPORT_FILE) as temp:
        temp.write_text("\n".join(parts))
    # What made the numbers, and nothing that changes with the day or the commit: the same runs on a machine of
    # the same kind give the same summary, byte for byte (when and at which revision the runs were made is in
    # benchmarks/pipeline_walls.json, which famarl docs shows beside the verdicts).
    made = {"machine": machine(), "famarl": version}
    write_json(summary, {name: {**s.summary(), "made": made} for name, s in built.items()})
    write_json(summary.with_name(METRICS_FILE), compared(list(built.values())))
    return built


METRICS_FILE = "metrics.json"


def compared(sections: list[Section]) -> dict:
    """The few numbers a user compares across pipelines and revisions: the claims and their verdicts' counts
    (summed over the experiments) and, for a report of one experiment, the sampled success of the paper's three
    agents where it runs them. The same keys in every pipeline, so ``dvc metrics show`` of all of them is one
    narrow table; everything else is in the summary."""
    counts = [section.summary() for section in sections]
    keys = ("claims", "reproduce", "do_not", "inconclusive")
    metrics = {key: sum(count[name] for count in counts) for key, name in zip(keys, COUNTS, strict=True)}
    headline = counts[0].get("headline", {}) if len(counts) == 1 else {}
    success = {agent: headline[agent]["success"] for agent in PAPER_AGENTS if agent in headline}
    return {**metrics, **({"success": success} if success else {})}
