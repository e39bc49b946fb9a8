"""``famarl inspect``: check an artifact, summarise it, and say what made it."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from famarl_cli.cli import app, reports_errors
from famarl_cli.cli.demos import demos_table
from famarl_cli.cli.segment import segments_table


@app.command()
@reports_errors
def inspect(
    path: Annotated[
        Path,
        typer.Argument(
            help="Artifact to check: demos, segments or traversal HDF5; a FAVAE, prior or segmenter checkpoint "
            "(.pt); a run folder (famarl train) or its checkpoint; a famarl JSON record (eval.json, oracle.json, a "
            "calibration, job.json)."
        ),
    ],
    plot: Annotated[
        bool, typer.Option("--plot", help="Also draw a demos file's trajectories to <file>.png, beside it.")
    ] = False,
) -> None:
    """Check that a file or folder is a valid famarl artifact, and print what it holds and what made it."""
    from famarl_cli.artifacts.base import file_kind
    from famarl_cli.core.errors import ArtifactError

    if not path.exists():
        raise ArtifactError(f"{path}: no such file or folder")
    kind = file_kind(path) if path.is_file() else None
    if plot and kind != "hdf5":  # a demos file's trajectories: _hdf5 checks the schema
        raise ArtifactError(f"{path}: --plot draws demos files; this is not one")
    if path.is_dir():
        table, made = _run_folder(path)
    elif kind == "hdf5":
        table, made = _hdf5(path, plot)
    elif kind == "torch":
        table, made = _checkpoint(path)
    else:
        table, made = _record(path)
    _provenance_rows(table, made)
    Console().print(table)


def _hdf5(path: Path, plot: bool) -> tuple[Table, dict]:
    from famarl_cli.artifacts import peek_schema, read_demos
    from famarl_cli.artifacts.demos import SCHEMA as DEMOS
    from famarl_cli.artifacts.made import read_provenance
    from famarl_cli.artifacts.segments import SCHEMA as SEGMENTS
    from famarl_cli.artifacts.segments import read_segments
    from famarl_cli.artifacts.traversal import SCHEMA as TRAVERSAL
    from famarl_cli.artifacts.traversal import read_traversal
    from famarl_cli.core.errors import ArtifactError

    schema = peek_schema(path)
    if plot and schema != DEMOS:
        raise ArtifactError(f"{path}: --plot draws demos files; this is not one")
    if schema == DEMOS:
        loaded = read_demos(path)
        table = demos_table(loaded, str(path))
        if plot:
            from famarl_cli.artifacts.pictures import plot_demos

            plot_demos(loaded, path.with_suffix(".png"))
            table.add_row("written", str(path.with_suffix(".png")))
        return table, loaded.provenance
    if schema == SEGMENTS:
        loaded = read_segments(path)
        return segments_table(loaded, str(path)), loaded.provenance
    if schema == TRAVERSAL:
        traversal = read_traversal(path)
        table = Table(title=str(path), show_header=False)
        table.add_row("schema", schema)
        table.add_row("variables (ladder, index)", ", ".join(f"({a},{b})" for a, b in traversal.variables.tolist()))
        table.add_row("effect per variable", ", ".join(f"{e:.3f}" for e in traversal.effects))
        return table, read_provenance(path)
    raise ArtifactError(f"{path}: is an HDF5 file of schema {schema!r}, which famarl inspect does not read")


def _checkpoint(path: Path) -> tuple[Table, dict]:
    import torch

    from famarl_cli.artifacts.runs import CHECKPOINT_FILE
    from famarl_cli.core.errors import ArtifactError

    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
        schema = payload.get("schema")
    except Exception as exc:  # foreign bytes in a zip: any kind of failure
        raise ArtifactError(f"{path}: not a readable torch checkpoint ({type(exc).__name__})") from exc
    if schema == "famarl.agent" and path.name == CHECKPOINT_FILE:
        return _run_folder(path.parent)
    table = Table(title=str(path), show_header=False)
    table.add_row("schema", f"{schema} (version {payload.get('schema_version')})")
    if schema in ("famarl.favae", "famarl.prior"):
        from famarl_cli.stages.inspect import model_rows

        for row in model_rows(path, schema):
            table.add_row(*row)
    elif schema == "famarl.segmenter":
        table.add_row("config", json.dumps(payload.get("config", {})))
    else:
        raise ArtifactError(f"{path}: is a torch file of schema {schema!r}, which famarl inspect does not read")
    return table, payload.get("provenance", {})


def _run_folder(folder: Path) -> tuple[Table, dict]:
    from famarl_cli.artifacts.runs import EVAL_FILE, read_evaluation, read_run_file
    from famarl_cli.stages.evaluate import judged_success

    run = read_run_file(folder)
    spec, ppo = run["spec"], run["spec"]["ppo"]
    table = Table(title=f"run {folder}", show_header=False)
    table.add_row("agent", f"{spec['agent']} ({spec['label']}), seed {spec['seed']}")
    table.add_row("env", f"{spec['env_id']} {spec.get('env_kwargs') or ''}".strip())
    if spec.get("favae"):
        table.add_row("FAVAE", spec["favae"])
    state = "complete" if run.get("complete") else "stopped (famarl train --resume continues it)"
    table.add_row("env steps", f"{run.get('env_steps', 0):,} of {ppo['total_steps']:,}; {state}")
    evaluation = folder / EVAL_FILE
    if evaluation.is_file():
        table.add_row("evaluation", judged_success(read_evaluation(evaluation)))
    return table, run.get("provenance", {})


def _evaluation(path: Path) -> tuple[Table, dict]:
    """An eval.json: the judged policy's numbers first, its mode's beside, then the run's."""
    from famarl_cli.artifacts.runs import EVAL_METRICS, read_evaluation
    from famarl_cli.stages.evaluate import judged_success

    found = read_evaluation(path)
    mode = found["deterministic"]
    table = Table(title=f"evaluation {path}", show_header=False)
    table.add_row("schema", f"{found['schema']} (version {found['schema_version']})")
    table.add_row("run", f"{found['run']}: {found['label']} ({found['agent']}) on {found['env']}, seed {found['seed']}")
    table.add_row("success", judged_success(found))
    table.add_row("success rule", str(found.get("success_rule")))
    for key in EVAL_METRICS:
        if key not in ("episodes", "success_rate", "success_rule") and key in found:
            table.add_row(key.replace("_", " "), f"{found[key]:.4g} (mode {mode.get(key, float('nan')):.4g})")
    for key in ("env_steps", "evaluation_seed", "layout_seed"):
        if key in found:
            table.add_row(key.replace("_", " "), str(found[key]))
    return table, found.get("provenance") or {}


