"""``famarl report``: every experiment's numbers beside the paper's claims, with verdicts and figures."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from famarl_cli.cli import app, reports_errors
from famarl_cli.errors import UsageError


@app.command()
@reports_errors
def report(
    experiment: Annotated[
        list[str] | None,
        typer.Option(
            "--experiment",
            "-e",
            help="Report only this experiment; repeat for several.  [default: every experiment with data: maze, "
            "scripts, beta, demos-count, traversal, robothand, macro-length]",
        ),
    ] = None,
    data: Annotated[Path, typer.Option(help="Where the pipelines wrote.", file_okay=False)] = Path("data"),
    out: Annotated[
        Path, typer.Option(help="Folder for report.md, summary.json and the figures.", file_okay=False)
    ] = Path("data/report"),
) -> None:
    """Gather the evaluations, training logs, FAVAE metrics and traversals of whatever runs exist into report.md:
    a table per experiment of the paper, our number beside the paper's claim, and a verdict."""
    from famarl_cli import __version__
    from famarl_cli.report import EXPERIMENTS, write_report

    names = experiment or list(EXPERIMENTS)
    unknown = [name for name in names if name not in EXPERIMENTS]
    if unknown:
        raise UsageError(f"unknown experiment {', '.join(unknown)} (known: {', '.join(EXPERIMENTS)})")
    sections = write_report(names, data, out, __version__)
    table = Table(title=f"{out / 'report.md'}")
    for column in ("experiment", "claims reproduced", "verdict"):
        table.add_column(column)
    for name, section in sections.items():
        table.add_row(name, f"{section.held} of {len(section.claims)}", section.verdict)
    Console().print(table)
