"""The experiments of the paper, one module each, with their claims, tables and figures.

A module registers its experiment with :func:`experiment`; :func:`experiments` imports every module of this
package, so a new experiment is a new file here and nothing else changes. ``build(data, out)`` reads what the
experiment's pipeline left under ``data`` and writes its figures into ``out``; it returns None when there is
nothing to report yet.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Experiment:
    name: str
    pipeline: str
    """The DVC pipeline that makes its data."""
    order: int
    """Its place in the report (the paper's order)."""
    build: Callable[[Path, Path], object]
    goals: bool = False
    """Its claims are goals of ours beyond the paper (met, missed) rather than the paper's claims."""
    rejudges: tuple[tuple[str, str, str], ...] = ()
    """Its claims that re-judge another experiment's runs: (its claim, the other experiment, the other's claim), for
    claims whose words differ from the other's (:mod:`famarl_cli.report.kinds`)."""


_REGISTRY: dict[str, Experiment] = {}


def experiment(
    name: str, pipeline: str, order: int, *, goals: bool = False, rejudges: dict[str, tuple[str, str]] | None = None
):
    """Register an experiment; ``goals``: its claims are goals beyond the paper; ``rejudges``: per claim of its own
    that re-judges another experiment's runs, (that experiment, its claim)."""

    def register(build: Callable[[Path, Path], object]) -> Callable[[Path, Path], object]:
        pairs = tuple((claim, other, theirs) for claim, (other, theirs) in (rejudges or {}).items())
        _REGISTRY[name] = Experiment(name, pipeline, order, build, goals, pairs)
        return build

    return register


def experiments() -> dict[str, Experiment]:
    """Every experiment, in the report's order."""
    for module in pkgutil.iter_modules(__path__):
        importlib.import_module(f"{__name__}.{module.name}")
    return dict(sorted(_REGISTRY.items(), key=lambda item: item[1].order))
