"""``famarl traverse``: latent traversal of a FAVAE."""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from famarl_cli.cli import EnvKwargs, ObsDims, app, reports_errors, torch_on_one_thread
from famarl_cli.core.errors import UsageError
from famarl_cli.envs import DEFAULT_WORLD, WORLDS

World = StrEnum("World", {name.upper().replace("-", "_"): name for name in WORLDS})


@app.command()
@reports_errors
def traverse(
    model: Annotated[
        Path | None,
        typer.Option(
            help="FAVAE checkpoint (from famarl favae fit).  [default: data/favae/pushed-down-only.pt, else the main "
            "job's data/maze/macros/seed0/favae.pt]"
        ),
    ] = None,
    ladder: Annotated[
        int | None, typer.Option(help="Traverse this ladder's variables (from 1).  [default: all]")
    ] = None,
    index: Annotated[int | None, typer.Option(help="Only this variable of the ladder (from 1).")] = None,
    values: Annotated[str, typer.Option(help="Values the variable takes; write --values=-3,-1,1,3.")] = "-3,-1,1,3",
    out: Annotated[
        Path | None,
        typer.Option(help="Traversal HDF5.  [default: data/traverse/<model name>[-ladder<L>[-index<I>]].h5]"),
    ] = None,
    draw: Annotated[
        str,
        typer.Option(
            help="run: run the decoded macro actions in --world (or --env); values: draw the "
            "decoded sequences' first two dimensions as positions (sequences that are paths, e.g. 2D Reaching)."
        ),
    ] = "run",
    env: Annotated[
        str | None,
        typer.Option(
            help="Run the macro actions in this gymnasium env (each from reset(seed=0)) and draw --obs-dims of its "
            "observations.  [default: the empty --world]"
        ),
    ] = None,
    world: Annotated[
        World,
        typer.Option(
            help="famarl's env family whose empty world runs the macro actions from its centre (without --env)."
        ),
    ] = World(DEFAULT_WORLD),
    env_kwargs: EnvKwargs = None,
    obs_dims: ObsDims = "0,1",
    frames: Annotated[
        bool,
        typer.Option(
            help="With --env: also draw what the env renders at the end of each macro action (<out>.frames.png). "
            "MuJoCo envs need MUJOCO_GL=egl or osmesa without a display."
        ),
    ] = False,
) -> None:
    """Decode sweeps of single latent variables and draw the paths their macro actions take (paper Fig. 5)."""
    from famarl_cli.envs.external import parse_env_kwargs
    from famarl_cli.method.traversal import EMPTY_LADDER_NATS, empty_ladders, parse_dims, parse_values
    from famarl_cli.stages import method as stages

    torch_on_one_thread()
    if model is None:
        model = stages.default_favae()
        if model == stages.PIPELINE_FAVAE:
            Console().print(f"traversing {model}: replicate 0 of the default pipeline (dvc repro)")
    name = model.stem + (f"-ladder{ladder}" if ladder else "") + (f"-index{index}" if index else "")
    out = out or Path("data/traverse") / f"{name}.h5"
    if env is None and env_kwargs:
        raise UsageError("--env-kwargs goes with --env")
    dims = parse_dims(obs_dims)
    result, carried = stages.traverse(
        model,
        out,
        parse_values(values),
        ladder,
        index,
        draw,
        env,
        parse_env_kwargs(env_kwargs),
        dims,
        frames,
        str(world),
    )
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
    Console().print(table)
    empty = {} if carried.best is None else empty_ladders(result.variables.tolist(), nats)
    for lad, total in empty.items():
        Console().print(
            f"ladder {lad} is empty: its variables carry {total:.3f} nats ({measure}) of the training data (under "
            f"{EMPTY_LADDER_NATS:g}), so traversing them changes almost nothing"
        )
    written = [out, out.with_suffix(".png"), out.with_suffix(".json")] + (
        [out.with_suffix(".frames.png")] if frames else []
    )
    Console().print("written " + ", ".join(map(str, written)))
