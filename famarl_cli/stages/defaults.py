"""Where a command finds its inputs when none is given: the files of the manual chain (``famarl demos``, ``segment``,
``favae fit``, ``train`` with their defaults, under ``data/``), else those the main job writes (``dvc repro``, under
``data/maze/``); a command that finds neither says in one line where it looked and what to pass."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from famarl_cli.artifacts.segments import REPLICATE_FILE
from famarl_cli.core.declare import option
from famarl_cli.core.errors import ArtifactError

DEMOS = Path("data/demos/pushed-down-only.h5")
"""What famarl demos writes with its defaults; the main job's demos too."""
SEGMENTS = Path("data/segments/pushed-down-only.h5")
"""What famarl segment writes with its defaults."""
FAVAE = Path("data/favae/pushed-down-only.pt")
"""What famarl favae fit writes by default, after famarl demos and famarl segment with their defaults."""
MAIN_JOB = Path("data/maze")
"""Where the main job (the root dvc.yaml) writes its replicates (macros/seed<S>/) and runs (runs/)."""
REPLICATE_FAVAE = "favae.pt"
"""The FAVAE's file in a replicate's folder (famarl macros)."""
REPLICATE_DEMOS = "demos.h5"
"""The demos' file in each run folder of famarl sweep demos (its runner's ``DEMOS_FILE``; named here too, so that
what reads demos need not import the command that records them)."""

_MANUAL = "famarl demos --script pushed-down-only, famarl segment"


def replicate(seed: int) -> Path:
    """The main job's folder of replicate ``seed`` (famarl macros --seed S)."""
    return MAIN_JOB / "macros" / f"seed{seed}"


def favae(flag: str, seed: int = 0) -> Path:
    """The manual chain's FAVAE, else the main job's replicate ``seed``'s."""
    return _first("FAVAE", flag, (FAVAE, f"{_MANUAL}, famarl favae fit"), replicate(seed) / REPLICATE_FAVAE)


def segments(flag: str, seed: int = 0) -> Path:
    """The manual chain's segments, else those of the main job's replicate ``seed``."""
    return _first("segments", flag, (SEGMENTS, _MANUAL), replicate(seed) / REPLICATE_FILE)


def runs(flag: str, manual: Path | None) -> Path:
    """famarl train's default run folder ``manual`` (None where it has none: no FAVAE to name it by), else the main
    job's folder of runs."""
    return _first("run", flag, None if manual is None else (manual, "famarl train"), MAIN_JOB / "runs")


def named_after(path: str | os.PathLike) -> str:
    """The name of what a command makes by default from the file ``path``: its stem (``pushed-down-only``), or, for a
    file named as every replicate's is (``favae.pt``, ``segments.h5``, ``demos.h5`` in a ``famarl macros`` or sweep
    folder), the folders that tell the replicates apart, from under ``data/`` (``maze-macros-seed1``), so that the
    outputs of two replicates never share a name."""
    path = Path(path)
    if path.name not in (REPLICATE_FAVAE, REPLICATE_FILE, REPLICATE_DEMOS):
        return path.stem
    folder = Path(os.path.abspath(path)).parent
    parts = folder.relative_to(Path.cwd()).parts if folder.is_relative_to(Path.cwd()) else folder.parts[1:]
    return "-".join(parts[1:] if parts[:1] == ("data",) else parts) or path.stem


def is_main_jobs(path: Path) -> bool:
    """Whether ``path`` is one of the main job's files or folders."""
    return MAIN_JOB in Path(path).parents


def _first(what: str, flag: str, manual: tuple[Path, str] | None, main_job: Path) -> Path:
    for candidate in ([] if manual is None else [manual[0]]) + [main_job]:
        if candidate.exists():
            return candidate
    where = f"{main_job} (dvc repro) does not exist"
    if manual is not None:
        where = f"neither {manual[0]} ({manual[1]}) nor {main_job} (dvc repro) exists"
    raise ArtifactError(f"no {what} given, and {where}; make one, or give {flag}")


@dataclass(frozen=True)
class FavaeInput:
    """The FAVAE a command reads, declared once for every command that takes one (``--favae``)."""

    favae: Path | None = option(
        None,
        f"FAVAE checkpoint (from famarl favae fit or famarl macros).  [default: {FAVAE}, else the main job's "
        f"{replicate(0) / REPLICATE_FAVAE}]",
    )
