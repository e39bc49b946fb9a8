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
    from famarl_cli.artifacts import prepare_output, provenance, write_json
    from famarl_cli.artifacts.traversal import write_traversal
    from famarl_cli.favae.checkpoint import load_favae
    from famarl_cli.plots import plot_traversal
    from famarl_cli.traversal import parse_values, variables_of
    from famarl_cli.traversal import traverse as run_traversal

    torch_on_one_thread()
    parsed = parse_values(values)
    name = model.stem + (f"-ladder{ladder}" if ladder else "") + (f"-index{index}" if index else "")
    out = prepare_output(out or Path("data/traverse") / f"{name}.h5")
    favae, _ = load_favae(model)
    result = run_traversal(favae, variables_of(favae, ladder, index), parsed)
    options = {"ladder": ladder, "index": index, "values": parsed}
    write_traversal(out, result, provenance("famarl traverse", options, None, [model]))
    effects = {f"({lad},{i})": float(e) for (lad, i), e in zip(result.variables.tolist(), result.effects, strict=True)}
    write_json(out.with_suffix(".json"), {"effects_m": effects, "values": parsed})
    plot_traversal(result, out.with_suffix(".png"), f"{model.name}: latent traversal over {values}")

    table = Table(title=f"traversal of {model}", show_header=True)
    table.add_column("(ladder, index)")
    table.add_column("effect (m)", justify="right")
    table.add_column("decoded lengths")
    for (lad, i), effect, lengths in zip(result.variables.tolist(), result.effects, result.lengths, strict=True):
        table.add_row(f"({lad},{i})", f"{effect:.3f}", " ".join(map(str, lengths)))
    Console().print(table)
    Console().print(f"written {out}, {out.with_suffix('.png')}, {out.with_suffix('.json')}")
