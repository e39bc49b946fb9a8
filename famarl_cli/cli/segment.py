"""``famarl segment``: cut demos into macro actions."""

from __future__ import annotations

from rich.console import Console
from rich.table import Table

from famarl_cli.artifacts.segments import Segments
from famarl_cli.cli import already_made, app, progress_bar
from famarl_cli.cli.derived import command
from famarl_cli.core.reproducibility import one_thread
from famarl_cli.stages.method import SegmentOptions


@command(app, SegmentOptions, "segment")
def segment(options: SegmentOptions) -> None:
    """Cut demos into macro actions at the peaks of an autoencoder's code distance (paper Alg. 1). With the
    defaults (100 demos, 300 segmenter epochs), its time is in docs/performance.md, "each command with its defaults"."""
    from famarl_cli.stages import method as stages

    if already_made("famarl segment", options, options.outputs()):
        return
    one_thread()
    with progress_bar() as progress:
        task = progress.add_task("segmenter", total=options.segment_epochs)
        result = stages.segment(
            options,
            on_epoch=lambda epoch, mse: progress.update(task, advance=1, description=f"segmenter mse {mse:.2e}"),
        )
    segments, metrics = result.segments, result.metrics
    table = segments_table(segments, f"segments of {options.demos}")
    if metrics["boundaries_exact"] is None:
        table.add_row("boundary F1", "not measured (the demos have no ground-truth phases)")
    # the tolerant score first: an exact match of the step is rare even for a cut in the right place
    tolerant = f"boundaries_within_{options.tolerance}"
    for key in dict.fromkeys((tolerant, "boundaries_exact")):
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