def _record(path: Path) -> tuple[Table, dict]:
    from famarl_cli.artifacts.runs import EVAL_SCHEMA
    from famarl_cli.core.errors import ArtifactError

    try:
        record = json.loads(path.read_text())
    except (ValueError, UnicodeDecodeError) as exc:
        raise ArtifactError(f"{path}: not an HDF5 file, a torch checkpoint or a JSON record") from exc
    made = record.get("provenance") if isinstance(record, dict) else None
    schema = record.get("schema") if isinstance(record, dict) else None
    if schema == EVAL_SCHEMA or (schema is None and (made or {}).get("command") == "famarl evaluate"):
        return _evaluation(path)
    if not str(schema).startswith("famarl.") and not str((made or {}).get("command", "")).startswith("famarl "):
        raise ArtifactError(f"{path}: a JSON file that no famarl command recorded (no famarl schema or provenance)")
    table = Table(title=str(path), show_header=False)
    if schema:
        table.add_row("schema", f"{schema} (version {record.get('schema_version')})")
    for key, value in record.items():
        if key not in ("schema", "schema_version", "provenance") and not isinstance(value, dict | list):
            table.add_row(key.replace("_", " "), str(value))
    return table, made or {}


def _provenance_rows(table: Table, made: dict) -> None:
    """What made the artifact: the command and its settings, its inputs, famarl's version."""
    if not made:
        table.add_row("made by", "not recorded")
        return
    seed = "" if made.get("seed") is None else f", seed {made['seed']}"
    table.add_row("made by", f"{made.get('command')} (famarl {made.get('famarl_version')}){seed}")
    making = made.get("made_from") or {}
    if making.get("options"):
        table.add_row("options", ", ".join(f"{k}={json.dumps(v)}" for k, v in making["options"].items()))
    for name, digest in (made.get("inputs") or {}).items():
        table.add_row("input", f"{name} (sha256 {digest[:12]})")
