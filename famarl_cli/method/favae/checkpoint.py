"""FAVAE checkpoints and the calibration file of the C_last pre-run.

Version 2 of both records the decoder (a version-1 checkpoint has the shared decoder and still loads as one) and,
in the calibration, what C_last measures (a version-1 calibration measured KL). Version 3 of the calibration records
the pre-run's share of the fit's epochs and the epochs C_last is the mean of (before it, C_last was the last
epoch's value of a pre-run as long as the fit); C_last reads the same in every version.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from famarl_cli.artifacts.base import check, sha256, write_json
from famarl_cli.artifacts.checkpoints import load_checkpoint, save_checkpoint
from famarl_cli.core.errors import ArtifactError
from famarl_cli.method.favae import Measure
from famarl_cli.method.favae.model import Favae, FavaeConfig
from famarl_cli.method.favae.training import TrainingParams

SCHEMA = "famarl.favae"
SCHEMA_VERSION = 2
CALIBRATION_SCHEMA = "famarl.favae-calibration"
CALIBRATION_SCHEMA_VERSION = 3


def save_favae(path: str | os.PathLike, model: Favae, training: dict, provenance: dict) -> None:
    """``training`` holds beta, C_last and the optimiser settings; the checkpoint loads without guessing."""
    save_checkpoint(
        path, SCHEMA, SCHEMA_VERSION, model.config.to_dict(), model.state_dict(), provenance, {"training": training}
    )


def load_favae(path: str | os.PathLike) -> tuple[Favae, dict]:
    """The model and the checkpoint's other contents (training, provenance)."""
    payload = load_checkpoint(path, SCHEMA, SCHEMA_VERSION)
    try:
        model = Favae(FavaeConfig.from_dict(payload["config"]))
        model.load_state_dict(payload["state_dict"])
    except (TypeError, ValueError, RuntimeError) as exc:
        raise ArtifactError(f"{path}: weights do not fit the FAVAE config ({str(exc).splitlines()[0]})") from exc
    return model, payload


def write_calibration(
    path: str | os.PathLike,
    c_last: list[float],
    config: FavaeConfig,
    provenance: dict,
    params: TrainingParams,
    beta: float,
    window: range,
) -> None:
    """C_last of a pre-run of ``config`` trained with ``params`` at ``beta``; C_last is in ``params.measure``, the
    mean over the pre-run's epochs ``window``."""
    write_json(
        path,
        {
            "schema": CALIBRATION_SCHEMA,
            "schema_version": CALIBRATION_SCHEMA_VERSION,
            "c_last": list(c_last),
            "measure": params.measure,
            "beta": beta,
            "progressive": params.progressive,
            "pre_run": params.pre_run,
            "c_last_epochs": [window.start, window.stop],
            "config": config.to_dict(),
            "provenance": provenance,
        },
    )


def read_calibration(
    path: str | os.PathLike, config: FavaeConfig, params: TrainingParams, segments: str | os.PathLike | None = None
) -> list[float]:
    """C_last from a calibration file, checked against the model about to be fitted, what its capacities
    constrain (``params.measure``) and, given, the ``segments`` it is fitted on: a calibration that records the
    segments it measured (its provenance's inputs) must have measured these, by content."""
    path = Path(path)
    if not path.is_file():
        raise ArtifactError(f"{path}: no such file")
    try:
        data = json.loads(path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ArtifactError(f"{path}: not a JSON calibration file") from exc
    check(isinstance(data, dict) and data.get("schema") == CALIBRATION_SCHEMA, path, "not a FAVAE calibration file")
    check(data.get("schema_version", 0) <= CALIBRATION_SCHEMA_VERSION, path, "calibration file from a newer famarl")
    c_last = data.get("c_last")
    check(
        isinstance(c_last, list) and len(c_last) == config.ladders and all(isinstance(c, int | float) for c in c_last),
        path,
        f"c_last must hold {config.ladders} numbers (one per ladder), got {c_last!r}",
    )
    try:
        calibrated = FavaeConfig.from_dict(data.get("config") or {})
    except (TypeError, ValueError):
        calibrated = None
    check(
        calibrated == config,
        path,
        f"was calibrated for another model ({data.get('config')}), not {config.to_dict()}",
    )
    measure = data.get("measure", Measure.KL.value)
    check(
        measure == params.measure,
        path,
        f"C_last there measures {measure}, but this fit constrains {params.measure} (--capacity-measure); "
        "re-run famarl favae calibrate with the same --capacity-measure",
    )
    measured_on = set(((data.get("provenance") or {}).get("inputs") or {}).values())
    check(
        segments is None or not measured_on or sha256(segments) in measured_on,
        path,
        f"measured C_last on other segments than {segments} (content hashes differ); calibrate on these: famarl "
        f"favae calibrate --segments {segments}",
    )
    return [float(c) for c in c_last]
