"""A training run's folder: what ``famarl train`` writes and ``famarl evaluate`` reads.

::

    RUN_DIR/
      run.json        schema famarl.run: the run's spec (env, agent, PPO settings, seed), provenance, status
      checkpoint.pt   schema famarl.agent: policy, optimiser, normalisers, environment and random state,
                      the frozen FAVAE decoder (FaMARL), and the log so far: everything to resume or evaluate
      train.csv       one row per PPO update (env steps, return, success, macro length, losses), for plots
      timing.json     the wall time the run took (seconds, over all its sessions): a measurement, kept apart
                      from the other files so that the same run made twice gives them byte for byte (DVC ignores
                      it, .dvcignore)
      eval.json       from famarl evaluate: success rate, return, lengths, decisions, macro length of the policy
                      sampling its actions as in training (what the verdicts judge), and under
                      ``deterministic`` the same of the policy acting with its mode
      rollouts.png    from famarl evaluate: a few deterministic episodes, each macro action in its own colour

The checkpoint carries the FAVAE weights it was trained with, so a run never depends on a FAVAE file that may
since have changed. The three training files are rewritten together at every checkpoint, each atomically.
"""

from __future__ import annotations

import csv
import json
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np

from famarl_cli.artifacts.base import check, require, write_csv, write_json
from famarl_cli.core.errors import ArtifactError

RUN_SCHEMA = "famarl.run"
RUN_SCHEMA_VERSION = 1
CHECKPOINT_SCHEMA = "famarl.agent"
CHECKPOINT_SCHEMA_VERSION = 2  # 2: the policy is one flat parameter tensor (famarl_cli/rl/policy.py)
TRAINER_STATE = ("policy", "optimizer", "torch_rng", "sampling_rng", "obs_norm", "reward_scaler", "episodes", "env")
"""What a run checkpoint's trainer state must hold to resume or evaluate (famarl_cli.rl.ppo.PPOTrainer)."""
RUN_FILE, CHECKPOINT_FILE, LOG_FILE, TIMING_FILE = "run.json", "checkpoint.pt", "train.csv", "timing.json"
EVAL_FILE, ROLLOUTS_FILE, FILM_FILE, STILLS_FILE = "eval.json", "rollouts.png", "episode.gif", "episode.png"
CURVES_FILES = ("curves.png", "curves.json")
"""``famarl evaluate``'s learning curves of several runs and their summary, by default beside the run folders."""


def write_timing(run_dir: str | os.PathLike, wall_s: float) -> None:
    write_json(Path(run_dir) / TIMING_FILE, {"wall_s": round(wall_s, 2)})


