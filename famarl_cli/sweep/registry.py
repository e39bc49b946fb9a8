"""The commands ``famarl sweep`` can run many of: each registers what one point of a sweep runs
(:func:`sweepable`), and a sweep plans its jobs from :data:`SWEEPABLE`."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from famarl_cli.core.declare import declared


@dataclass(frozen=True)
class JobRecipe:
    """What one point of ``famarl sweep COMMAND`` runs: a job runner (the function itself, so a renamed runner fails
    when the sweep is planned, never in a worker), its config, its input files, and whether it can continue
    unfinished work (:class:`~famarl_cli.sweep.plan.Job` gets its name and key from the sweep)."""

    runner: Callable[..., dict | None]
    config: dict
    inputs: tuple[str, ...] = ()
    resumable: bool = False
    batched: bool = False
    """The runner takes several jobs that differ only in their seed at once (``runner(configs, contexts)``), and
    a sweep gives it batches of them (:attr:`~famarl_cli.sweep.plan.Job.batched`)."""


@dataclass(frozen=True)
class Sweepable:
    options: type
    """The command's declared options (famarl_cli.core.declare): a sweep's axes are typed by them."""
    make: Callable[[Any], JobRecipe]
    """From the command's options to the job."""
    owned: tuple[str, ...]
    """Options the sweep sets itself (the output folder), which the command's options must not give."""
    refused: dict[str, str]
    """Options of the command that a sweep does not offer, and why."""
    command: str
    """The command a point runs ("prior fit" for ``famarl sweep prior``)."""


SWEEPABLE: dict[str, Sweepable] = {}
"""Commands that ``famarl sweep`` can run many of; each registers itself with :func:`sweepable`."""


def sweepable(
    command: str,
    options: type,
    owned: tuple[str, ...] = (),
    refused: dict[str, str] | None = None,
    runs: str | None = None,
):
    """Register ``make(options) -> JobRecipe`` as what ``famarl sweep COMMAND`` runs per point (the command ``runs``,
    "prior fit", where it is not COMMAND itself); the options named in ``owned`` and ``refused`` must be the
    declaration's."""
    flags = {option.flag for option in declared(options)}
    unknown = sorted((set(owned) | set(refused or {})) - flags)
    if unknown:
        raise TypeError(f"famarl {command} has no options {', '.join(unknown)}")

    def register(make: Callable[[Any], JobRecipe]) -> Callable[[Any], JobRecipe]:
        SWEEPABLE[command] = Sweepable(options, make, owned, refused or {}, runs or command)
        return make

    return register
