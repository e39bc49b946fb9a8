"""A sweep's plan: its axes, the jobs they expand to, each job's key, and what to do with the folder that holds
them.

A job's *key* hashes everything its result depends on: the function that runs it, its full config, the package
version, a fingerprint of the package's source, and the content of its input files. Two jobs with the same key
produce the same files (on the same machine), so a complete job whose key is unchanged is never run again.

Before a sweep runs, :func:`reconcile` compares the output folder with the plan, job folder by job folder:

============================================  ==========================================
the folder                                    becomes
============================================  ==========================================
missing or empty                              run
complete, same key                            skipped
started, same key                             resumed from where it stopped (run again
                                              where the job cannot resume)
any other key, or files the driver never      replaced: run again, the old work put back
marked                                        where the new fails
a job folder that is not in the plan          deleted
============================================  ==========================================

A sweep replaces or deletes only when allowed to (:func:`refuse_unasked`): a result it did not make in this call is
never lost silently.
"""

from __future__ import annotations

import functools
import hashlib
import itertools
import json
import re
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path

from famarl_cli import __version__
from famarl_cli.artifacts.base import read_object, sha256
from famarl_cli.artifacts.made import JOB_FILE, JOB_SCHEMA, JOB_SCHEMA_VERSION, shown_path, what_changed
from famarl_cli.artifacts.runs import CURVES_FILES
from famarl_cli.core.errors import ArtifactError, UsageError

MANIFEST = "sweep.json"
"""In the sweep's output folder: the plan (each job's name, axis values and key)."""

_RANGE = re.compile(r"^(\d+)-(\d+)$")


def parse_values(text: str) -> tuple[str, ...]:
    """``"0-9"`` -> 0..9, ``"0,3,7"`` -> 0, 3, 7, ``"a, b"`` -> a, b; ranges and lists mix (``"0-2,10"``)."""
    values: list[str] = []
    for part in (p.strip() for p in str(text).split(",")):
        if not part:
            continue
        found = _RANGE.match(part)
        if found:
            low, high = int(found[1]), int(found[2])
            if low > high:
                raise UsageError(f"range {part!r} runs backwards; write {high}-{low}")
            values += [str(v) for v in range(low, high + 1)]
        else:
            values.append(part)
    if not values:
        raise UsageError(f"no values in {text!r}")
    if len(set(values)) < len(values):
        raise UsageError(f"{text!r} repeats a value")
    return tuple(values)


@dataclass(frozen=True)
class Axis:
    name: str
    values: tuple[str, ...]

    @staticmethod
    def parse(text: str) -> Axis:
        """``NAME=V1,V2,...`` (values as :func:`parse_values` reads them)."""
        name, sep, values = text.partition("=")
        name = name.strip()
        if not sep or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_-]*", name):
            raise UsageError(f"--over takes NAME=V1,V2,...; got {text!r}")
        return Axis(name, parse_values(values))


def expand(axes: list[Axis]) -> list[dict[str, str]]:
    """Every combination of the axes' values, the first axis varying slowest."""
    names = [axis.name for axis in axes]
    if len(set(names)) < len(names):
        raise UsageError(f"an axis is given twice: {', '.join(names)}")
    return [dict(zip(names, combo, strict=True)) for combo in itertools.product(*(a.values for a in axes))]


def fill(template: str, point: dict[str, str]) -> str:
    """``template`` with ``{axis}`` replaced by the point's value."""
    try:
        return template.format_map(point)
    except KeyError as exc:
        raise UsageError(f"{template!r} names {{{exc.args[0]}}}, which is not an axis ({', '.join(point)})") from None
    except (ValueError, IndexError) as exc:
        raise UsageError(f"{template!r} is not a valid template ({exc})") from None


def default_name(point: dict[str, str]) -> str:
    """``famarl-seed3``, ``beta0.1-seed3``: each value, prefixed by its axis name when it is a number; the seed
    last."""
    ordered = sorted(point.items(), key=lambda item: item[0] == "seed")
    return "-".join(value if not re.fullmatch(r"[-+0-9.e]+", value) else f"{name}{value}" for name, value in ordered)


