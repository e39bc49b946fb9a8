"""``famarl sequences``: plain arrays of sequences into a segments file, for FAVAE without demos or an env."""

from __future__ import annotations

from famarl_cli.cli import already_made, app, results_console
from famarl_cli.cli.derived import command
from famarl_cli.stages.sequences import SequencesOptions


@command(app, SequencesOptions, "sequences")
def sequences(options: SequencesOptions) -> None:
    """Import sequences from outside as macro actions, one per sequence, to fit FAVAE on (docs/favae.md).

    A .npz may also hold ``lengths`` (N,) for shorter sequences, ``factors`` (N, F) for MIG and ``factor_names``.
    """
    from famarl_cli.stages.sequences import import_sequences

    if already_made("famarl sequences", options, [options.out]):
        return
    segments = import_sequences(options)
    results_console().print(
        f"{len(segments.length)} sequences of {segments.action_dim} dimensions, up to {segments.length.max()} steps "
        f"(padded to {segments.max_length}), factors {', '.join(segments.factor_names) or 'none'}: written "
        f"{options.out}"
    )
