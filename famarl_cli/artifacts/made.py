"""What an output was made from, and the one rule every command follows for an output that is there already.

An output's *making* is the command that wrote it, the command's options (those that change what it makes: where
it writes, whether it also draws a picture, how many workers it uses do not), famarl's version and its input files'
content hashes. Every artifact records its making in its provenance (``made_from``, :func:`making`); a
``famarl macros`` folder and a sweep's job folder in their ``job.json`` (:mod:`famarl_cli.sweep.plan`).

Run again where its output is, a command follows :func:`claim_output`:

=========================================================  ===========================================
the output                                                 the command
=========================================================  ===========================================
missing                                                    makes it
there and complete, made from the same inputs and options  "already complete; nothing to do"
there but not complete (a file of it missing)              makes it again
made from other inputs or options                          refused, naming what changed (by its option)
a file that records no making (by hand, or older famarl)   refused
a file that cannot be read (truncated, corrupt)            refused, saying so
=========================================================  ===========================================

A *derived* output, a result computed from a run (``famarl evaluate``'s, ``famarl oracle``'s), made by the same
command and options from inputs that changed since (the run was trained further), is out of date rather than
another's work: it is made again, not refused.

``--overwrite`` makes it afresh in every case. An output in a DVC stage's output (:mod:`famarl_cli.artifacts.tracked`)
that would be made, or that is refused, is refused as DVC's first: no option lets a command write there by hand.
famarl's own source is not part of the making (as with any tool, a
new release is a new version): a sweep's key adds it, because DVC re-runs a sweep's stage when the code changes.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import h5py

from famarl_cli import __version__
from famarl_cli.artifacts.base import file_kind, sha256
from famarl_cli.core.declare import affecting, declared, option
from famarl_cli.core.errors import UsageError
from famarl_cli.core.reproducibility import platform_facts


def shown_path(path: str | os.PathLike) -> str:
    """``path`` as a record names it: relative to the working folder where it lies inside it (the project's root,
    for DVC), so that a record does not change with the folder a project was cloned into."""
    path = Path(path)
    if path.is_absolute():
        try:
            return str(path.relative_to(Path.cwd()))
        except ValueError:
            return str(path)
    return str(path)


def input_files(options: Any) -> list[Path]:
    """The files an options object reads: its options typed as paths that affect the output and name a file."""
    found = []
    for declaration in declared(type(options)):
        if not declaration.affects or declaration.base not in (Path, list[Path]):
            continue
        value = getattr(options, declaration.name)
        found += [Path(v) for v in (value if isinstance(value, list) else [value]) if v and Path(v).is_file()]
    return found


def making(command: str, options: Any, inputs: Iterable[str | os.PathLike] = ()) -> dict:
    """What ``command`` with ``options`` makes its output from: the options that change it, famarl's version and
    the content of the files the options name, with ``inputs`` (files the options imply, a run's checkpoint).
    ``options`` is a declaration (:mod:`famarl_cli.core.declare`), or a dict of the settings themselves (a run's
    spec, every entry of which changes the run)."""
    given = isinstance(options, dict)
    files = dict.fromkeys([*([] if given else input_files(options)), *map(Path, inputs)])
    return {
        "command": command,
        "options": options if given else _settings(options),
        "famarl_version": __version__,
        "inputs": {shown_path(p): sha256(p) for p in files},
    }


def _settings(options: Any) -> dict:
    """The options that change what a command makes, but those naming files: a file counts by its content (the
    making's inputs), not by the name it was given under (``d.h5`` and ``./d.h5``, or a project cloned elsewhere)."""
    paths = {d.name for d in declared(type(options)) if d.base in (Path, list[Path])}
    return {name: value for name, value in affecting(options).items() if name not in paths}


def provenance(
    command: str,
    params: dict[str, Any],
    seed: int | None,
    inputs: Iterable[str | os.PathLike] = (),
    options: Any = None,
) -> dict:
    """What made an artifact: command, parameters, seed, package version, the inputs' content hashes, the platform
    facts that decide its floats (:func:`famarl_cli.core.reproducibility.platform_facts`) and, given the command's
    ``options``, its making (:func:`making`), by which a command run again knows its work (:func:`claim_output`)."""
    inputs = list(inputs)
    made = None if options is None else making(command, options, inputs)
    hashed = {} if made is None else made["inputs"]  # each input's content read once
    return _recorded(
        command, params, seed, {shown_path(p): hashed.get(shown_path(p)) or sha256(p) for p in inputs}, made
    )


def provenance_of(made: dict, params: dict[str, Any], seed: int | None) -> dict:
    """:func:`provenance` of an output whose making (:func:`making`) was taken already, to see whether it was there:
    its inputs are the making's, each file's content read once."""
    return _recorded(made["command"], params, seed, dict(made["inputs"]), made)


def _recorded(command: str, params: dict[str, Any], seed: int | None, inputs: dict, made: dict | None) -> dict:
    prov = {
        "command": command,
        "params": params,
        "seed": seed,
        "famarl_version": __version__,
        "inputs": inputs,
        "platform": platform_facts(),
    }
    return prov if made is None else {**prov, "made_from": made}


def _provenance(path: Path) -> dict:
    """The provenance an artifact records (HDF5, JSON or torch checkpoint), empty where it records none (other
    bytes: a file made by hand); the reader's exception where a file of those kinds cannot be read."""
    kind = file_kind(path)
    if kind == "empty":
        raise ValueError("the file is empty")
    if kind is None:
        return {}
    if kind == "hdf5":
        with h5py.File(path, "r") as handle:
            prov = json.loads(handle.attrs.get("provenance", "{}"))
    elif kind == "torch":
        import torch

        prov = torch.load(path, map_location="cpu", weights_only=True).get("provenance", {})
    else:
        prov = json.loads(path.read_text()).get("provenance", {})
    return prov if isinstance(prov, dict) else {}


def read_provenance(path: Path) -> dict:
    """The provenance an artifact records; empty where it records none or cannot be read."""
    try:
        return _provenance(path)
    except Exception:  # an unreadable file records nothing
        return {}


def recorded_making(path: Path) -> dict | None:
    """The making an artifact records in its provenance, or None where it records none or cannot be read."""
    made = read_provenance(path).get("made_from")
    return made if isinstance(made, dict) else None


def flat_settings(options: dict, prefix: str = "") -> dict:
    """Nested settings by dotted name (``ppo.total_steps``), so that a change names the one that changed."""
    flat = {}
    for name, value in options.items():
        if isinstance(value, dict) and value:
            flat.update(flat_settings(value, f"{prefix}{name}."))
        else:
            flat[f"{prefix}{name}"] = value
    return flat


def what_changed(before: dict, now: dict, names: dict[str, str] | None = None) -> list[str]:
    """How the making ``now`` differs from ``before``, in words: the command, each option (``--update-epochs 10 ->
    5``: named by ``names``, a setting's dotted name to the command's option, where given; by the setting's name
    otherwise), each input whose content changed, famarl's version."""
    names = names or {}
    changes = [] if before.get("command") == now["command"] else [f"the command ({before.get('command')})"]
    changes += _changed_options(before, now, names)
    inputs = before.get("inputs")
    if inputs is None:
        changes.append("its inputs (the record does not hold their contents)")
    else:
        was, read = set(inputs.values()), set(now["inputs"].values())
        changes += [f"the content of {p}" for p, digest in now["inputs"].items() if digest not in was]
        gone = [p for p, digest in inputs.items() if digest not in read and p not in now["inputs"]]
        changes += [f"{p}, read before and not now" for p in gone]
    if before.get("famarl_version") != now["famarl_version"]:
        changes.append(f"famarl {before.get('famarl_version')} -> {now['famarl_version']}")
    return changes


def _changed_options(before: dict, now: dict, names: dict[str, str]) -> list[str]:
    """Each option whose value differs, once under the name the user types (two settings of one option, as
    ``--normalize`` sets both of its, read as one change)."""
    was_options, options = flat_settings(before.get("options") or {}), flat_settings(now["options"])
    # a setting recorded under an option's former name (named, like the option, by its flag) is that option
    for old in set(was_options) - set(options):
        new = [name for name in set(options) - set(was_options) if names.get(name, name) == names.get(old)]
        if len(new) == 1:
            was_options[new[0]] = was_options.pop(old)
    changes = []
    for name in sorted(set(was_options) | set(options)):
        if was_options.get(name) != options.get(name):
            change = f"{names.get(name, name)} {json.dumps(was_options.get(name))} -> {json.dumps(options.get(name))}"
            if change not in changes:
                changes.append(change)
    return changes


def option_names(cls: type) -> dict[str, str]:
    """Each option of the declaration ``cls`` by its setting's name, to its flag (``epochs`` -> ``--update-epochs``):
    how a refusal names what changed. A setting's former names (a record written before it was renamed) map to the
    same flag, so that a record of the same option under its old name is no change."""
    return {name: d.flag for d in declared(cls) for name in (d.name, *d.former)}


def claim_output(
    outputs: list[Path],
    made: dict,
    overwrite: bool,
    instead: str = "give another --out",
    names: dict[str, str] | None = None,
    derived: bool = False,
) -> bool:
    """Whether to make ``outputs`` (the first records the making; all of them make it complete) by the rule of the
    module doc: True to make them, False where they are complete and made so; a usage error otherwise, whose hint
    offers ``--overwrite`` or ``instead`` and names the changed options by ``names`` (:func:`what_changed`).

    ``derived``: the output is a result computed from its inputs (an evaluation of a run), so one made by the same
    command and options from inputs that have changed since (the run trained further) is out of date, not someone
    else's work: it is made again, not refused.

    Where it would be made or refused, an output lying in a DVC stage's output is refused as such first
    (:func:`~famarl_cli.artifacts.tracked.refuse_tracked`): before any work, and before advice (``--overwrite``)
    that could not help."""
    from famarl_cli.artifacts.tracked import refuse_tracked

    try:
        afresh = _claim(outputs, made, overwrite, instead, names, derived)
    except UsageError:
        for output in outputs:
            refuse_tracked(output)
        raise
    if afresh:
        for output in outputs:
            refuse_tracked(output)
    return afresh


def _claim(
    outputs: list[Path], made: dict, overwrite: bool, instead: str, names: dict[str, str] | None, derived: bool
) -> bool:
    """:func:`claim_output`'s rule, DVC's outputs aside."""
    primary = outputs[0]
    if overwrite or not primary.exists():
        return True
    try:
        recorded = _provenance(primary).get("made_from")
    except Exception as exc:
        why = " ".join(f"{type(exc).__name__}: {exc}".split())
        raise UsageError(
            f"{primary} exists and cannot be read (truncated or corrupt? {why}); add --overwrite to replace it, or "
            f"{instead}"
        ) from None
    if not isinstance(recorded, dict):
        raise UsageError(
            f"{primary} exists and does not record what it was made from (made by hand or by an older famarl); "
            f"add --overwrite to replace it, or {instead}"
        )
    changes = what_changed(recorded, made, names)
    if changes and derived and recorded.get("command") == made["command"] and not _changed_options(recorded, made, {}):
        return True
    if changes:
        raise UsageError(
            f"{primary} was made from other inputs or options: {'; '.join(changes)}; add --overwrite to make it "
            f"afresh, or {instead}"
        )
    return not all(p.exists() for p in outputs)


JOB_FILE = "job.json"
"""In every job folder (and a ``famarl macros`` folder), :func:`famarl_cli.sweep.plan.job_record`: the job's key,
what it hashes and whether the job is complete. In a sweep, the driver alone writes it."""
JOB_SCHEMA, JOB_SCHEMA_VERSION = "famarl.job", 1

ALREADY_MADE = "already holds this, complete and made from the same inputs and options; nothing to do"
"""What a command says where :func:`claim_output` finds its work done (after the output's name)."""


@dataclass(frozen=True)
class Replaceable:
    """The option of every command that writes an output (:func:`claim_output`)."""

    overwrite: bool = option(
        False,
        "Make the output afresh where it exists (made from other inputs or options, or by hand); without it, a "
        "complete output made from the same inputs and options is left as it is.",
        affects=False,
    )


def made_result(
    path: Path, made: dict, overwrite: bool, instead: str = "give another --out", names: dict[str, str] | None = None
) -> dict | None:
    """A JSON result (an evaluation, an oracle's) that ``path`` holds, complete and made so (less its provenance),
    or None where it is to be made (:func:`claim_output`'s rule for a derived output: one whose inputs have changed
    since, the run trained further, is made again)."""
    if claim_output([path], made, overwrite, instead, names, derived=True):
        return None
    return {key: value for key, value in json.loads(path.read_text()).items() if key != "provenance"}
