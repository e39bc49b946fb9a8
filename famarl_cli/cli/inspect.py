"""``famarl inspect``: check an artifact, summarise it, and say what made it."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from famarl_cli.cli import app, reports_errors, results_console
from famarl_cli.cli.demos import demos_table
from famarl_cli.cli.segment import segments_table
from famarl_cli.core.errors import ArtifactError, UsageError


@app.command()
@reports_errors
def inspect(
    path: Annotated[
        Path,
        typer.Argument(
            help="Artifact to check: demos, segments or traversal HDF5; a FAVAE, prior or segmenter checkpoint "
            "(.pt); a run folder (famarl train) or its checkpoint; a sweep's folder or a famarl macros folder (what "
            "its sweep.json or job.json records); a folder famarl evaluate or famarl oracle wrote into; a JSON file "
            "famarl writes (eval.json, oracle.json, "
            "a calibration, a .metrics.json, timing.json, job.json, sweep.json, curves.json, a report's summary.json "
            "and metrics.json)."
        ),
    ],
    plot: Annotated[
        bool, typer.Option("--plot", help="Also draw a demos file's trajectories to <file>.png, beside it.")
    ] = False,
) -> None:
    """Check that a file or folder is a valid famarl artifact, and print what it holds and what made it."""
    from famarl_cli.artifacts.base import file_kind
    from famarl_cli.artifacts.tracked import refuse_tracked

    if not path.exists():
        raise ArtifactError(f"{path}: no such file or folder")
    kind = file_kind(path) if path.is_file() else None
    if plot:
        if kind != "hdf5":  # a demos file's trajectories: _hdf5 checks the schema
            raise UsageError(f"{path}: --plot draws demos files; this is not one")
        # before reading: the picture of a stage's demos is that stage's output, which only dvc repro writes
        refuse_tracked(path.with_suffix(".png"), "copy the demos file elsewhere to draw it there")
    if path.is_dir():
        table, made = _folder(path)
    elif kind == "hdf5":
        table, made = _hdf5(path, plot)
    elif kind == "torch":
        table, made = _checkpoint(path)
    else:
        table, made = _record(path, kind)
    _provenance_rows(table, made)
    for column in table.columns:  # a path longer than its column is folded onto the next line, never cut
        column.overflow = "fold"
    results_console().print(table)


def _hdf5(path: Path, plot: bool) -> tuple[Table, dict]:
    from famarl_cli.artifacts import peek_schema, read_demos
    from famarl_cli.artifacts.demos import SCHEMA as DEMOS
    from famarl_cli.artifacts.made import read_provenance
    from famarl_cli.artifacts.segments import SCHEMA as SEGMENTS
    from famarl_cli.artifacts.segments import read_segments
    from famarl_cli.artifacts.traversal import SCHEMA as TRAVERSAL
    from famarl_cli.artifacts.traversal import read_traversal

    schema = peek_schema(path)
    if plot and schema != DEMOS:
        raise UsageError(f"{path}: --plot draws demos files; this is not one")
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


def _folder(folder: Path) -> tuple[Table, dict]:
    """A run folder; else a sweep's folder (its sweep.json) or a famarl macros replicate's (its job.json); else a
    folder of results, each run's in its subfolder (what famarl evaluate and famarl oracle write into --out); else
    an error that says where a report's verdicts are, or names the files in the folder famarl inspect would read."""
    from famarl_cli.artifacts.base import file_kind
    from famarl_cli.artifacts.records import REPORT_FILE
    from famarl_cli.artifacts.runs import EVAL_FILE, ORACLE_FILE, RUN_FILE
    from famarl_cli.sweep.plan import JOB_FILE, MANIFEST

    if (folder / RUN_FILE).is_file():
        return _run_folder(folder)
    record = next((folder / name for name in (MANIFEST, JOB_FILE) if (folder / name).is_file()), None)
    if record is not None:
        return _record(record, "json")
    results = sorted(folder.glob(f"*/{EVAL_FILE}")) + sorted(folder.glob(f"*/{ORACLE_FILE}"))
    if results:
        return _results(folder, results)
    if (folder / REPORT_FILE).is_file():
        raise ArtifactError(
            f"{folder}: a report ({REPORT_FILE}), not a run folder; its verdicts are in the summary.json famarl "
            "report wrote at --summary (by default beside it; a pipeline's: summary.json or "
            "pipelines/<name>/summary.json): inspect that"
        )
    # A folder of a stage's files (famarl traverse --out d/t.h5 writes d/t.h5, t.png, t.json): inspect reads files.
    files = sorted(p.name for p in folder.iterdir() if p.is_file() and file_kind(p) in ("hdf5", "torch", "json"))
    if files:
        more = len(files) - FILES_NAMED
        named = ", ".join(files[:FILES_NAMED]) + (f" and {more} more" if more > 0 else "")
        raise ArtifactError(
            f"{folder}: not a run folder (no {RUN_FILE}), a sweep's or a folder of results; give one of its files "
            f"instead: {named}"
        )
    return _run_folder(folder)  # its error: not a run folder


