"""The ``famarl`` command line: thin typer commands that parse options and call the library, one module per stage.

Every command turns a :class:`~famarl_cli.core.errors.FamarlError` into one line on stderr and its exit code;
``famarl --debug ...`` shows the traceback instead.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

from famarl_cli import __version__
from famarl_cli.core.declare import declared
from famarl_cli.core.errors import FamarlError

app = typer.Typer(
    name="famarl",
    help="FaMARL: macro-action RL over disentangled latents of expert action sequences, stage by stage.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    # Help texts are plain: "[default: ...]" and "famarl[ray]" must not be read as rich markup and vanish.
    rich_markup_mode=None,
)
console = Console(stderr=True)
_debug = False


def _print_version(value: bool) -> None:
    if value:
        typer.echo(f"famarl {__version__}")
        raise typer.Exit()


@app.callback()
def _global_options(
    version: Annotated[
        bool, typer.Option("--version", callback=_print_version, is_eager=True, help="Print the version and exit.")
    ] = False,
    debug: Annotated[bool, typer.Option("--debug", help="Show the full traceback when a command fails.")] = False,
) -> None:
    global _debug
    _debug = debug


INTERRUPTED = 130
"""The exit code of a command stopped with Ctrl-C (128 + SIGINT, as shells report it)."""


def reports_errors(command):
    """Print a FamarlError as ``error: <message>`` and exit with its code, and Ctrl-C as one line and exit 130,
    unless ``--debug`` is on."""

    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        try:
            return command(*args, **kwargs)
        except FamarlError as exc:
            if _debug:
                raise
            typer.echo(f"error: {exc}", err=True)
            raise typer.Exit(exc.exit_code) from None
        except KeyboardInterrupt:
            if _debug:
                raise
            # Every artifact is written to a temporary name and renamed when complete: an interrupted stage leaves
            # each file as it was or complete, never half-written (a run's last checkpoint is one to resume from).
            typer.echo(
                "error: interrupted; no file was left half-written (files completed before stay; famarl train "
                "--resume, or the same famarl macros or sweep, continues)",
                err=True,
            )
            raise typer.Exit(INTERRUPTED) from None

    return wrapper


def torch_on_one_thread() -> None:
    """Small networks train fastest on one thread (measured: a second adds nothing on a 2-core laptop); the
    portable profile's backends when it is on (famarl_cli.core.reproducibility)."""
    from famarl_cli.core.reproducibility import one_thread

    one_thread()


@dataclass(frozen=True)
class JobRecipe:
    """What one point of ``famarl sweep COMMAND`` runs: a job runner (the function itself, so a renamed runner fails
    when the sweep is planned, never in a worker), its config, its input files, and whether it can continue
    unfinished work (famarl_cli.sweep.plan.Job gets its name and key from the sweep)."""

    runner: Callable[..., dict | None]
    config: dict
    inputs: tuple[str, ...] = ()
    resumable: bool = False
    batched: bool = False
    """The runner takes several jobs that differ only in their seed at once (``runner(configs, contexts)``), and
    a sweep gives it batches of them (famarl_cli.sweep.plan.Job.batched)."""


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


def progress_bar() -> Progress:
    """A bar on a terminal that leaves no trace when done. Off when stderr is not a terminal (a log, DVC, a pipe):
    there a transient bar draws nothing anyway, but would leave an empty line before the command's output or its
    ``error:`` line."""
    return Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeRemainingColumn(),
        console=console,
        transient=True,
        disable=not console.is_terminal,
    )


def main() -> None:
    app()


# The commands register themselves on ``app`` when their modules are imported.
from famarl_cli.cli import (  # noqa: E402, F401
    demos,
    docs,
    evaluate,
    favae,
    inspect,
    macros,
    minari,
    prior,
    report,
    segment,
    sequences,
    sweep,
    train,
    traverse,
)
