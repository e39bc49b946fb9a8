"""``famarl macros``: learn a macro-action space from demos for one seed (segment, pre-run, fit, traverse)."""

from __future__ import annotations

import json

from rich.table import Table

from famarl_cli.cli import app, note, print_written, progress_bar, results_console
from famarl_cli.cli.derived import command
from famarl_cli.core.reproducibility import one_thread
from famarl_cli.stages.macros import FAVAE, MacrosOptions, macros_job
from famarl_cli.sweep.registry import sweepable


@command(app, MacrosOptions, "macros")
def macros(options: MacrosOptions) -> None:
    """Everything the method learns before RL, for one seed, into one folder: segments, C_last, FAVAE, traversal.

    The folder's files are those of famarl segment, favae calibrate, favae fit and traverse (the prior is famarl
    prior fit's, on the folder's segments and FAVAE), and job.json: what the folder is made from (options, the
    inputs' contents, famarl's version and source). A folder stopped part-way continues at the step it was in; a
    complete one is left as it is; one made from other inputs or options is refused unless --overwrite. famarl
    sweep macros runs this for many seeds (independent replicates).

    Its time with the defaults (100 demos): docs/performance.md, "each command with its defaults"; the default
    pipeline's 10 replicates with famarl sweep macros: docs/pipelines.md's wall table.
    """
    from famarl_cli.stages.macros import make_macros

    one_thread()
    out = options.destination
    with progress_bar() as progress:
        tasks: dict[str, int] = {}

        def show(phase: str, done: int, total: int) -> None:
            if phase not in tasks:
                tasks[phase] = progress.add_task(phase, total=total)
            progress.update(tasks[phase], completed=done)

        made = make_macros(options, show)
    if not made:
        note(f"{out} already holds these macros, complete; nothing to do")
    metrics = json.loads((out / FAVAE).with_suffix(".metrics.json").read_text())
    table = Table(title=f"macro actions of {options.demos or options.segments}, seed {options.seed}", show_header=False)
    table.add_row("KL per ladder", ", ".join(f"{k:.3f}" for k in metrics["kl_per_ladder"]))
    table.add_row("information per ladder", ", ".join(f"{k:.3f}" for k in metrics["information_per_ladder"]))
    table.add_row(
        "length accuracy", f"{metrics['length_accuracy']:.1%} exact, {metrics['length_within_one']:.1%} within one step"
    )
    table.add_row("MIG", metrics["mig_note"] if metrics["mig"] is None else f"{metrics['mig']:.3f}")
    results_console().print(table)
    if made:
        print_written([out])


sweepable("macros", MacrosOptions, owned=("--out", "--overwrite"))(macros_job)
