"""``famarl report``: every experiment's numbers beside the paper's claims, with verdicts and figures."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from famarl_cli.cli import app, named_rows, reports_errors, results_console


@app.command()
@reports_errors
def report(
    experiment: Annotated[
        list[str] | None,
        typer.Option(
            "--experiment",
            "-e",
            metavar="<name>",
            help="Report only this experiment; repeat for several.  [default: every one in "
            "famarl_cli/report/experiments]",
        ),
    ] = None,
    data: Annotated[Path, typer.Option(help="Where the pipelines wrote.", file_okay=False)] = Path("data"),
    out: Annotated[
        Path,
        typer.Option(
            help="Folder for report.md, summary.json and the figures (beside the pipelines' reports in data/report, "
            "which only their DVC stages write).",
            file_okay=False,
        ),
    ] = Path("data/report/all"),
    summary: Annotated[
        Path | None,
        typer.Option(
            help="Where to write summary.json (verdicts, intervals, headline numbers; famarl docs reads it), and "
            "beside it metrics.json (the verdicts' counts and the agents' success: a pipeline's DVC metric).  "
            "[default: OUT/summary.json]",
            dir_okay=False,
        ),
    ] = None,
) -> None:
    """Gather the evaluations, training logs, FAVAE metrics and traversals of whatever runs exist into report.md:
    a table per experiment of the paper, our numbers beside the paper's claims, and a three-way verdict per claim
    (reproduces, does not reproduce, inconclusive) from 95% intervals over seeds. Each pipeline's report stage's
    time (its bootstraps and figures) is in docs/pipelines.md's wall table."""
    from famarl_cli.stages.report import make_report

    sections = make_report(experiment, data, out, summary)
    table = named_rows(f"{out / 'report.md'}", ("experiment", "claims", "reproduce", "do not", "inconclusive"))
    for name, section in sections.items():
        counts = section.summary()
        keys = ("claims", "claims_reproduced", "claims_not_reproduced", "claims_inconclusive")
        table.add_row(name, *(str(counts[key]) for key in keys))
    results_console().print(table)
