"""A typer command derived from a stage's declared options (:mod:`famarl_cli.core.declare`): each field becomes
an option with its type, default, help and bounds, and the command's function receives the options object."""

from __future__ import annotations

import functools
import inspect
import typing
from collections.abc import Callable
from dataclasses import MISSING
from pathlib import Path
from typing import Annotated, Any

import typer

from famarl_cli.core.declare import Declared, declared

_ALIAS = "renamed__"
"""The prefix of a renamed option's hidden parameter, which takes its old spelling."""


def _take_old_spelling(option: Declared, given: dict) -> None:
    """Move the value given under ``option``'s old flag to the option (:func:`old_spelling`)."""
    default = option.text if option.parse is not None else option.default
    value = old_spelling(option.renamed[0], option.flag, given.pop(_ALIAS + option.name), given[option.name] != default)
    if value is not None:
        given[option.name] = value


def old_spelling(old: str, flag: str, value: Any, flag_given: bool) -> Any:
    """``value``, given under ``flag``'s old spelling ``old`` (None: not given), with a note that names the new
    flag; a usage error where both are given."""
    from famarl_cli.cli import note
    from famarl_cli.core.errors import UsageError

    if value is None:
        return None
    if flag_given:
        raise UsageError(f"{old} is the old spelling of {flag}: give one of them")
    note(f"{old} is now {flag}; the old spelling goes in the next release")
    return value


def _settings(option: Declared) -> dict[str, Any]:
    settings: dict[str, Any] = {"help": option.help}
    if option.min is not None:
        settings["min"] = option.min
    if option.max is not None:
        settings["max"] = option.max
    if option.path == "file":
        settings["dir_okay"] = False
    elif option.path == "dir":
        settings["file_okay"] = False
    if option.base in (Path, list[Path]):  # one placeholder for each kind of path, whatever typer would print
        settings["metavar"] = "<dir>" if option.path == "dir" else "<file>"
    if option.placeholder is not None:
        settings["metavar"] = option.placeholder
    return settings


def typer_option(option: Declared) -> tuple[Any, Any]:
    """(annotation, default) of ``option`` as a typer parameter."""
    settings = _settings(option)
    if option.parse is not None:  # written as text on the command line
        kind: Any = str | None if option.text is None else str
        default = option.text
    else:
        kind, default = option.type, option.default
    if option.argument:
        return Annotated[kind, typer.Argument(**settings, show_default=default is not MISSING)], default
    return Annotated[kind, typer.Option(*option.flags, **settings)], default


def command(registrar: typer.Typer, options: type, name: str | None = None, **settings: Any):
    """Register ``run(options) -> None`` as the command ``name`` of ``registrar`` whose options are the fields of the
    declaration ``options``; its docstring is the command's help. ``run`` is returned unchanged."""
    from famarl_cli.cli import reports_errors

    fields = declared(options)
    # --help lists the command's own options first, then those of the declarations it builds on.
    owner = {
        option.name: next(
            i for i, cls in enumerate(options.__mro__) if option.name in vars(cls).get("__annotations__", {})
        )
        for option in fields
    }
    shown = sorted(fields, key=lambda option: owner[option.name])

    def register(run: Callable[[Any], None]) -> Callable[[Any], None]:
        parameters = []
        for option in shown:
            annotation, default = typer_option(option)
            default = inspect.Parameter.empty if default is MISSING else default
            parameters.append(
                inspect.Parameter(option.name, inspect.Parameter.KEYWORD_ONLY, default=default, annotation=annotation)
            )
        renamed = [option for option in shown if option.renamed]
        for option in renamed:
            kind = typing.get_args(typer_option(option)[0])[0]
            alias = typer.Option(*option.renamed, **{**_settings(option), "hidden": True})
            parameters.append(
                inspect.Parameter(
                    _ALIAS + option.name,
                    inspect.Parameter.KEYWORD_ONLY,
                    default=None,
                    annotation=Annotated[kind | None, alias],
                )
            )
        annotations = {parameter.name: parameter.annotation for parameter in parameters}

        def invoke(**given: Any) -> None:
            for option in renamed:
                _take_old_spelling(option, given)
            return run(options(**parsed(fields, given)))

        invoke.__signature__ = inspect.Signature(parameters, return_annotation=None)
        invoke.__annotations__ = {**annotations, "return": None}
        invoke.__doc__ = run.__doc__
        invoke.__name__ = run.__name__
        invoke.declaration = options  # what famarl_cli.cli.names reads each option's origin from
        registrar.command(name, **settings)(reports_errors(invoke))
        return run

    return register


@functools.cache
def click_command(registrar: typer.Typer):
    """The click command typer builds for ``registrar``, built once: building it reads every command's signature
    (tens of milliseconds), and a sweep parses each of its runs' options with it. Every command has registered
    itself by then (importing famarl_cli.cli imports them all), and parsing leaves the command as it was."""
    return typer.main.get_command(registrar)


def parse_options(registrar: typer.Typer, name: str, options: type, argv: list[str]) -> dict:
    """The values of ``famarl NAME ARGV`` by option name, as the command derived from ``options`` parses them
    (bounds checked, texts parsed), before the declaration is built; a usage error is one line. ``NAME`` may name a
    subcommand ("prior fit")."""
    from famarl_cli.core.errors import UsageError

    parser = click_command(registrar)
    for part in name.split():
        parser = parser.commands[part]
    try:
        given = parser.make_context(f"famarl {name}", list(argv)).params
    except Exception as exc:  # typer's (bundled click's) usage errors: they carry their message
        if not hasattr(exc, "format_message"):
            raise
        raise UsageError(f"famarl {name} {' '.join(argv)}: {exc.format_message()}") from None
    return parsed(declared(options), given)


def parsed(fields: list[Declared], given: dict) -> dict:
    """The command line's values with the ones written as text parsed."""
    values = {}
    for option in fields:
        value = given[option.name]
        if option.parse is not None:
            value = option.default if value is None else option.parse(value)
        values[option.name] = value
    return values
