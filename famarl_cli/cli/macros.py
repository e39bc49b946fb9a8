"""``famarl macros``: learn a macro-action space from demos for one seed (segment, pre-run, fit, traverse)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import typer
from rich.table import Table

from famarl_cli.artifacts.made import Replaceable
from famarl_cli.cli import JobRecipe, app, print_written, progress_bar, results_console, sweepable, torch_on_one_thread
from famarl_cli.cli.derived import command
from famarl_cli.core.declare import option, pick, same_as, to_json
from famarl_cli.stages.macros import FAVAE, MacrosConfig


@dataclass(frozen=True)
class MacrosOptions(MacrosConfig):
    """``famarl macros``: a replicate's options and the folder it goes into."""

    out: Path | None = option(
        None, "Folder.  [default: data/macros/<demos or segments name>/seed<S>]", path="dir", affects=False
    )
    overwrite: bool = same_as(
        Replaceable,
        "overwrite",
        help="Start afresh where --out holds what other inputs or options made (or files by hand); without it, a "
        "folder made from the same inputs and options continues, or is left as it is where it is complete.",
    )


@command(app, MacrosOptions, "macros")
def macros(options: MacrosOptions) -> None:
    """Everything the method learns before RL, for one seed, into one folder: segments, C_last, FAVAE, traversal.

    The folder's files are those of famarl segment, favae calibrate, favae fit and traverse (the prior is famarl
    prior fit's, on the folder's segments and FAVAE), and job.json: what the folder is made from (options, the
    inputs' contents, famarl's version and source). A folder stopped part-way continues at the step it was in; a
    complete one is left as it is; one made from other inputs or options is refused unless --overwrite. famarl
    sweep macros runs this for many seeds (independent replicates).

    Time with the defaults (100 demos): about 45 s on one core of a 2-core AMD EPYC VM; 10 replicates with famarl
    sweep macros, about 2.5 minutes on 2 cores (docs/performance.md, docs/pipelines.md).
    """
    from famarl_cli.artifacts.lock import claim_folder
    from famarl_cli.stages.macros import learn_macros
    from famarl_cli.sweep.driver import make_in_folder
    from famarl_cli.sweep.plan import Job
    from famarl_cli.sweep.worker import name_of

    torch_on_one_thread()
    config, seed = pick(MacrosConfig, options), options.seed
    source = config.demos or config.segments
    out = options.out or Path("data/macros") / source.stem / f"seed{seed}"
    recipe = macros_job(options)
    job = Job("macros", name_of(recipe.runner), recipe.config, recipe.inputs, recipe.resumable)

    def work() -> None:
        with progress_bar() as progress:
            tasks: dict[str, int] = {}

            def show(phase: str, done: int, total: int) -> None:
                if phase not in tasks:
                    tasks[phase] = progress.add_task(phase, total=total)
                progress.update(tasks[phase], completed=done)

            learn_macros(config, out, show)

    with claim_folder(out):
        if not make_in_folder(out, job, options.overwrite, work):
            typer.echo(f"note: {out} already holds these macros, complete; nothing to do", err=True)
    metrics = json.loads((out / FAVAE).with_suffix(".metrics.json").read_text())
    table = Table(title=f"macro actions of {source}, seed {seed}", show_header=False)
    table.add_row("KL per ladder", ", ".join(f"{k:.3f}" for k in metrics["kl_per_ladder"]))
    table.add_row("information per ladder", ", ".join(f"{k:.3f}" for k in metrics["information_per_ladder"]))
    table.add_row(
        "length accuracy", f"{metrics['length_accuracy']:.1%} exact, {metrics['length_within_one']:.1%} within one step"
    )
    table.add_row("MIG", metrics["mig_note"] if metrics["mig"] is None else f"{metrics['mig']:.3f}")
    results_console().print(table)
    print_written([out])


@sweepable("macros", MacrosOptions, owned=("--out", "--overwrite"))
def macros_job(options: MacrosOptions) -> JobRecipe:
    """``famarl sweep macros``: each replicate is what ``famarl macros`` with the same options would make; the
    replicates of one setting are fitted in batches (famarl sweep --batch)."""
    from famarl_cli.stages.macros import run_jobs

    config = pick(MacrosConfig, options)
    return JobRecipe(run_jobs, to_json(config), tuple(map(str, config.inputs)), resumable=True, batched=True)
