"""The ``famarl`` command line: thin typer commands that parse options and call the library, one module per stage.

Every failure is one line on stderr, ``error: ...``, and an exit code (``famarl --debug ...`` shows the traceback
instead):

- **2, usage:** the command line is wrong: an unknown option or command, a value out of its bounds or of the wrong
  kind, options that do not go together, a name famarl does not know (an env id, a script). The option parser's own
  errors are rendered so too (:class:`Famarl`), with the command's ``--help`` named.
- **1, input:** the command line is right but what it points at is not: a missing or malformed file, data that
  does not fit (a FAVAE of another action size than the env's), a GPU that is not there.
- **130:** stopped with Ctrl-C.
"""

from __future__ import annotations

import functools
import importlib
import os
import sys
import threading
from collections.abc import Collection, Iterable, Sequence
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn
from rich.table import Table
from typer import core as typer_core
from typer.core import TyperGroup

from famarl_cli import __version__
from famarl_cli.core.errors import FamarlError, UsageError

# the click typer parses with: its own copy from typer 0.25 on, click itself before
click = getattr(typer_core, "_click", None) or typer_core.click
current_context = importlib.import_module(f"{click.__name__}.globals").get_current_context
NO_ARGS_IS_HELP = getattr(click.exceptions, "NoArgsIsHelpError", ())
"""click >= 8.2's "no arguments: show the help" (a usage error whose message is the help)."""


WORKFLOW = (
    "demos", "segment", "favae", "macros", "traverse", "prior", "train", "evaluate", "oracle", "report", "power",
    "sweep", "sequences", "export-minari", "inspect", "status", "docs",
)  # fmt: skip
"""The commands in the order a user meets them (``famarl --help``); one not named here comes last."""


class Famarl(TyperGroup):
    """The root command: its commands listed in workflow order (:data:`WORKFLOW`), and the option parser's usage
    errors (a bad value, an unknown option) as famarl's one ``error:`` line naming the command's ``--help``, exit 2,
    instead of click's four-line usage block."""

    def list_commands(self, ctx) -> list[str]:
        names = super().list_commands(ctx)
        return sorted(names, key=lambda name: WORKFLOW.index(name) if name in WORKFLOW else len(WORKFLOW))

    def main(self, *args, standalone_mode: bool = True, **kwargs):
        if not standalone_mode:
            return super().main(*args, standalone_mode=False, **kwargs)
        try:
            code = super().main(*args, standalone_mode=False, **kwargs)
        except NO_ARGS_IS_HELP as exc:  # "famarl" alone: its help, as before
            exc.show()
            sys.exit(exc.exit_code)
        except click.exceptions.ClickException as exc:
            where = exc.ctx.command_path if getattr(exc, "ctx", None) is not None else "famarl"
            message = " ".join(exc.format_message().split())
            typer.echo(f"error: {message} (see `{where} --help`)", err=True)
            sys.exit(exc.exit_code)
        except typer.Abort:
            typer.echo("error: aborted", err=True)
            sys.exit(1)
        # what click returns without standalone_mode: an Exit's code, or a command's own return value (none)
        sys.exit(code if isinstance(code, int) else 0)


app = typer.Typer(
    name="famarl",
    cls=Famarl,
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
            typer.echo(f"error: {exc}{_help_hint(exc)}", err=True)
            raise typer.Exit(exc.exit_code) from None
        except KeyboardInterrupt:
            if _debug:
                raise
            # Every artifact is written to a temporary name and renamed when complete: an interrupted stage leaves
            # each file as it was or complete, never half-written (a run's last checkpoint is one to resume from).
            typer.echo(
                "error: interrupted; no file was left half-written (files completed before stay; famarl train "
                "--resume continues a run from its last checkpoint, where one was saved; the same famarl macros or "
                "sweep continues its work)",
                err=True,
            )
            if any(thread.daemon and thread.is_alive() for thread in threading.enumerate()):
                # A job's daemon thread (famarl sweep --jobs 1, famarl evaluate) is abandoned either way; one inside
                # torch when the interpreter finalises aborts the process (exit 134, "terminate called without an
                # active exception"), so leave without finalising.
                sys.stdout.flush()
                sys.stderr.flush()
                os._exit(INTERRUPTED)
            raise typer.Exit(INTERRUPTED) from None

    return wrapper


def _help_hint(exc: FamarlError) -> str:
    """For a usage error (the command line is wrong), where the right one is described, as the option parser's own
    errors say it (:class:`Famarl`)."""
    context = current_context(silent=True)
    if not isinstance(exc, UsageError) or context is None:
        return ""
    return f" (see `{context.command_path} --help`)"


def note(text: str) -> None:
    """``note: ...`` on stderr: what a user should know that is not an error."""
    typer.echo(f"note: {text}", err=True)


ROOT = Annotated[Path, typer.Option(help="The project's root (its dvc.yaml).", file_okay=False)]
"""``--root``, of the commands that read a project's committed results."""


def already_made(command: str, options: Any, outputs: list, inputs: tuple = ()) -> bool:
    """Whether ``outputs`` are there, complete and made by ``command`` from the same inputs and options (then a
    note says so and the command does nothing); a usage error where they were made otherwise, unless
    ``options.overwrite`` (:func:`famarl_cli.artifacts.made.claim_output`, the rule every command follows), or where
    they lie in a DVC stage's output (:mod:`famarl_cli.artifacts.tracked`)."""
    from famarl_cli.artifacts.made import ALREADY_MADE, claim_output, making, option_names

    made = making(command, options, inputs)
    if claim_output(outputs, made, options.overwrite, names=option_names(type(options))):
        return False
    note(f"{outputs[0]} {ALREADY_MADE} (--overwrite makes it afresh)")
    return True


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


def results_console() -> Console:
    """Where a command prints its results (stdout). Its lines are never broken or cut to the terminal's width (the
    terminal wraps them), so a table's title and a ``written ...`` line keep their paths whole; a table still fits
    its columns to the width, and its names column stays whole (:func:`named_rows`)."""
    return Console(soft_wrap=True)


def named_rows(title: str, columns: Sequence[str], left: Collection[str] = ()) -> Table:
    """A table whose first column names each row (a run, a label, a pipeline): never wrapped nor cut short at any
    terminal width (ten runs ``famarl-seed0`` .. ``famarl-seed9`` must not all read ``famarl-s…``); the other columns
    wrap to make room. The columns named in ``left`` (text) are left-justified like the names, the others (numbers)
    right-justified."""
    table = Table(title=title)
    for index, column in enumerate(columns):
        table.add_column(column, justify="left" if index == 0 or column in left else "right", no_wrap=index == 0)
    return table


def print_written(paths: Iterable) -> None:
    """``written A, B, ...``: the files a command wrote, each path whole (:func:`results_console`; a bracket in a
    path is not markup)."""
    results_console().print("written " + ", ".join(map(str, paths)), markup=False)


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
    oracle,
    power,
    prior,
    report,
    segment,
    sequences,
    status,
    sweep,
    train,
    traverse,
)