FILES_NAMED = 6
"""A folder that holds files, not a run: how many of them its error names."""


def _results(folder: Path, results: list[Path]) -> tuple[Table, dict]:
    """Each run's evaluation or oracle result in ``results`` on a row of its own, named by its file; what made each
    is that file's to show (famarl inspect FILE)."""
    from famarl_cli.artifacts.runs import EVAL_FILE, read_evaluation, read_oracle
    from famarl_cli.stages.evaluate import shown

    table = Table("file", "run", "success", title=f"results in {folder}")
    for path in results:
        if path.name == EVAL_FILE:
            found = read_evaluation(path)
            mode = found["deterministic"]["success_rate"]
            success = f"{shown(found['success_rate'])} judged ({shown(mode)} mode) of {found['episodes']} episodes"
        else:
            found = read_oracle(path)
            interval = f"[{shown(found['success_low'])}, {shown(found['success_high'])}]"
            success = f"{shown(found['success_rate'])} {interval} of {len(found['episodes'])} layouts solved"
        agent = "" if found["agent"] == found["label"] else f" ({found['agent']})"
        table.add_row(
            str(path.relative_to(folder)), f"{found['label']}{agent}, seed {found['seed']}, {found['env']}", success
        )
    commands = sorted({"famarl evaluate" if path.name == EVAL_FILE else "famarl oracle" for path in results})
    return table, {"command": " and ".join(commands)}


def _run_folder(folder: Path) -> tuple[Table, dict]:
    from famarl_cli.artifacts.runs import EVAL_FILE, RUN_FILE, check_run_folder, read_evaluation
    from famarl_cli.stages.evaluate import judged_success

    run = check_run_folder(folder)
    try:
        spec, ppo = run["spec"], run["spec"]["ppo"]
        agent, label, seed, env, total = spec["agent"], spec["label"], spec["seed"], spec["env_id"], ppo["total_steps"]
    except (KeyError, TypeError) as exc:
        raise ArtifactError(f"{folder / RUN_FILE}: its run's settings lack {exc} (edited by hand?)") from None
    table = Table(title=f"run {folder}", show_header=False)
    table.add_row("agent", f"{agent} ({label}), seed {seed}")
    table.add_row("env", f"{env} {spec.get('env_kwargs') or ''}".strip())
    if spec.get("favae"):
        table.add_row("FAVAE", spec["favae"])
    state = "complete" if run.get("complete") else "stopped (famarl train --resume continues it)"
    table.add_row("env steps", f"{run.get('env_steps', 0):,} of {total:,}; {state}")
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


def _record(path: Path, kind: str | None) -> tuple[Table, dict]:
    """A JSON file of ``kind`` (:func:`~famarl_cli.artifacts.base.file_kind`'s, read already)."""
    from famarl_cli.artifacts.records import unschemed_record
    from famarl_cli.artifacts.runs import EVAL_SCHEMA, RUN_SCHEMA
    from famarl_cli.sweep.plan import JOB_FILE, JOB_SCHEMA

    if kind == "empty":
        raise ArtifactError(f"{path}: an empty file (truncated?)")
    if kind != "json":
        raise ArtifactError(f"{path}: not an HDF5 file, a torch checkpoint or a JSON record")
    try:
        record = json.loads(path.read_text())
    except (ValueError, UnicodeDecodeError) as exc:
        raise ArtifactError(f"{path}: not valid JSON (truncated or corrupt: {exc})") from exc
    if not isinstance(record, dict):
        raise ArtifactError(f"{path}: a JSON file that no famarl command wrote (not an object)")
    made = record.get("provenance") if isinstance(record.get("provenance"), dict) else {}
    schema = record.get("schema")
    if schema == EVAL_SCHEMA or (schema is None and made.get("command") == "famarl evaluate"):
        return _evaluation(path)
    if schema == RUN_SCHEMA:
        return _run_folder(path.parent)
    if schema == JOB_SCHEMA:
        return _job(path, record)
    table = Table(title=str(path), show_header=False)
    if schema is not None:
        table.add_row("schema", f"{schema} (version {record.get('schema_version')})")
    if schema == "famarl.sweep":  # a sweep's plan (famarl_cli.sweep.driver): each job's folder records its making
        for name, job in (record.get("jobs") or {}).items():
            point = ", ".join(f"{k}={v}" for k, v in job.items() if k != "key")
            table.add_row("job", f"{name} ({point}): its making in {name}/{JOB_FILE}")
        return table, {"command": "famarl sweep"}
    if not str(schema).startswith("famarl.") and not str(made.get("command", "")).startswith("famarl "):
        what, record, made = unschemed_record(path, record)
        table.add_row("what", what)
    for key, value in record.items():
        shown = _shown(value)
        if key not in ("schema", "schema_version", "provenance") and shown is not None:
            table.add_row(key.replace("_", " "), shown)
    return table, made


