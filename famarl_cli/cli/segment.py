"""``famarl segment``: cut demos into macro actions."""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from famarl_cli.artifacts.segments import Segments
from famarl_cli.cli import app, progress_bar, reports_errors, torch_on_one_thread


class Distance(StrEnum):
    EUCLIDEAN = "euclidean"
    NORMALISED = "normalised"


class LongSegments(StrEnum):
    SPLIT = "split"
    DROP = "drop"
    FAIL = "fail"


@app.command()
@reports_errors
def segment(
    demos: Annotated[Path, typer.Option(help="Demos HDF5 file to segment.")] = Path("data/demos/pushed-down-only.h5"),
    out: Annotated[
        Path | None,
        typer.Option(help="Output segments HDF5.  [default: data/segments/<demos name>.h5]", dir_okay=False),
    ] = None,
    encoder: Annotated[
        Path | None,
        typer.Option(help="Use this trained segmenter (a .segmenter.pt) instead of training one."),
    ] = None,
    window: Annotated[int, typer.Option(min=2, help="Steps per sliding window.")] = 4,
    peak_neighbours: Annotated[
        int, typer.Option(min=2, help="A peak is highest among this many adjacent points.")
    ] = 10,
    margin: Annotated[
        float,
        typer.Option(
            min=0.0,
            max=1.0,
            help="Peak threshold, as a fraction of the distance range over all episodes (the paper's value is 0.05; "
            "0.7 scored best on our demos, see docs/segmentation.md).",
        ),
    ] = 0.7,
    distance: Annotated[Distance, typer.Option(help="Distance between adjacent windows' codes.")] = Distance.EUCLIDEAN,
    length: Annotated[
        int | None, typer.Option(min=1, help="FAVAE input length L.  [default: longest segment, rounded up to 8]")
    ] = None,
    long: Annotated[
        LongSegments, typer.Option(help="Segments longer than L: split into pieces, drop, or fail.")
    ] = LongSegments.SPLIT,
    tolerance: Annotated[int, typer.Option(min=0, help="Boundary tolerance (steps) for the second F1.")] = 2,
    code_dim: Annotated[int, typer.Option(min=1, help="Size of the autoencoder's code.")] = 4,
    hidden: Annotated[int, typer.Option(min=1, help="Width of the autoencoder's hidden layer.")] = 32,
    epochs: Annotated[int, typer.Option(min=1, help="Training epochs of the autoencoder.")] = 300,
    seed: Annotated[int, typer.Option(help="Seed of the autoencoder's initialisation and batches.")] = 0,
    plot: Annotated[bool, typer.Option(help="Also draw distance curves and boundaries to <out>.png.")] = True,
    episodes: Annotated[
        int | None, typer.Option(min=1, help="Only the first this many episodes of the demos.  [default: all]")
    ] = None,
) -> None:
    """Cut demos into macro actions at the peaks of an autoencoder's code distance (paper Alg. 1)."""
    from famarl_cli.method.segmentation import SegmentParams
    from famarl_cli.stages import method as stages

    torch_on_one_thread()
    params = SegmentParams(peak_neighbours, margin, distance.value, length, long.value, tolerance, seed)
    segmenter = stages.SegmenterOptions(window=window, code_dim=code_dim, hidden=hidden, epochs=epochs)
    with progress_bar() as progress:
        task = progress.add_task("segmenter", total=epochs)
        result = stages.segment(
            demos,
            out or Path("data/segments") / f"{demos.stem}.h5",
            params,
            segmenter,
            encoder,
            plot,
            on_epoch=lambda epoch, mse: progress.update(task, advance=1, description=f"segmenter mse {mse:.2e}"),
            episodes=episodes,
        )
    segments, metrics = result.segments, result.metrics
    table = segments_table(segments, f"segments of {demos}")
    if metrics["boundaries_exact"] is None:
        table.add_row("boundary F1", "not measured (the demos have no ground-truth phases)")
    for key in ("boundaries_exact", f"boundaries_within_{tolerance}"):
        score = metrics[key]
        if score is None:
            continue
        table.add_row(
            f"boundary F1 (±{score['tolerance']})",
            f"{score['f1']:.3f}  (precision {score['precision']:.3f}, recall {score['recall']:.3f}; "
            f"{score['predicted']} found, {score['true']} true)",
        )
    table.add_row("written", ", ".join(map(str, result.written)))
    Console().print(table)


def segments_table(segments: Segments, title: str) -> Table:
    table = Table(title=title, show_header=False)
    episodes = len(segments.boundaries)
    table.add_row("segments", f"{len(segments.length)} ({len(segments.length) / episodes:.2f} per episode)")
    lengths = segments.length
    table.add_row("length", f"{lengths.mean():.1f} mean, {lengths.min()}-{lengths.max()}; L = {segments.max_length}")
    table.add_row("longer than L", f"{segments.n_split} split, {segments.n_dropped} dropped")
    return table
