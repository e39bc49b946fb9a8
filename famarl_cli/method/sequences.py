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

import math
import os
import zipfile
from pathlib import Path
from typing import IO

import numpy as np

from famarl_cli.artifacts.segments import Segments
from famarl_cli.core.errors import ArtifactError, UsageError, one_line
from famarl_cli.core.macro_actions import pad

SEQUENCE_KEYS = ("sequences", "trajectories")
REAL_KINDS = "biuf"
"""numpy kinds famarl reads as numbers: booleans, integers, floats (not complex, strings or objects)."""


MAX_ABS = 1e15
"""The largest magnitude a sequence value may have: the FAVAE squares values in float32 (which overflows past
about 1.8e19), and standardising squares them in float64; a bound well inside both keeps every loss finite."""
MAX_BYTES = 4 * 2**30
"""The largest padded sequences array (float32) that ``famarl sequences`` builds: a bigger one is refused before
anything is allocated (a laptop has a few times this)."""


def load_arrays(path: str | os.PathLike, key: str | None = None) -> dict[str, np.ndarray]:
    """The arrays of a .npy or .npz file (pickles refused), checked; ``sequences`` always, the rest if present.

    Each array's header (shape and type) is read and checked against the bytes that follow it before the array
    is: a header that declares more data than the file holds is refused, not allocated."""
    path = Path(path)
    if not path.is_file():
        raise ArtifactError(f"{path}: no such file")
    try:
        if zipfile.is_zipfile(path):
            with zipfile.ZipFile(path) as archive:
                for member in archive.infolist():
                    with archive.open(member) as handle:
                        _check_header(handle, member.file_size, f"{path}: {member.filename}")
        else:
            with open(path, "rb") as handle:
                _check_header(handle, path.stat().st_size, str(path))
        loaded = np.load(path, allow_pickle=False)
        if isinstance(loaded, np.ndarray):
            arrays = None
        else:
            with loaded:  # an .npz reads its arrays lazily: an object array fails here, not at np.load
                arrays = {name: loaded[name] for name in loaded.files}
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
        raise ArtifactError(f"{path}: not a numpy .npy or .npz file of plain arrays ({one_line(exc)})") from exc
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


def _check_header(handle: IO[bytes], size: int, where: str) -> None:
    """Refuse a .npy header whose shape and type need more bytes than the file (``size`` bytes) holds."""
    try:
        version = np.lib.format.read_magic(handle)
    except ValueError as exc:
        raise ArtifactError(f"{where}: not a numpy .npy or .npz file (no numpy header at its start)") from exc
    try:
        read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        shape, _, dtype = read(handle)  # numpy's own limit on the header's length
    except (ValueError, SyntaxError, TypeError, OverflowError) as exc:
        raise ArtifactError(f"{where}: not a numpy array file ({one_line(exc)})") from exc
    if dtype.hasobject:
        raise ArtifactError(f"{where}: holds Python objects (a pickle), which famarl does not load")
    needed = math.prod(shape) * dtype.itemsize
    held = size - handle.tell()
    if needed > held:
        raise ArtifactError(
            f"{where}: its header declares a {shape} {dtype} array ({needed:,} bytes); it holds {held:,}"
        )


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
    if sequences.ndim != 3 or 0 in sequences.shape or sequences.dtype.kind not in REAL_KINDS:
        raise ArtifactError(
            f"{source}: sequences must be a real-valued (N, T, D) array, got {sequences.dtype} {sequences.shape}"
        )
    n, steps, dims = sequences.shape
    length = length or -(-steps // multiple) * multiple
    if length < steps:
        raise UsageError(f"--length {length} is shorter than the sequences' {steps} steps")
    if length % multiple:
        raise UsageError(f"--length must be a multiple of {multiple} (2 ** ladders), got {length}")
    padded_bytes = n * length * (dims + 2) * np.dtype(np.float32).itemsize
    if padded_bytes > MAX_BYTES:
        raise UsageError(
            f"{n} sequences padded to {length} steps of {dims + 2} values would take {padded_bytes / 2**30:,.1f} GiB; "
            f"famarl builds at most {MAX_BYTES / 2**30:.0f} GiB (a smaller --length or --ladders, or fewer sequences)"
        )
    lengths = np.asarray(arrays.get("lengths", np.full(n, steps)))
    if (
        lengths.shape != (n,)
        or not np.issubdtype(lengths.dtype, np.integer)
        or lengths.min() < 1
        or lengths.max() > steps
    ):
        raise ArtifactError(f"{source}: lengths must be {n} integers in 1..{steps}")
    parts = [np.asarray(s[:k], dtype=np.float64) for s, k in zip(sequences, lengths, strict=True)]
    bad = [i for i, part in enumerate(parts) if not (np.abs(part) <= MAX_ABS).all()]
    if bad:
        raise ArtifactError(f"{source}: sequences {bad[:5]} contain NaN, Inf or values beyond +-{MAX_ABS:g}")
    if standardize:
        steps_all = np.concatenate(parts)
        mean, spread = steps_all.mean(axis=0), steps_all.std(axis=0)
        parts = [(part - mean) / np.where(spread > 0, spread, 1.0) for part in parts]
    factors = np.asarray(arrays.get("factors", np.zeros((n, 0))))
    if factors.ndim != 2 or len(factors) != n or factors.dtype.kind not in REAL_KINDS:
        raise ArtifactError(
            f"{source}: factors must be a real-valued ({n}, F) array, got {factors.dtype} {factors.shape}"
        )
    factors = factors.astype(np.float64)
    if not (np.abs(factors) <= MAX_ABS).all():
        raise ArtifactError(f"{source}: factors contain NaN, Inf or values beyond +-{MAX_ABS:g}")
    names = np.asarray(arrays.get("factor_names", [f"factor_{j}" for j in range(factors.shape[1])]))
    if names.size == 0 and names.ndim == 1:
        names = names.astype(str)  # no factors: an empty list of names, whatever type numpy gave it
    if names.ndim != 1 or names.dtype.kind not in "US" or len(names) != factors.shape[1]:
        raise ArtifactError(
            f"{source}: factor_names must be {factors.shape[1]} strings (one per factor), got {names.dtype} "
            f"{names.shape}"
        )
    names = tuple(str(name) for name in names)
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
