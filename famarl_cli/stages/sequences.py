"""``famarl sequences``: plain arrays of sequences into a segments file, for FAVAE without demos or an env."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from famarl_cli.artifacts.made import Replaceable
from famarl_cli.artifacts.segments import Segments
from famarl_cli.core.declare import option, same_as, to_json
from famarl_cli.method.favae import FavaeOptions
from famarl_cli.method.segment_params import SegmentParams


@dataclass(frozen=True)
class SequencesOptions:
    """``famarl sequences``: plain arrays of sequences into a segments file."""

    source: Path = option(help="A .npy (N, T, D) array, or a .npz holding one (see below).", argument=True)
    out: Path = option(help="Output segments HDF5 (the input of famarl favae fit).", path="file", affects=False)
    key: str | None = option(None, "The .npz array of sequences.  [default: sequences, or trajectories]")
    length: int | None = same_as(
        SegmentParams,
        "length",
        help="FAVAE input length L: steps to pad to.  [default: T rounded up to a multiple of 2 ** ladders]",
    )
    ladders: int = same_as(
        FavaeOptions, "ladders", help="Ladders of the FAVAE to be fitted (L must divide by 2 ** it)."
    )
    standardize: bool = option(True, "Scale each dimension to mean 0, std 1 (FAVAE's loss assumes unit-scale values).")
    overwrite: bool = same_as(Replaceable, "overwrite")


def import_sequences(options: SequencesOptions) -> Segments:
    """The sequences of ``options.source`` as segments, one per sequence (:mod:`famarl_cli.method.sequences`),
    written to ``options.out``."""
    from famarl_cli.artifacts import prepare_output, provenance
    from famarl_cli.artifacts.segments import write_segments
    from famarl_cli.method.sequences import load_arrays, to_segments

    source, out = options.source, prepare_output(options.out)
    arrays = load_arrays(source, options.key)
    recorded = {key: value for key, value in to_json(options).items() if key not in ("source", "out", "overwrite")}
    made = provenance("famarl sequences", recorded, None, [source], options=options)
    segments = to_segments(arrays, source, options.length, 2**options.ladders, made, options.standardize)
    write_segments(out, segments)
    return segments
