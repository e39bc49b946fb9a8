"""The traversal file: what each traversed FAVAE latent variable decodes to, and where it goes.

Layout (HDF5)::

    /              attrs: schema="famarl.traversal", schema_version, famarl_version, provenance (JSON, with the
                          model's content hash), map_size
    variables      (V, 2)            int64, (ladder, index) of each variable, counted from 1
    values         (K,)              float64
    actions        (V, K, L, D)      float32, decoded actions (steps past a macro's length are not executed)
    lengths        (V, K)            int64, decoded lengths (cut where action_off wins)
    paths          (V, K, L + 1, 2)  float64, positions when run open-loop from the map's centre
    effects        (V,)              float64, mean distance (m) between the paths of neighbouring values
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import h5py
import numpy as np

from famarl_cli.artifacts.base import atomic_path, check, open_artifact, require, write_header
from famarl_cli.envs.continuous_world import TRAVERSAL_MAP_SIZE

SCHEMA = "famarl.traversal"
SCHEMA_VERSION = 1
FIELDS = ("variables", "values", "actions", "lengths", "paths", "effects")


@dataclass
class Traversal:
    variables: np.ndarray
    """(V, 2) (ladder, index) of each traversed variable, counted from 1."""
    values: np.ndarray
    """(K,) the values each variable takes."""
    actions: np.ndarray
    """(V, K, L, D) decoded actions (padding past each length included, as decoded)."""
    lengths: np.ndarray
    """(V, K) decoded macro-action lengths."""
    paths: np.ndarray
    """(V, K, L + 1, 2) positions of each macro action run from the map's centre."""
    effects: np.ndarray
    """(V,) effect size of each variable (m, or the drawn observation dimensions' units)."""
    frames: np.ndarray | None = None
    """(V, K, H, W, 3) what a gymnasium env renders at the end of each macro action, when asked for."""


def write_traversal(path: str | os.PathLike, traversal: Traversal, provenance: dict) -> None:
    with atomic_path(path) as temp, h5py.File(temp, "w") as handle:
        write_header(handle, SCHEMA, SCHEMA_VERSION, provenance, map_size=TRAVERSAL_MAP_SIZE)
        for key in FIELDS:
            handle.create_dataset(key, data=getattr(traversal, key))


def read_traversal(path: str | os.PathLike) -> Traversal:
    with open_artifact(path, SCHEMA, SCHEMA_VERSION) as handle:
        require(handle, FIELDS, path, "missing dataset {!r}")
        traversal = Traversal(**{key: handle[key][()] for key in FIELDS})
    shape = traversal.lengths.shape
    check(traversal.variables.shape == (shape[0], 2), path, "variables do not match lengths")
    check(traversal.paths.shape[:2] == shape and np.isfinite(traversal.paths).all(), path, "paths are malformed")
    return traversal
