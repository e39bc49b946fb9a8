"""``famarl traverse``: latent traversal of a FAVAE."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from famarl_cli.cli import app, reports_errors, torch_on_one_thread


@app.command()
@reports_errors
def traverse(
    model: Annotated[Path, typer.Option(help="FAVAE checkpoint (from famarl favae fit).")] = Path(
        "data/favae/pushed-down-only.pt"
    ),
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
            help="run: run the decoded macro actions in the environment that takes their size; values: draw the "
            "decoded sequences' first two dimensions as positions (sequences that are paths, e.g. 2D Reaching)."
        ),
    ] = "run",
) -> None:
    """Decode sweeps of single latent variables and draw the paths their macro actions take (paper Fig. 5)."""
    from famarl_cli import stages
    from famarl_cli.traversal import EMPTY_LADDER_NATS, empty_ladders, parse_values

    torch_on_one_thread()
    name = model.stem + (f"-ladder{ladder}" if ladder else "") + (f"-index{index}" if index else "")
    out = out or Path("data/traverse") / f"{name}.h5"
    result, information = stages.traverse(model, out, parse_values(values), ladder, index, draw)
    table = Table(title=f"traversal of {model}", show_header=True)
    table.add_column("(ladder, index)")
    table.add_column("effect (m)", justify="right")
    table.add_column("information (nats)", justify="right")
    table.add_column("decoded lengths")
    kl = information or [None] * len(result.effects)
    for (lad, i), effect, nats, lengths in zip(
        result.variables.tolist(), result.effects, kl, result.lengths, strict=True
    ):
        table.add_row(
            f"({lad},{i})", f"{effect:.3f}", "?" if nats is None else f"{nats:.3f}", " ".join(map(str, lengths))
        )
    Console().print(table)
    empty = {} if information is None else empty_ladders(result.variables.tolist(), information)
    for lad, nats in empty.items():
        Console().print(
            f"ladder {lad} is empty: its variables carry {nats:.3f} nats of the training data (under "
            f"{EMPTY_LADDER_NATS:g}), so traversing them changes almost nothing"
        )
    Console().print(f"written {out}, {out.with_suffix('.png')}, {out.with_suffix('.json')}")
