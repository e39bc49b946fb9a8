"""``famarl demos``: record scripted-expert demos."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from famarl_cli.artifacts import Demos
from famarl_cli.cli import JobRecipe, app, progress_bar, reports_errors, sweepable
from famarl_cli.errors import UsageError
from famarl_cli.experts.scripts import Environment, Script


@app.command()
@reports_errors
def demos(
    script: Annotated[
        Script,
        typer.Option(
            "--script", "-s", help="Expert script: the paper's four act in ContinuousWorld Base, pegging in RobotHand."
        ),
    ] = Script.PUSHED_DOWN_ONLY,
    env: Annotated[
        Environment | None,
        typer.Option(help="Environment family; optional, the script implies it.  [default: the script's]"),
    ] = None,
    episodes: Annotated[int, typer.Option(min=1, help="Number of episodes to record.")] = 100,
    seed: Annotated[int, typer.Option(help="Seed of the episodes' layouts; same seed, same file.")] = 0,
    out: Annotated[
        Path | None, typer.Option(help="Output HDF5 file.  [default: data/demos/<script>.h5]", dir_okay=False)
    ] = None,
    plot: Annotated[bool, typer.Option(help="Also draw the trajectories to <out>.png.")] = True,
) -> None:
    """Record scripted-expert demos (with their true phase boundaries and factors) to an HDF5 file."""
    if env is not None and env != script.environment:
        raise UsageError(f"script {script.value} acts in {script.environment}, not in {env.value}")
    from famarl_cli.artifacts import prepare_output, write_demos
    from famarl_cli.demos import record_demos
    from famarl_cli.plots import plot_demos

    out = prepare_output(out or Path("data/demos") / f"{script.value}.h5")
    with progress_bar() as progress:
        task = progress.add_task(f"demos {script.value}", total=episodes)
        recorded = record_demos(script, episodes, seed, on_episode=lambda _: progress.advance(task))
    write_demos(out, recorded)
    written = [out]
    if plot:
        written.append(out.with_suffix(".png"))
        plot_demos(recorded, written[-1])

    table = demos_table(recorded, f"demos: {script.value}")
    table.add_row("written", ", ".join(map(str, written)))
    Console().print(table)


@sweepable("demos", owned=("--out",))
def demos_job(params: dict) -> JobRecipe:
    """``famarl sweep demos``: each job records what ``famarl demos`` with the same options would, into
    ``<job folder>/demos.h5`` (and ``.png``)."""
    script, env = params["script"], params["env"]
    if env is not None and env != script.environment:
        raise UsageError(f"script {script.value} acts in {script.environment}, not in {env.value}")
    config = {"script": script.value, "episodes": params["episodes"], "seed": params["seed"], "plot": params["plot"]}
    return JobRecipe("famarl_cli.demos:run_job", config)


def demos_table(demos: Demos, title: str) -> Table:
    lengths = [e.length for e in demos.episodes]
    table = Table(title=title, show_header=False)
    table.add_row("script", demos.script)
    table.add_row("episodes", str(len(demos.episodes)))
    table.add_row("steps", str(demos.total_steps))
    table.add_row("success rate", f"{demos.success_rate:.1%}")
    table.add_row("episode length", f"{np.mean(lengths):.1f} mean, {min(lengths)}-{max(lengths)}")
    table.add_row("phases per episode", f"{np.mean([len(e.segment_starts) for e in demos.episodes]):.2f}")
    return table