@dataclass(frozen=True)
class Job:
    """One unit of a sweep, run in a worker as ``runner(config, folder, context)``."""

    name: str
    """Its folder's name inside the sweep's output folder."""
    runner: str
    """``package.module:function``; any importable function can be a job kind."""
    config: dict
    """Everything the job is made from (JSON types only)."""
    inputs: tuple[str, ...] = ()
    """Files whose content the result depends on."""
    resumable: bool = False
    """Whether the runner can continue a folder it left unfinished."""
    point: dict = field(default_factory=dict)
    """The axis values this job was expanded from."""
    batched: bool = False
    """The runner takes a batch of jobs, ``runner(configs, contexts)``: jobs of the same :attr:`group` run
    together in one process (replicates fitted as one batched model)."""
    setting: str | None = None
    """What the jobs of one setting share, where the sweep knows it (the command's options before the seed is filled
    in, and the other axes' values); a batched job's :attr:`group`."""

    def __post_init__(self) -> None:
        if not re.fullmatch(r"[A-Za-z0-9_.+=-]+", self.name) or self.name.startswith("."):
            raise UsageError(f"{self.name!r} is not a usable folder name for a job (letters, digits, . _ + = -)")

    @property
    def key(self) -> str:
        return job_key(self)

    @property
    def group(self) -> str | None:
        """Jobs that may share a batch have the same group: the runner and the :attr:`setting`, else the config but
        for the seed (None: the job runs alone)."""
        if not self.batched:
            return None
        rest = self.setting or {key: value for key, value in self.config.items() if key != "seed"}
        return json.dumps([self.runner, rest], sort_keys=True)


def named_apart(jobs: list[Job]) -> list[Job]:
    """``jobs``, refused where two share a name: they would share a folder."""
    names = [job.name for job in jobs]
    if len(set(names)) < len(names):
        shared = next(name for name in names if names.count(name) > 1)
        raise UsageError(
            f"two runs of the sweep are named {shared!r} and would share its folder; give --name a template that "
            "tells them apart, with {seed} and each --over axis"
        )
    return jobs


