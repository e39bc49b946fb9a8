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
) -> None:
    """Decode sweeps of single latent variables and draw the paths their macro actions take (paper Fig. 5)."""
    from famarl_cli import stages
    from famarl_cli.traversal import parse_values

    torch_on_one_thread()
    name = model.stem + (f"-ladder{ladder}" if ladder else "") + (f"-index{index}" if index else "")
    out = out or Path("data/traverse") / f"{name}.h5"
    result = stages.traverse(model, out, parse_values(values), ladder, index)
    table = Table(title=f"traversal of {model}", show_header=True)
    table.add_column("(ladder, index)")
    table.add_column("effect (m)", justify="right")
    table.add_column("decoded lengths")
    for (lad, i), effect, lengths in zip(result.variables.tolist(), result.effects, result.lengths, strict=True):
        table.add_row(f"({lad},{i})", f"{effect:.3f}", " ".join(map(str, lengths)))
    Console().print(table)
    Console().print(f"written {out}, {out.with_suffix('.png')}, {out.with_suffix('.json')}")
