"""Outputs of DVC stages, which only ``dvc repro`` writes.

A pipeline's outputs (``data/maze/runs``, ``data/maze/eval``, ...) belong to DVC: dvc.lock records their content,
and a file a command adds or changes there by hand makes the next ``dvc repro`` run the stage again, or fail where
the stage finds a folder it did not make. So no famarl command writes inside one, unless DVC runs it as that
stage: DVC sets ``DVC_STAGE`` in the environment of every stage's command. :func:`refuse_tracked` is the check,
made by every write (:func:`famarl_cli.artifacts.base.atomic_path`) and, before any work, by the commands that
write folders.

The outputs are read from the ``dvc.lock`` files of the DVC project around the path (its root's and those one or
two folders below it, as ``pipelines/<name>/dvc.lock``): the stages DVC has made, whose outputs a command could
spoil. A path outside any DVC project is never tracked.
"""

from __future__ import annotations

import functools
import os
from dataclasses import dataclass
from pathlib import Path

from famarl_cli.core.errors import UsageError

STAGE_VARIABLE = "DVC_STAGE"
"""Set by DVC for each stage's command (its address, ``train`` or ``pipelines/x/dvc.yaml:train@a``)."""


@dataclass(frozen=True)
class TrackedOutput:
    """One output of one DVC stage."""

    path: Path
    """The output, absolute."""
    stage: str
    definition: Path
    """The dvc.yaml that defines the stage, relative to the project's root."""

    def owns(self, path: Path) -> bool:
        return path == self.path or self.path in path.parents


def tracked_output(path: str | os.PathLike) -> TrackedOutput | None:
    """The DVC output that ``path`` lies in (or is), or None: outside a DVC project, not in any stage's output, or
    when DVC itself runs the command (``DVC_STAGE`` set)."""
    if os.environ.get(STAGE_VARIABLE):
        return None
    absolute = Path(os.path.abspath(path))
    root = next((folder for folder in absolute.parents if (folder / ".dvc").is_dir()), None)
    if root is None:
        return None
    return next((out for out in _outputs(root) if out.owns(absolute)), None)


def refuse_tracked(path: str | os.PathLike, instead: str = "give --out elsewhere") -> None:
    """A usage error where ``path`` lies in a DVC stage's output (:func:`tracked_output`), naming the stage and
    what to do instead."""
    found = tracked_output(path)
    if found is None:
        return
    shown = os.path.relpath(found.path)
    raise UsageError(
        f"{path} lies in {shown}, the output of the DVC stage {found.stage} ({found.definition}), which only "
        f"`dvc repro` writes (a file written there by hand makes the stage run again); {instead}"
    )


def _outputs(root: Path) -> tuple[TrackedOutput, ...]:
    locks = sorted([*root.glob("dvc.lock"), *root.glob("*/dvc.lock"), *root.glob("*/*/dvc.lock")])
    # Read again whenever a lock changed (a long-lived process, a notebook, sees a dvc repro made meanwhile).
    return _read_locks(root, tuple((lock, lock.stat().st_mtime_ns) for lock in locks))


@functools.cache
def _read_locks(root: Path, locks: tuple[tuple[Path, int], ...]) -> tuple[TrackedOutput, ...]:
    import yaml

    # libyaml's parser where there is one: a pipeline's lock is large, and the pure-Python one takes a second.
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    found = []
    for lock, _ in locks:
        try:
            stages = (yaml.load(lock.read_text(), Loader=loader) or {}).get("stages") or {}
            definition = lock.with_name("dvc.yaml")
            declared = {}
            if definition.is_file():
                declared = (yaml.load(definition.read_text(), Loader=loader) or {}).get("stages") or {}
        except Exception:  # a lock DVC could not read either: it protects nothing
            continue
        for name, stage in stages.items():
            # A foreach stage's lock entry is `name@key`; its wdir is the declaration's.
            wdir = (declared.get(name.split("@")[0]) or {}).get("wdir", ".")
            for out in (stage or {}).get("outs") or []:
                if isinstance(out, dict) and isinstance(out.get("path"), str):
                    path = Path(os.path.normpath(lock.parent / wdir / out["path"]))
                    found.append(TrackedOutput(path, name, definition.relative_to(root)))
    return tuple(found)