def read_timing(run_dir: str | os.PathLike) -> float | None:
    """The run's wall time so far, or None where it was not recorded (a run folder restored from DVC's cache)."""
    try:
        return float(json.loads((Path(run_dir) / TIMING_FILE).read_text())["wall_s"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def write_run(
    run_dir: str | os.PathLike, spec: dict, trainer_state: dict, mode_state: dict, provenance: dict, status: dict
) -> None:
    """Checkpoint first, then the log and the run file: a run file never claims more than the checkpoint holds."""
    # here, not above: reading a run's JSON, CSV and curves (a sweep's plan, the report) does not load torch
    from famarl_cli.artifacts.checkpoints import arrays_to_tensors, save_checkpoint

    run_dir = Path(run_dir)
    save_checkpoint(
        run_dir / CHECKPOINT_FILE,
        CHECKPOINT_SCHEMA,
        CHECKPOINT_SCHEMA_VERSION,
        spec,
        trainer_state["policy"],
        provenance,
        {"trainer": arrays_to_tensors(trainer_state), "mode": mode_state, "status": status},
    )
    if trainer_state["log"]:
        write_csv(run_dir / LOG_FILE, trainer_state["log"])
    write_json(
        run_dir / RUN_FILE,
        {"schema": RUN_SCHEMA, "schema_version": RUN_SCHEMA_VERSION, "spec": spec, "provenance": provenance, **status},
    )


def read_run_file(run_dir: str | os.PathLike) -> dict:
    if not Path(run_dir).is_dir():
        raise ArtifactError(f"{run_dir}: no such run folder")
    missing = f"{run_dir}: not a run folder (no {RUN_FILE}; was it made by famarl train?)"
    return _read_record(Path(run_dir) / RUN_FILE, RUN_SCHEMA, RUN_SCHEMA_VERSION, missing)


def expand_run_folders(folders: list[Path]) -> list[Path]:
    """Each folder as given if it is a run folder; a folder without a run file but with run folders inside stands
    for those, in name order (``famarl evaluate --run data/maze/runs`` evaluates every run of an experiment). Each
    is checked whole (:func:`check_run_folder`) before any is returned: what evaluate and oracle make from runs,
    none is written where one run cannot be read."""
    expanded = []
    for folder in folders:
        inside = sorted(folder.glob(f"*/{RUN_FILE}")) if folder.is_dir() else []
        if (folder / RUN_FILE).exists() or not inside:
            expanded.append(folder)
        else:
            expanded.extend(path.parent for path in inside)
    for folder in expanded:
        check_run_folder(folder)
    return expanded


def check_run_destination(folder: Path) -> None:
    """A usage error where a new run would be trained into ``folder`` among files not its own: a folder that holds
    no run file may be missing, empty, or hold what a run stopped before its first save leaves (its checkpoint,
    log, timing, lock and sweep record); anything else there is someone else's, and a run written in beside it
    would be read later as one folder."""
    from famarl_cli.artifacts.lock import LOCK_FILE
    from famarl_cli.artifacts.made import JOB_FILE
    from famarl_cli.core.errors import UsageError

    if not folder.is_dir() or (folder / RUN_FILE).exists():
        return
    own = {CHECKPOINT_FILE, LOG_FILE, TIMING_FILE, LOCK_FILE, JOB_FILE}
    foreign = sorted(path.name for path in folder.iterdir() if path.name not in own)
    if foreign:
        shown = ", ".join(foreign[:3]) + (f" and {len(foreign) - 3} more" if len(foreign) > 3 else "")
        raise UsageError(f"{folder} holds files that are not a run's ({shown}); give an empty or new --out")


ORACLE_FILE = "oracle.json"
"""``famarl oracle``'s result for one run (famarl_cli.stages.oracle)."""
ORACLE_SCHEMA, ORACLE_SCHEMA_VERSION = "famarl.oracle", 1


def read_oracle(path: str | os.PathLike) -> dict:
    """An ``oracle.json`` written by ``famarl oracle``: its env, agent, label, seed, share solved and layouts."""
    path = Path(path)
    values = _read_record(
        path, ORACLE_SCHEMA, ORACLE_SCHEMA_VERSION, f"{path}: no such oracle result (has famarl oracle run?)"
    )
    require(values, ("env", "agent", "label", "seed", "success_rate", "episodes"), path)
    check(_finite(values["success_rate"]) and 0 <= values["success_rate"] <= 1, path, "has no share in [0, 1]")
    check(isinstance(values["episodes"], list) and values["episodes"], path, "has no searched layouts")
    return values


EVAL_SCHEMA = "famarl.evaluation"
EVAL_SCHEMA_VERSION = 2
"""2: the top level is the policy sampling as in training (the one judged), ``deterministic`` the policy's mode;
version 1 (no schema) had them the other way round, the sampled policy under ``sampled``."""
EVAL_METRICS = (
    "episodes",
    "success_rate",
    "success_rule",
    "return_mean",
    "return_std",
    "episode_length",
    "decisions",
    "macro_length",
    "steps_per_decision",
    "macro_share",
    "macro_step_share",
)
"""What eval.json holds of each policy: at the top level for the sampled one, under ``deterministic`` for its mode."""


def read_evaluation(path: str | os.PathLike) -> dict:
    """An ``eval.json`` written by ``famarl evaluate``, with the fields the report groups and compares by; one of
    version 1 is read in version 2's layout (:data:`EVAL_SCHEMA_VERSION`)."""
    path = Path(path)
    missing = f"{path}: no such evaluation (has famarl evaluate run?)"
    values = _read_record(path, EVAL_SCHEMA, EVAL_SCHEMA_VERSION, missing, older=evaluation_from_version_1)
    keys = ("label", "agent", "env", "seed", "run", "episodes", "success_rate", "return_mean", "macro_length")
    require(values, keys, path, "has no {!r} (written by an older famarl evaluate? run it again)")
    mode = values.get("deterministic")
    check(isinstance(mode, dict) and "success_rate" in mode, path, "has no deterministic success")
    for key in ("success_rate", "return_mean", "macro_length"):
        for value in (values[key], mode.get(key, 0.0)):
            if value is None and key == "success_rate":
                continue  # an env without a meaning of success (famarl_cli.envs.success)
            check(_finite(value), path, f"has a non-finite {key!r}")
    return values


def evaluation_from_version_1(values: dict) -> dict:
    """An eval.json of version 1 (no schema; the deterministic policy at the top level, the sampled one under
    ``sampled``) in version 2's layout; any other record as it is."""
    if "schema" in values or not isinstance(values.get("sampled"), dict):
        return values
    rest = {key: value for key, value in values.items() if key not in EVAL_METRICS and key != "sampled"}
    deterministic = {key: values[key] for key in EVAL_METRICS if key in values}
    return {"schema": EVAL_SCHEMA, "schema_version": 1, **rest, **values["sampled"], "deterministic": deterministic}


def _finite(value: object) -> bool:
    return isinstance(value, int | float) and bool(np.isfinite(value))


def _read_record(
    path: Path, schema: str, version: int, missing: str, older: Callable[[dict], dict] | None = None
) -> dict:
    """The JSON record at ``path`` of ``schema`` at most ``version`` (``older`` brings one of an older layout to the
    current one); ``missing`` says what is wrong where there is no file."""
    try:
        values = json.loads(path.read_text())
    except FileNotFoundError as exc:
        raise ArtifactError(missing) from exc
    except (OSError, json.JSONDecodeError) as exc:
        raise ArtifactError(f"{path}: not readable JSON ({exc})") from exc
    if older is not None and isinstance(values, dict):
        values = older(values)
    check(isinstance(values, dict) and values.get("schema") == schema, path, f"is not a {schema} file")
    found = int(values.get("schema_version", 0))
    check(found <= version, path, f"schema version {found} is newer than this famarl reads ({version})")
    return values


def read_run_checkpoint(run_dir: str | os.PathLike) -> dict:
    """The checkpoint's payload with the trainer state's arrays back in numpy."""
    from famarl_cli.artifacts.checkpoints import load_checkpoint, tensors_to_arrays

    path = Path(run_dir) / CHECKPOINT_FILE
    payload = load_checkpoint(path, CHECKPOINT_SCHEMA, CHECKPOINT_SCHEMA_VERSION)
    found = int(payload["schema_version"])
    check(
        found == CHECKPOINT_SCHEMA_VERSION,
        path,
        f"is a version {found} run checkpoint, from before the policy was one flat parameter vector; this famarl "
        f"reads version {CHECKPOINT_SCHEMA_VERSION}: train the run again",
    )
    for key in ("trainer", "mode", "status"):
        check(isinstance(payload.get(key), dict), path, f"has no {key!r}")
    trainer = payload["trainer"]
    missing = [key for key in TRAINER_STATE if key not in trainer]
    check(not missing, path, f"its trainer state lacks {', '.join(missing)}; not a run famarl can continue")
    # Network, optimiser and RNG states stay tensors; the rest was numpy when saved.
    payload["trainer"] = {
        k: v if k in ("policy", "optimizer", "torch_rng") else tensors_to_arrays(v) for k, v in trainer.items()
    }
    return payload


def read_training_log(run_dir: str | os.PathLike) -> dict[str, np.ndarray]:
    """``train.csv`` as columns of floats."""
    path = Path(run_dir) / LOG_FILE
    if not path.is_file():
        raise ArtifactError(f"{path}: no training log (has the run done an update yet?)")
    try:
        with open(path, newline="") as handle:
            rows = list(csv.DictReader(handle))
        columns = {key: np.array([float(row[key]) for row in rows]) for key in rows[0]}
    except (OSError, ValueError, KeyError, IndexError, TypeError) as exc:
        raise ArtifactError(f"{path}: not a readable training log ({exc})") from exc
    for key in ("env_steps", "episode_success", "episode_return"):
        check(key in columns, path, f"has no {key!r} column")
    return columns


def check_run_folder(run_dir: str | os.PathLike) -> dict:
    """The run file of a run folder whose checkpoint loads and whose training log agrees with both: what ``famarl
    inspect`` vouches for. The checkpoint is written first and the run file last (:func:`write_run`), so a run
    stopped while it saved may have a checkpoint and log ahead of its run file, never behind it."""
    run = read_run_file(run_dir)
    checkpoint, log = Path(run_dir) / CHECKPOINT_FILE, Path(run_dir) / LOG_FILE
    if not checkpoint.exists():
        raise ArtifactError(f"{checkpoint}: missing; the run can be neither evaluated nor continued")
    saved, claimed = int(read_run_checkpoint(run_dir)["status"].get("updates", -1)), int(run.get("updates", 0))
    check(saved >= claimed, checkpoint, f"holds {saved} updates where {RUN_FILE} says {claimed}: an older save")
    if claimed == 0:  # no update yet, so no log
        return run
    steps = read_training_log(run_dir)["env_steps"]
    check(
        claimed <= len(steps) <= saved,
        log,
        f"has {len(steps)} updates where {RUN_FILE} says {claimed} and {CHECKPOINT_FILE} {saved} (truncated?)",
    )
    check(
        steps[claimed - 1] == run.get("env_steps"),
        log,
        f"has {steps[claimed - 1]:.0f} env steps at update {claimed} where {RUN_FILE} says {run.get('env_steps')}",
    )
    return run
