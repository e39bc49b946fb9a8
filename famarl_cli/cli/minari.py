"""``famarl export-minari``: a demos file as a Minari dataset, for offline-RL tools that read Minari."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from famarl_cli.cli import app, note, reports_errors
from famarl_cli.cli.derived import old_spelling


@app.command("export-minari")
@reports_errors
def export_minari(
    demos: Annotated[Path, typer.Argument(help="Demos HDF5 file (famarl demos).", dir_okay=False)],
    dataset_id: Annotated[
        str, typer.Option(help="Minari dataset id, [namespace/]name-v<version>, e.g. famarl/pushed-down-v0.")
    ],
    datasets_path: Annotated[
        Path | None,
        typer.Option(
            help="Folder of Minari datasets to write into.  [default: $MINARI_DATASETS_PATH, else ~/.minari/datasets]",
            file_okay=False,
        ),
    ] = None,
    root: Annotated[Path | None, typer.Option("--root", hidden=True, file_okay=False)] = None,
    overwrite: Annotated[bool, typer.Option(help="Replace a dataset of the same id.")] = False,
) -> None:
    """Export demos as a Minari dataset that minari.load_dataset(ID) opens, ground truth included (see
    famarl_cli.artifacts.minari_datasets), so that importing it gives back the same demos."""
    from famarl_cli.artifacts import read_demos
    from famarl_cli.artifacts.minari_datasets import export_minari as write_dataset

    # famarl docs --root is the project's root
    root = old_spelling("--root", "--datasets-path", root, datasets_path is not None) or datasets_path
    recorded = read_demos(demos)
    folder = write_dataset(recorded, dataset_id, root, overwrite=overwrite, on_note=note)
    table = Table(title=f"Minari dataset: {dataset_id}", show_header=False)
    table.add_row("dataset id", dataset_id)
    table.add_row("folder", str(folder))
    table.add_row("episodes", str(len(recorded.episodes)))
    table.add_row("steps", str(recorded.total_steps))
    Console().print(table)
