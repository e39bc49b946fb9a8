"""Plain sequences as macro actions: arrays from outside (no environment, no expert) into a segments file that
``famarl favae fit`` reads, each sequence one macro action.

Input: a ``.npy`` array of shape (N, T, D), or a ``.npz`` holding one under ``sequences`` (or ``trajectories``,
the FAVAE authors' 2D Reaching name, or a key you give), with optionally ``lengths`` (N,) for sequences shorter
than T (their steps past the length are ignored), ``factors`` (N, F) numbers for MIG, and ``factor_names`` (F,).
Each sequence is standardised (by default), padded to L steps (by default T rounded up to a multiple of
2 ** ladders, which FAVAE's convolutions need) and given the ``action_on`` / ``action_off`` channels, as demos'
macro actions are.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from famarl_cli.artifacts.segments import Segments
from famarl_cli.errors import ArtifactError, UsageError
from famarl_cli.macro_actions import pad

SEQUENCE_KEYS = ("sequences", "trajectories")


def load_arrays(path: str | os.PathLike, key: str | None = None) -> dict[str, np.ndarray]:
    """The arrays of a .npy or .npz file (pickles refused), checked; ``sequences`` always, the rest if present."""
    path = Path(path)
    if not path.is_file():
        raise ArtifactError(f"{path}: no such file")
    try:
        loaded = np.load(path, allow_pickle=False)
        if isinstance(loaded, np.ndarray):
            arrays = None
        else:
            with loaded:  # an .npz reads its arrays lazily: an object array fails here, not at np.load
                arrays = {name: loaded[name] for name in loaded.files}
    except (ValueError, OSError, EOFError) as exc:
        raise ArtifactError(f"{path}: not a numpy .npy or .npz file of plain arrays ({exc})") from exc
    if arrays is None:
        if key is not None:
            raise UsageError(f"{path} is a single array; --key is for .npz files")
        arrays = {"sequences": loaded}
    else:
        names = [key] if key else [k for k in SEQUENCE_KEYS if k in arrays]
        if not names or names[0] not in arrays:
            wanted = key or " or ".join(SEQUENCE_KEYS)
            raise ArtifactError(f"{path}: no array {wanted!r} (it holds {', '.join(sorted(arrays)) or 'nothing'})")
        arrays["sequences"] = arrays.pop(names[0])
    return arrays


def to_segments(
    arrays: dict[str, np.ndarray],
    source: Path,
    length: int | None,
    multiple: int,
    provenance: dict,
    standardize: bool = True,
) -> Segments:
    """A segments file's contents from checked arrays: one macro action per sequence.

    ``standardize`` shifts and scales each dimension to mean 0 and standard deviation 1 over all real steps.
    FAVAE's reconstruction is a unit-variance Gaussian log-likelihood summed over steps; on data whose spread is
    far below 1 (2D Reaching's paths differ by about 0.1) encoding anything costs more KL than it saves, and
    every latent stays at the prior.
    """
    sequences = arrays["sequences"]
    if sequences.ndim != 3 or 0 in sequences.shape or not np.issubdtype(sequences.dtype, np.number):
        raise ArtifactError(
            f"{source}: sequences must be a numeric (N, T, D) array, got {sequences.dtype} {sequences.shape}"
        )
    n, steps, _ = sequences.shape
    lengths = np.asarray(arrays.get("lengths", np.full(n, steps)))
    if (
        lengths.shape != (n,)
        or not np.issubdtype(lengths.dtype, np.integer)
        or lengths.min() < 1
        or lengths.max() > steps
    ):
        raise ArtifactError(f"{source}: lengths must be {n} integers in 1..{steps}")
    parts = [np.asarray(s[:k], dtype=np.float64) for s, k in zip(sequences, lengths, strict=True)]
    bad = [i for i, part in enumerate(parts) if not np.isfinite(part).all()]
    if bad:
        raise ArtifactError(f"{source}: sequences {bad[:5]} contain NaN or Inf")
    if standardize:
        steps_all = np.concatenate(parts)
        mean, spread = steps_all.mean(axis=0), steps_all.std(axis=0)
        parts = [(part - mean) / np.where(spread > 0, spread, 1.0) for part in parts]
    factors = np.asarray(arrays.get("factors", np.zeros((n, 0))), dtype=np.float64)
    if factors.ndim != 2 or len(factors) != n or not np.isfinite(factors).all():
        raise ArtifactError(f"{source}: factors must be a finite ({n}, F) array, got shape {factors.shape}")
    names = tuple(str(name) for name in arrays.get("factor_names", [f"factor_{j}" for j in range(factors.shape[1])]))
    if len(names) != factors.shape[1]:
        raise ArtifactError(f"{source}: {len(names)} factor_names for {factors.shape[1]} factors")
    length = length or -(-steps // multiple) * multiple
    if length < steps:
        raise UsageError(f"--length {length} is shorter than the sequences' {steps} steps")
    if length % multiple:
        raise UsageError(f"--length must be a multiple of {multiple} (2 ** ladders), got {length}")
    return Segments(
        episode=np.arange(n),
        start=np.zeros(n, dtype=np.int64),
        length=lengths.astype(np.int64),
        actions=np.concatenate(parts).astype(np.float32),
        padded=pad(parts, length),
        boundaries=[np.zeros(0, dtype=np.int64)] * n,
        distance=[np.zeros(0)] * n,
        factors=factors,
        factor_names=names,
        threshold=float("nan"),
        window=0,
        demos_script=source.name,
        provenance=provenance,
    )
