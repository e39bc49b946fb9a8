"""Model checkpoints: torch files that carry a schema, the model's full config and their provenance.

A checkpoint is a dict saved with ``torch.save``: ``schema``, ``schema_version``, ``famarl_version``,
``provenance``, ``config`` (everything needed to rebuild the model, nothing to guess) and ``state_dict``.
It loads with ``weights_only=True``: no code in a checkpoint ever runs.
"""

from __future__ import annotations

import os
import pickle
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import torch

from famarl_cli import __version__
from famarl_cli.artifacts.base import atomic_path, check, describe_file
from famarl_cli.core.declare import plain
from famarl_cli.core.errors import ArtifactError


def arrays_to_tensors(tree: Any) -> Any:
    """numpy arrays anywhere in nested dicts and lists become tensors and numpy scalars Python numbers, which
    ``weights_only`` loading accepts."""
    if isinstance(tree, np.ndarray):
        return torch.from_numpy(np.ascontiguousarray(tree))
    return tree.item() if isinstance(tree, np.generic) else _nested(tree, arrays_to_tensors)


def tensors_to_arrays(tree: Any) -> Any:
    """The inverse of :func:`arrays_to_tensors`."""
    return tree.numpy() if isinstance(tree, torch.Tensor) else _nested(tree, tensors_to_arrays)


def _nested(tree: Any, convert: Callable[[Any], Any]) -> Any:
    """``convert`` applied inside a dict or list; anything else as it is."""
    if isinstance(tree, dict):
        return {k: convert(v) for k, v in tree.items()}
    return [convert(v) for v in tree] if isinstance(tree, list) else tree


def save_checkpoint(
    path: str | os.PathLike,
    schema: str,
    version: int,
    config: dict,
    state_dict: dict,
    provenance: dict,
    extra: dict | None = None,
) -> None:
    """``extra`` holds what a kind of checkpoint adds (FAVAE: its training settings and C_last). ``config`` and
    ``provenance`` are written as plain data (:func:`~famarl_cli.core.declare.plain`: an enum as its value, a path
    as its text), which is all that the safe loader reads back."""
    payload = {
        **(extra or {}),
        "schema": schema,
        "schema_version": version,
        "famarl_version": __version__,
        "provenance": plain(provenance),
        "config": plain(config),
        "state_dict": state_dict,
    }
    with atomic_path(path) as temp:
        torch.save(payload, temp)


def refused_object(exc: Exception) -> str | None:
    """What inside a whole, readable torch file its safe (``weights_only``) loading refused: ``a <module.name>
    object`` where torch names the class or function; None where loading failed otherwise (a truncated or foreign
    file)."""
    message = str(exc)
    if not isinstance(exc, pickle.UnpicklingError) or not message.startswith("Weights only load failed"):
        return None
    # Foreign bytes fail the same way; only a named global is something inside a whole checkpoint.
    found = re.search(r"GLOBAL ([\w.]+)", message)
    return None if found is None else f"a {found.group(1)} object"


def load_checkpoint(path: str | os.PathLike, schema: str, version: int) -> dict[str, Any]:
    """Load and check a checkpoint; every problem is an ArtifactError naming the file."""
    path = Path(path)
    if not path.is_file():
        raise ArtifactError(f"{path}: no such file" if not path.exists() else f"{path}: is not a file")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch.load on foreign bytes raises almost any kind (IndexError on 6 bytes, ...)
        refused = refused_object(exc)
        if refused is not None:
            raise ArtifactError(
                f"{path}: holds {refused}, which loading refuses: a checkpoint may hold only tensors and plain data "
                "(loading runs no code)"
            ) from exc
        kind = describe_file(path)
        if kind is not None and "torch" not in kind:
            raise ArtifactError(f"{path}: is {kind}, expected a {schema} checkpoint (a torch .pt file)") from exc
        raise ArtifactError(f"{path}: not a readable checkpoint (truncated or not a torch file?)") from exc
    check(isinstance(payload, dict) and "schema" in payload, path, "has no 'schema'; not a famarl checkpoint")
    check(payload["schema"] == schema, path, f"is a {payload['schema']!r} checkpoint, expected {schema!r}")
    found = int(payload.get("schema_version", -1))
    check(found <= version, path, f"schema version {found} is newer than this famarl reads ({version})")
    for key in ("config", "state_dict"):
        check(isinstance(payload.get(key), dict), path, f"has no {key!r}")
    return payload
