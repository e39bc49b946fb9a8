"""``famarl macros``: learn a macro-action space from demos for one seed (segment, pre-run, fit, traverse)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from famarl_cli.cli import (
    EnvKwargs,
    JobRecipe,
    ObsDims,
    app,
    progress_bar,
    reports_errors,
    sweepable,
    torch_on_one_thread,
)
from famarl_cli.cli.favae import MAX_LADDERS, CalibrationBetaOption, DecoderOption, MeasureOption, ProgressiveOption
from famarl_cli.method.favae import CALIBRATION_BETA, DECODER, MEASURE, PROGRESSIVE, Capacity, Head


@app.command()
@reports_errors
def macros(
    demos: Annotated[Path | None, typer.Option(help="Demos HDF5 file to segment (or give --segments).")] = None,
    episodes: Annotated[
        int | None, typer.Option(min=1, help="Only the first this many episodes of --demos.  [default: all]")
    ] = None,
    segments: Annotated[
        Path | None, typer.Option(help="Use these segments (from famarl segment) instead of segmenting demos.")
    ] = None,
    calibration: Annotated[
        Path | None, typer.Option(help="C_last from famarl favae calibrate on --segments; without it the pre-run runs.")
    ] = None,
    out: Annotated[
        Path | None,
        typer.Option(help="Folder.  [default: data/macros/<demos or segments name>/seed<S>]", file_okay=False),
    ] = None,
    seed: Annotated[int, typer.Option(help="Seed of the segmenter, the pre-run and the fit.")] = 0,
    margin: Annotated[
        float, typer.Option(min=0.0, max=1.0, help="Segmentation peak threshold (famarl segment --margin).")
    ] = 0.7,
    segment_epochs: Annotated[int, typer.Option(min=1, help="Training epochs of the segmenter.")] = 300,
    beta: Annotated[float, typer.Option(min=0.0, help="FAVAE's weight of the capacity term.")] = 50.0,
    epochs: Annotated[int, typer.Option(min=1, help="Epochs of the pre-run and of the fit.")] = 1500,
    ladders: Annotated[int, typer.Option(min=1, max=MAX_LADDERS, help="FAVAE ladders.")] = 3,
    latent_dim: Annotated[int, typer.Option(min=1, help="Latent variables per ladder.")] = 2,
    head: Annotated[Head, typer.Option(help="FAVAE heads (famarl favae fit --head).")] = Head.FLATTEN,
    capacity: Annotated[
        Capacity, typer.Option(help="FAVAE capacities (famarl favae fit --capacity).")
    ] = Capacity.MEASURED,
    decoder: DecoderOption = DECODER,
    capacity_measure: MeasureOption = MEASURE,
    progressive: ProgressiveOption = PROGRESSIVE,
    calibration_beta: CalibrationBetaOption = CALIBRATION_BETA,
    length: Annotated[
        int | None,
        typer.Option(
            min=1, help="FAVAE input length L; longer segments are split.  [default: longest, rounded up to 8]"
        ),
    ] = None,
    values: Annotated[str, typer.Option(help="Traversal values; write --values=-3,-1,1,3.")] = "-3,-1,1,3",
    env: Annotated[
        str | None,
        typer.Option(
            help="Run the traversal's macro actions in this gymnasium env.  [default: the demos' env, where it is "
            "not famarl's own; famarl's env of the actions' size otherwise]"
        ),
    ] = None,
    env_kwargs: EnvKwargs = None,
    obs_dims: ObsDims = "0,1",
) -> None:
    """Everything the method learns before RL, for one seed, into one folder: segments, C_last, FAVAE, traversal.

    The folder's files are those of famarl segment, favae calibrate, favae fit and traverse. An interrupted folder
    continues at the step it was in. famarl sweep macros runs this for many seeds (independent replicates).
    """
    from famarl_cli.artifacts.lock import claim_folder
    from famarl_cli.stages.macros import learn_macros

    torch_on_one_thread()
    config = _config(locals())
    source = Path(config.demos or config.segments)
    out = out or Path("data/macros") / source.stem / f"seed{seed}"
    with claim_folder(out), progress_bar() as progress:
        tasks: dict[str, int] = {}

        def show(phase: str, done: int, total: int) -> None:
            if phase not in tasks:
                tasks[phase] = progress.add_task(phase, total=total)
            progress.update(tasks[phase], completed=done)

        metrics = learn_macros(config, out, show)
    table = Table(title=f"macro actions of {source}, seed {seed}", show_header=False)
    table.add_row("KL per ladder", ", ".join(f"{k:.3f}" for k in metrics["kl_per_ladder"]))
    table.add_row("information per ladder", ", ".join(f"{k:.3f}" for k in metrics["information_per_ladder"]))
    table.add_row("length accuracy", f"{metrics['length_accuracy']:.1%}")
    table.add_row("MIG", metrics["mig_note"] if metrics["mig"] is None else f"{metrics['mig']:.3f}")
    table.add_row("written", str(out))
    Console().print(table)


def _config(params: dict):
    from famarl_cli.envs.external import parse_env_kwargs
    from famarl_cli.method.traversal import parse_dims, parse_values
    from famarl_cli.stages.macros import MacrosConfig

    def text(path: Path | None) -> str | None:
        return None if path is None else str(path)

    return MacrosConfig(
        seed=params["seed"],
        demos=text(params["demos"]),
        episodes=params["episodes"],
        segments=text(params["segments"]),
        calibration=text(params["calibration"]),
        margin=params["margin"],
        segment_epochs=params["segment_epochs"],
        beta=params["beta"],
        epochs=params["epochs"],
        ladders=params["ladders"],
        latent_dim=params["latent_dim"],
        head=str(params["head"]),
        capacity=str(params["capacity"]),
        decoder=str(params["decoder"]),
        capacity_measure=str(params["capacity_measure"]),
        progressive=params["progressive"],
        calibration_beta=params["calibration_beta"],
        values=parse_values(params["values"]),
        length=params["length"],
        env=params["env"],
        env_kwargs=parse_env_kwargs(params["env_kwargs"]),
        obs_dims=list(parse_dims(params["obs_dims"])),
    )


@sweepable("macros", owned=("--out",))
def macros_job(params: dict) -> JobRecipe:
    """``famarl sweep macros``: each replicate is what ``famarl macros`` with the same options would make."""
    config = _config(params)
    return JobRecipe(
        "famarl_cli.stages.macros:run_job", config.to_dict(), tuple(map(str, config.inputs)), resumable=True
    )
