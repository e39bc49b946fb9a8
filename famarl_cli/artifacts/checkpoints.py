"""Model checkpoints: torch files that carry a schema, the model's full config and their provenance.

A checkpoint is a dict saved with ``torch.save``: ``schema``, ``schema_version``, ``famarl_version``,
``provenance``, ``config`` (everything needed to rebuild the model, nothing to guess) and ``state_dict``.
It loads with ``weights_only=True``: no code in a checkpoint ever runs.
"""

from __future__ import annotations

import os
import pickle
from pathlib import Path
from typing import Any

import torch

from famarl_cli import __version__
from famarl_cli.artifacts.base import atomic_path, check
from famarl_cli.errors import ArtifactError


def save_checkpoint(
    path: str | os.PathLike,
    schema: str,
    version: int,
    config: dict,
    state_dict: dict,
    provenance: dict,
    extra: dict | None = None,
) -> None:
    """``extra`` holds what a kind of checkpoint adds (FAVAE: its training settings and C_last)."""
    payload = {
        **(extra or {}),
        "schema": schema,
        "schema_version": version,
        "famarl_version": __version__,
        "provenance": provenance,
        "config": config,
        "state_dict": state_dict,
    }
    with atomic_path(path) as temp:
        torch.save(payload, temp)


def load_checkpoint(path: str | os.PathLike, schema: str, version: int) -> dict[str, Any]:
    """Load and check a checkpoint; every problem is an ArtifactError naming the file."""
    path = Path(path)
    if not path.is_file():
        raise ArtifactError(f"{path}: no such file" if not path.exists() else f"{path}: is not a file")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except (OSError, RuntimeError, EOFError, pickle.UnpicklingError, ValueError) as exc:
        raise ArtifactError(f"{path}: not a readable checkpoint (truncated or not a torch file?)") from exc
    check(isinstance(payload, dict) and "schema" in payload, path, "has no 'schema'; not a famarl checkpoint")
    check(payload["schema"] == schema, path, f"is a {payload['schema']!r} checkpoint, expected {schema!r}")
    found = int(payload.get("schema_version", -1))
    check(found <= version, path, f"schema version {found} is newer than this famarl reads ({version})")
    for key in ("config", "state_dict"):
        check(isinstance(payload.get(key), dict), path, f"has no {key!r}")
    return payload