def _shown(value: object) -> str | None:
    """A record's value on one row: a number or text as it is, a list or mapping of them as a list, a mapping of
    anything else by its keys; None where a row cannot hold it (a list of records)."""
    if not isinstance(value, dict | list):
        return str(value)
    items = value.values() if isinstance(value, dict) else value
    if not all(isinstance(item, str | int | float | bool) or item is None for item in items):
        return ", ".join(value) if isinstance(value, dict) else None
    if isinstance(value, dict):
        return ", ".join(f"{key} {_number(item)}" for key, item in value.items())
    return ", ".join(map(_number, value))


def _number(value: object) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def _job(path: Path, record: dict) -> tuple[Table, dict]:
    """A sweep's job record (or a famarl macros folder's): the job, and its making as its key hashes it."""
    table = Table(title=str(path), show_header=False)
    table.add_row("schema", f"{record['schema']} (version {record.get('schema_version')})")
    point = ", ".join(f"{k}={v}" for k, v in (record.get("point") or {}).items())
    state = "complete" if record.get("complete") else "not complete"
    table.add_row("job", f"{record.get('name')} ({point}), {state}; key {str(record.get('key'))[:12]}")
    config = record.get("config") or {}
    # famarl train's job holds the run's spec, as run.json does; the others hold the command's own options
    runner = str(record.get("runner"))
    command = "famarl train" if "spec" in config else _swept_command(runner) or runner
    table.add_row("runner", runner)
    made = {
        "command": command,
        "famarl_version": record.get("famarl_version"),
        "made_from": {"options": config.get("spec", config)},
        "inputs": record.get("inputs") or {},
    }
    return table, made


def _swept_command(runner: str) -> str | None:
    """The command a job's runner (``module:function``) runs a point of: the sweepable command whose options are
    declared beside it."""
    from famarl_cli.sweep.registry import SWEEPABLE

    module = runner.split(":")[0]
    return next((f"famarl {s.command}" for s in SWEEPABLE.values() if s.options.__module__ == module), None)


def _provenance_rows(table: Table, made: dict) -> None:
    """What made the artifact: the command and its settings, under the options that set them, its inputs,
    famarl's version."""
    if not made.get("command"):
        table.add_row("made by", "not recorded")
        return
    seed = "" if made.get("seed") is None else f", seed {made['seed']}"
    version = "" if made.get("famarl_version") is None else f" (famarl {made['famarl_version']})"
    where = "" if made.get("machine") is None else f", on {made['machine']}"
    table.add_row("made by", f"{made['command']}{version}{seed}{where}")
    making = made.get("made_from") or {}
    if making.get("options"):
        table.add_row("options", ", ".join(_options_shown(made["command"], making["options"])))
    for name, digest in (made.get("inputs") or {}).items():
        table.add_row("input", f"{name} (sha256 {digest[:12]})")


def _options_shown(command: str, options: dict) -> list[str]:
    """Each recorded setting of ``command`` as its option is typed (``--prior-steps 400``), once per option; a
    setting no option sets (``ppo.vf_coef``) under its own dotted name."""
    from famarl_cli.artifacts.made import flat_settings

    names = _option_names(command)
    shown = [f"{names.get(name, name)} {json.dumps(value)}" for name, value in flat_settings(options).items()]
    return list(dict.fromkeys(shown))


def _option_names(command: str) -> dict[str, str]:
    """The settings a making of ``command`` records, to the options that set them; empty for a command famarl no
    longer has."""
    from famarl_cli.artifacts.made import option_names
    from famarl_cli.cli.derived import click_command

    if command == "famarl train":  # a run records its spec, whose settings the options set under other names
        from famarl_cli.stages.train import setting_options

        return setting_options()
    found = click_command(app)
    for word in command.split()[1:]:
        found = getattr(found, "commands", {}).get(word)
    declaration = getattr(getattr(found, "callback", None), "declaration", None)
    return {} if declaration is None else option_names(declaration)
