"""``famarl sequences``: plain arrays of sequences into a segments file, for FAVAE without demos or an env."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from famarl_cli.cli import app, reports_errors
from famarl_cli.cli.favae import MAX_LADDERS


@app.command()
@reports_errors
def sequences(
    source: Annotated[Path, typer.Argument(help="A .npy (N, T, D) array, or a .npz holding one (see below).")],
    out: Annotated[Path, typer.Option(help="Output segments HDF5 (the input of famarl favae fit).", dir_okay=False)],
    key: Annotated[
        str | None, typer.Option(help="The .npz array of sequences.  [default: sequences, or trajectories]")
    ] = None,
    length: Annotated[
        int | None, typer.Option(min=1, help="Steps to pad to.  [default: T rounded up to a multiple of 2 ** ladders]")
    ] = None,
    ladders: Annotated[
        int,
        typer.Option(min=1, max=MAX_LADDERS, help="Ladders of the FAVAE to be fitted (L must divide by 2 ** it)."),
    ] = 3,
    standardize: Annotated[
        bool, typer.Option(help="Scale each dimension to mean 0, std 1 (FAVAE's loss assumes unit-scale values).")
    ] = True,
) -> None:
    """Import sequences from outside as macro actions, one per sequence, to fit FAVAE on (docs/favae.md).

    A .npz may also hold ``lengths`` (N,) for shorter sequences, ``factors`` (N, F) for MIG and ``factor_names``.
    """
    from famarl_cli.artifacts import prepare_output, provenance
    from famarl_cli.artifacts.segments import write_segments
    from famarl_cli.method.sequences import load_arrays, to_segments

    out = prepare_output(out)
    arrays = load_arrays(source, key)
    options = {"key": key, "length": length, "ladders": ladders, "standardize": standardize}
    made = provenance("famarl sequences", options, None, [source])
    segments = to_segments(arrays, source, length, 2**ladders, made, standardize)
    write_segments(out, segments)
    Console().print(
        f"{len(segments.length)} sequences of {segments.action_dim} dimensions, up to {segments.length.max()} steps "
        f"(padded to {segments.max_length}), factors {', '.join(segments.factor_names) or 'none'}: written {out}"
    )
