"""``famarl inspect``: check an artifact and summarise it."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from famarl_cli.cli import app, reports_errors
from famarl_cli.cli.demos import demos_table
from famarl_cli.cli.segment import segments_table


@app.command()
@reports_errors
def inspect(
    path: Annotated[Path, typer.Argument(help="Artifact to check: a demos or segments HDF5 file.")],
    plot: Annotated[Path | None, typer.Option(help="Draw a demos file's trajectories to this PNG.")] = None,
) -> None:
    """Check that a file is a valid artifact, and print what it holds and what made it."""
    from famarl_cli.artifacts import peek_schema, read_demos
    from famarl_cli.artifacts.demos import SCHEMA as DEMOS
    from famarl_cli.artifacts.segments import SCHEMA as SEGMENTS
    from famarl_cli.artifacts.segments import read_segments
    from famarl_cli.core.errors import ArtifactError
    from famarl_cli.report.plots import plot_demos

    schema = peek_schema(path)
    if schema == DEMOS:
        loaded = read_demos(path)
        table = demos_table(loaded, str(path))
        if plot:
            plot_demos(loaded, plot)
            table.add_row("written", str(plot))
    elif schema == SEGMENTS:
        loaded = read_segments(path)
        table = segments_table(loaded, str(path))
    else:
        raise ArtifactError(f"{path}: is a {schema!r} file; famarl inspect reads {DEMOS!r} and {SEGMENTS!r} files")
    made_by = loaded.provenance
    version = made_by.get("famarl_version")
    table.add_row("made by", f"{made_by.get('command')} {made_by.get('params')} (famarl {version})")
    Console().print(table)
