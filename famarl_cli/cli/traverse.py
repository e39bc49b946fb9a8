"""``famarl traverse``: latent traversal of a FAVAE."""

from __future__ import annotations

from dataclasses import replace

from rich.table import Table

from famarl_cli.cli import already_made, app, print_written, results_console
from famarl_cli.cli.derived import command
from famarl_cli.core.reproducibility import one_thread
from famarl_cli.stages.method import TraverseOptions


@command(app, TraverseOptions, "traverse")
def traverse(options: TraverseOptions) -> None:
    """Decode sweeps of single latent variables and draw the paths their macro actions take (paper Fig. 5). With
    the defaults (every variable of a 3-ladder FAVAE, four values), its time is in docs/performance.md, "each
    command with its defaults"."""
    from famarl_cli.stages import defaults
    from famarl_cli.stages import method as stages

    one_thread()
    # The default FAVAE is looked up once: the output's name and the traversal take it from the options.
    options = replace(options, favae=options.favae or defaults.favae("--favae"))
    model = options.favae
    stages.check_traverse(options)
    if already_made("famarl traverse", options, options.outputs()):
        return
    console = results_console()
    if defaults.is_main_jobs(model):
        console.print(f"traversing {model}: a FAVAE of the default pipeline (dvc repro)")
    result, carried = stages.traverse(options)
    table = Table(title=f"traversal of {model}", show_header=True)
    table.add_column("(ladder, index)")
    table.add_column("effect (m)", justify="right")
    measure, nats = carried.best or ("information", [None] * len(result.effects))
    table.add_column(f"{measure} (nats)", justify="right")
    table.add_column("decoded lengths")
    for (lad, i), effect, carries, lengths in zip(
        result.variables.tolist(), result.effects, nats, result.lengths, strict=True
    ):
        table.add_row(
            f"({lad},{i})", f"{effect:.3f}", "?" if carries is None else f"{carries:.3f}", " ".join(map(str, lengths))
        )
    console.print(table)
    for lad, total in carried.empty(result.variables.tolist()).items():
        console.print(
            f"ladder {lad} is empty: its variables carry {total:.3f} nats ({measure}) of the training data (under "
            f"{carried.EMPTY_BELOW:g}), so traversing them changes almost nothing"
        )
    print_written(options.outputs())
