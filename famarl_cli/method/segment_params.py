"""The segmentation's options, declared once (:mod:`famarl_cli.core.declare`): how boundaries are found and
segments cut (:class:`SegmentParams`) and the window autoencoder that scores them (:class:`SegmenterOptions`).
Torch-free, so the CLI derives ``famarl segment`` and ``famarl macros`` from them without loading torch."""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from famarl_cli.core.declare import option


class Distance(StrEnum):
    """Distance between adjacent windows' codes."""

    EUCLIDEAN = "euclidean"
    NORMALISED = "normalised"


class LongSegments(StrEnum):
    """What to do with a segment longer than L: split it into pieces of at most L steps, drop it, or stop."""

    SPLIT = "split"
    DROP = "drop"
    FAIL = "fail"


LENGTH_MULTIPLE = 8
"""An automatic L is the longest segment rounded up to a multiple of this: FAVAE halves the length three times."""


@dataclass(frozen=True)
class SegmentParams:
    """How demos are cut into macro actions (recorded in the segments' provenance)."""

    peak_neighbours: int = option(
        10, "A peak is highest among this many adjacent points.", min=2, former=("neighbours",)
    )
    margin: float = option(
        0.7,
        "Peak threshold, as a fraction of the distance range over all episodes (the paper's value is 0.05; 0.7 "
        "scored best on our demos, see docs/segmentation.md).",
        min=0.0,
        max=1.0,
    )
    distance: Distance = option(Distance.EUCLIDEAN, "Distance between adjacent windows' codes.")
    length: int | None = option(
        None, "FAVAE input length L; longer segments are split.  [default: longest segment, rounded up to 8]", min=1
    )
    long: LongSegments = option(LongSegments.SPLIT, "Segments longer than L: split into pieces, drop, or fail.")
    tolerance: int = option(2, "Boundary tolerance (steps) for the second F1.", min=0)
    seed: int = option(0, "Seed of the autoencoder's initialisation and batches.")


@dataclass(frozen=True)
class SegmenterOptions:
    """The window autoencoder's shape and training."""

    window: int = option(4, "Steps per sliding window.", min=2)
    code_dim: int = option(4, "Size of the autoencoder's code.", min=1)
    hidden: int = option(32, "Width of the autoencoder's hidden layer.", min=1)
    segment_epochs: int = option(
        300, "Training epochs of the segmenter (an autoencoder).", min=1, renamed=("--epochs",), former=("epochs",)
    )
