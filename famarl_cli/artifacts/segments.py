"""The segments file: macro actions cut from demos, ready for FAVAE, plus how they were found.

Layout (HDF5)::

    /                       attrs: schema="famarl.segments", schema_version, famarl_version, provenance (JSON:
                                   command, params, seed, inputs with content hashes), demos_script, action_dim,
                                   length (L), n_segments, n_split (pieces made from segments longer than L),
                                   n_dropped, threshold, window, factor_names (JSON)
    /segments/
        episode             (S,)             int64, the demos episode each macro action comes from
        start               (S,)             int64, its first step in that episode
        length              (S,)             int64, its number of real steps (1..L)
        actions             (sum length, D)  float32, the real steps of all macro actions, one after another
        padded              (S, L, D + 2)    float32, FAVAE's input: actions zero-padded to L, then action_on,
                                             action_off (see famarl_cli/core/macro_actions.py)
    /episodes/
        boundaries          (B,)             int64, detected boundaries (first steps of segments after the first)
        boundary_offsets    (E + 1,)         int64, episode e's boundaries are boundaries[offsets[e]:offsets[e+1]]
        distance            (C,)             float64, the distance curves, one after another
        distance_offsets    (E + 1,)         int64
    /ground_truth/
        factors             (S, F)           float64, factors of the expert phase that overlaps each segment most;
                                             for evaluation metrics only
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from famarl_cli.artifacts.base import atomic_path, check, open_artifact, require, write_header
from famarl_cli.core.macro_actions import OFF, ON

REPLICATE_FILE = "segments.h5"
"""The segments' name in a replicate's folder (famarl macros), beside the FAVAE fitted on them."""
SCHEMA = "famarl.segments"
SCHEMA_VERSION = 1
ARRAYS = {"episode": np.int64, "start": np.int64, "length": np.int64, "actions": np.float32, "padded": np.float32}
"""The datasets of ``/segments`` and their stored dtypes."""


@dataclass
class Segments:
    episode: np.ndarray
    start: np.ndarray
    length: np.ndarray
    actions: np.ndarray
    padded: np.ndarray
    boundaries: list[np.ndarray]
    distance: list[np.ndarray]
    factors: np.ndarray
    factor_names: tuple[str, ...]
    threshold: float
    window: int
    """The segmenter's window: distance curve index j sits at step j + window // 2."""
    demos_script: str = ""
    n_split: int = 0
    n_dropped: int = 0
    provenance: dict = field(default_factory=dict)

    @property
    def max_length(self) -> int:
        return self.padded.shape[1]

    @property
    def action_dim(self) -> int:
        return self.actions.shape[1]

    def macro_actions(self) -> list[np.ndarray]:
        """Each macro action's real steps, as (length, D) arrays."""
        return np.split(self.actions, np.cumsum(self.length)[:-1])


def _flatten(arrays: list[np.ndarray], dtype) -> tuple[np.ndarray, np.ndarray]:
    offsets = np.concatenate([[0], np.cumsum([len(a) for a in arrays])]).astype(np.int64)
    values = np.concatenate(arrays).astype(dtype) if arrays else np.zeros(0, dtype)
    return values, offsets


def _unflatten(values: np.ndarray, offsets: np.ndarray) -> list[np.ndarray]:
    return [values[a:b] for a, b in zip(offsets[:-1], offsets[1:], strict=True)]


def write_segments(path: str | os.PathLike, segments: Segments) -> None:
    boundaries, boundary_offsets = _flatten(segments.boundaries, np.int64)
    distance, distance_offsets = _flatten(segments.distance, np.float64)
    with atomic_path(path) as temp, h5py.File(temp, "w") as handle:
        write_header(
            handle,
            SCHEMA,
            SCHEMA_VERSION,
            segments.provenance,
            demos_script=segments.demos_script,
            action_dim=segments.action_dim,
            length=segments.max_length,
            n_segments=len(segments.length),
            n_split=segments.n_split,
            n_dropped=segments.n_dropped,
            threshold=float(segments.threshold),
            window=segments.window,
            factor_names=list(segments.factor_names),
        )
        group = handle.create_group("segments")
        for key, dtype in ARRAYS.items():
            group.create_dataset(key, data=getattr(segments, key).astype(dtype))
        episodes = handle.create_group("episodes")
        episodes.create_dataset("boundaries", data=boundaries)
        episodes.create_dataset("boundary_offsets", data=boundary_offsets)
        episodes.create_dataset("distance", data=distance)
        episodes.create_dataset("distance_offsets", data=distance_offsets)
        handle.create_group("ground_truth").create_dataset("factors", data=segments.factors.astype(np.float64))


def read_segments(path: str | os.PathLike) -> Segments:
    """Read and validate a segments file; every problem is an ArtifactError naming the file and the fault."""
    path = Path(path)
    with open_artifact(path, SCHEMA, SCHEMA_VERSION) as handle:
        require(handle, [f"segments/{key}" for key in ARRAYS], path, "missing dataset {!r}")
        episodes = handle["episodes"]
        segments = Segments(
            **{key: handle[f"segments/{key}"][()] for key in ARRAYS},
            boundaries=_unflatten(episodes["boundaries"][()], episodes["boundary_offsets"][()]),
            distance=_unflatten(episodes["distance"][()], episodes["distance_offsets"][()]),
            factors=handle["ground_truth/factors"][()],
            factor_names=tuple(json.loads(handle.attrs["factor_names"])),
            threshold=float(handle.attrs["threshold"]),
            window=int(handle.attrs["window"]),
            demos_script=str(handle.attrs.get("demos_script", "")),
            n_split=int(handle.attrs.get("n_split", 0)),
            n_dropped=int(handle.attrs.get("n_dropped", 0)),
            provenance=json.loads(handle.attrs.get("provenance", "{}")),
        )
    _validate(segments, path)
    return segments


def _validate(segments: Segments, path: Path) -> None:
    n = len(segments.length)
    check(n > 0, path, "holds no segments")
    check(segments.padded.ndim == 3, path, f"segments/padded must be (S, L, D+2), got {segments.padded.shape}")
    length, dims = segments.padded.shape[1], segments.padded.shape[2] - 2
    check(
        segments.actions.ndim == 2 and segments.actions.shape[1] == dims,
        path,
        f"segments/actions must be (steps, {dims}), got {segments.actions.shape}",
    )
    for key in ("episode", "start"):
        check(getattr(segments, key).shape == (n,), path, f"segments/{key} must have shape ({n},)")
    check(segments.padded.shape[0] == n, path, f"segments/padded must have {n} rows, got {segments.padded.shape[0]}")
    check(bool(np.all((segments.length >= 1) & (segments.length <= length))), path, f"lengths must be in 1..{length}")
    check(int(segments.length.sum()) == len(segments.actions), path, "segment lengths do not add up to the actions")
    check(segments.factors.shape[0] == n, path, f"ground_truth/factors must have {n} rows")
    for key in ("actions", "padded"):
        check(np.isfinite(getattr(segments, key)).all(), path, f"segments/{key} contain NaN or Inf")
    on = segments.padded[..., ON]
    check(
        bool(np.array_equal(on.sum(axis=1), segments.length)) and bool(np.all(on + segments.padded[..., OFF] == 1)),
        path,
        "action_on / action_off channels do not match the segment lengths",
    )
