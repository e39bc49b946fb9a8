"""``famarl docs``: the README's and docs/' result tables, made from the committed metrics."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from famarl_cli.cli import ROOT, app, reports_errors


@app.command()
@reports_errors
def docs(
    root: ROOT = Path("."),
    check: Annotated[
        bool, typer.Option("--check", help="Write nothing; exit 1 when a table differs from the metrics.")
    ] = False,
) -> None:
    """Write the result tables of README.md and docs/ (verdicts, every claim's interval and rule, each pipeline's
    headline, pipeline walls, speed benchmarks, studies, and the options of every command by name) from each
    pipeline's committed summary.json, benchmarks/pipeline_walls.json, benchmarks/measured.json and
    studies/measured.json, between their marker comments; a pipeline whose
    code, params or command changed since its dvc.lock is marked stale. Takes a few seconds (it asks DVC which
    stages are stale)."""
    from famarl_cli.cli.names import names_table
    from famarl_cli.stages.report import make_docs

    changed, files = make_docs(root, check, names_table())
    typer.echo(f"{', '.join(changed) or 'nothing'} {'would change' if check else 'written'} ({', '.join(files)})")