def batches(jobs: list[Job], workers: int, most: int | None = None) -> list[list[int]]:
    """The jobs' indices in the batches they run in: each group of batched jobs split into
    ``ceil(len(group) / workers)``-sized batches (at most ``most``), so the group fills the workers; every other
    job alone. Batches keep the jobs' order."""
    groups: dict[str | None, list[int]] = {}
    result = []
    for index, job in enumerate(jobs):
        if job.group is None:
            result.append([index])
        else:
            groups.setdefault(job.group, []).append(index)
    for members in groups.values():
        size = max(1, -(-len(members) // max(workers, 1)))
        size = min(size, most) if most else size
        result += [members[i : i + size] for i in range(0, len(members), size)]
    return sorted(result)


@functools.cache
def code_fingerprint() -> str:
    """Hash of the package's source: a job's key changes whenever the code that runs it may have."""
    root = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


def made_from(job: Job) -> dict:
    """Everything a job's key hashes: the function that runs it, its config, famarl's version and source, and its
    input files' content hashes."""
    missing = [p for p in job.inputs if not Path(p).is_file()]
    if missing:
        raise ArtifactError(f"{missing[0]}: no such file (an input of job {job.name})")
    return {
        "runner": job.runner,
        "config": job.config,
        "famarl_version": __version__,
        "code": code_fingerprint(),
        "inputs": {shown_path(p): sha256(p) for p in job.inputs},
    }


def job_key(job: Job, made: dict | None = None) -> str:
    """The hash of :func:`made_from` (given, when the caller has it already)."""
    payload = made_from(job) if made is None else made
    return hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()


def job_record(job: Job, complete: bool, made: dict | None = None) -> dict:
    """What :data:`JOB_FILE` holds: the job's name, key, axis values and whether it is complete, and what the key
    hashes, so that a folder made from other inputs can say which (:func:`folder_action`)."""
    made = made_from(job) if made is None else made
    return {
        "schema": JOB_SCHEMA,
        "schema_version": JOB_SCHEMA_VERSION,
        "name": job.name,
        "key": job_key(job, made),
        "point": job.point,
        "complete": complete,
        **made,
    }


def _making(record: dict) -> dict:
    """A job record (or :func:`made_from`) as :mod:`famarl_cli.artifacts.made` words a making."""
    keys = {"command": "runner", "options": "config", "famarl_version": "famarl_version", "inputs": "inputs"}
    return {key: record.get(field) for key, field in keys.items()}


class Action(StrEnum):
    SKIP = "skip"
    RESUME = "resume"
    RUN = "run"


@dataclass
class Reconciliation:
    actions: dict[str, Action]
    """Per job name."""
    delete: list[Path]
    """Job folders of earlier plans."""
    replace: dict[str, str] = field(default_factory=dict)
    """Jobs whose folder holds something else, which running them replaces: why, per job name."""


def read_job_record(folder: Path) -> dict | None:
    """The driver's record in a job folder, or None when there is none (or it is unreadable)."""
    record = read_object(folder / JOB_FILE)
    return record if record is not None and record.get("schema") == JOB_SCHEMA else None


def reconcile(out: Path, jobs: list[Job], made: dict[str, dict]) -> Reconciliation:
    """What to do with each job's folder in ``out``, given what each job is made from (:func:`made_from`, by name),
    and which folders to delete (see the module doc)."""
    actions, replace = {}, {}
    for job in jobs:
        folder = out / job.name
        record = read_job_record(folder)
        if record is None or record.get("key") != job_key(job, made[job.name]):
            actions[job.name] = Action.RUN
            if held(folder):
                replace[job.name] = _replaced_because(record, made[job.name])
        elif record.get("complete"):
            actions[job.name] = Action.SKIP
        else:
            actions[job.name] = Action.RESUME if job.resumable else Action.RUN
    planned = {job.name for job in jobs}
    delete, foreign = [], []
    for entry in sorted(out.iterdir()) if out.is_dir() else []:
        # famarl evaluate's curves of the runs, beside them by default, are theirs: neither foreign nor to delete
        if entry.name in planned or entry.name in (MANIFEST, *CURVES_FILES) or entry.name.startswith("."):
            continue
        (delete if entry.is_dir() and (entry / JOB_FILE).is_file() else foreign).append(entry)
    if foreign:
        raise UsageError(
            f"{out} holds {foreign[0].name}, which is not a job folder of a famarl sweep; "
            "a sweep deletes what is not in its plan, so give it a folder of its own"
        )
    return Reconciliation(actions, delete, replace)


def _replaced_because(record: dict | None, made: dict) -> str:
    """Why a job's folder is not the job's: what its record says it was made from, in a few words."""
    if record is None:
        return "files no sweep recorded"
    if all(record.get(field) == made[field] for field in ("runner", "config", "inputs")):
        return "made by other famarl code"
    return "made from other options or inputs"


def refuse_unasked(out: Path, plan: Reconciliation) -> None:
    """A usage error naming every job folder in ``out`` that ``plan`` would delete or replace, with why, and the
    option that allows it; nothing where the plan only adds, skips and continues."""
    if not plan.delete and not plan.replace:
        return
    parts = []
    if plan.delete:
        parts.append(f"delete {', '.join(folder.name for folder in plan.delete)} (no longer in the plan)")
    if plan.replace:
        reasons: dict[str, list[str]] = {}
        for name, why in plan.replace.items():
            reasons.setdefault(why, []).append(name)
        parts.append("replace " + "; ".join(f"{', '.join(names)} ({why})" for why, names in reasons.items()))
    raise UsageError(
        f"{out} holds runs this sweep did not make: it would {' and '.join(parts)}; nothing was changed. Add "
        "--overwrite to let it, or give another --out"
    )


def held(folder: Path) -> list[Path]:
    """What a job wrote in ``folder``: its entries but the hidden ones (the lock a command holds it by)."""
    return sorted(e for e in folder.iterdir() if not e.name.startswith(".")) if folder.is_dir() else []


def folder_action(
    folder: Path, job: Job, overwrite: bool, made: dict | None = None, names: dict[str, str] | None = None
) -> Action:
    """What a command that makes one job in ``folder`` (``famarl macros --out``) does with what the folder holds:
    the sweep's rule for one folder, except that work made from other inputs is never replaced unasked.

    =======================================================  ==========================================
    the folder                                               becomes
    =======================================================  ==========================================
    missing or empty                                         run
    complete, same inputs and options                        skipped: already complete, nothing to do
    started, same inputs and options                         resumed from where it stopped
    other inputs or options, or files no famarl job recorded refused, unless ``overwrite``: run afresh
    =======================================================  ==========================================

    famarl's source is not compared, as for any command's output (:mod:`famarl_cli.artifacts.made`). ``made``: what
    the job is made from (:func:`made_from`), when the caller has it already; ``names``: the command's flag of each
    setting of the job's config (:func:`~famarl_cli.artifacts.made.option_names`), which the refusal names it by.
    """
    record = read_job_record(folder)
    if record is None:
        found = held(folder)
        if found and not overwrite:
            raise UsageError(
                f"{folder} holds files no famarl job recorded ({found[0].name}, ...); give an empty --out, or add "
                "--overwrite to replace them"
            )
        return Action.RUN
    if overwrite:
        return Action.RUN
    made = made_from(job) if made is None else made
    changes = what_changed(_making(record), _making(made), names)
    if changes:
        raise UsageError(
            f"{folder} was made from other inputs or options: {'; '.join(changes)}; add --overwrite to start over "
            "in it, or give another --out"
        )
    return Action.SKIP if record.get("complete") else Action.RESUME
