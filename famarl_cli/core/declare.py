"""Options declared once: a stage's options are a frozen dataclass whose fields carry their type, default, help and
bounds (:func:`option`). The ``famarl`` command (:mod:`famarl_cli.cli.derived`), a sweep's typed values and jobs
(parsed by the command, :func:`to_json`, :func:`from_json`) and the provenance the stage records all come from it, so a
default changes in one line and shows up everywhere.

Torch-free and typer-free: the declarations are imported when the CLI starts.
"""

from __future__ import annotations

import dataclasses
import enum
import types
import typing
from collections.abc import Callable
from dataclasses import MISSING, dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from famarl_cli.core.errors import UsageError


def option(
    default: Any = MISSING,
    help: str = "",
    *,
    factory: Callable[[], Any] | None = None,
    min: float | None = None,
    max: float | None = None,
    flags: tuple[str, ...] = (),
    path: str | None = None,
    text: str | None = None,
    parse: Callable[[str], Any] | None = None,
    argument: bool = False,
    affects: bool = True,
    renamed: tuple[str, ...] = (),
    former: tuple[str, ...] = (),
    placeholder: str | None = None,
) -> Any:
    """One option's declaration (a dataclass field).

    ``min``/``max`` bound numbers; ``flags`` replaces the option's name on the command line (``--peak-neighbours``
    for ``neighbours``, or a short ``-s`` beside it); ``path`` is ``"file"`` or ``"dir"`` for a path that must be
    one. A value that the command line writes as text (a list of numbers, JSON) has ``parse`` (text -> value) and
    its default ``text``. An ``argument`` is given by its place, not by a flag (without a default, it is required).
    ``affects=False``: the option says where or how the command shows what it makes (its output's path, a picture,
    its workers), not what it makes, so an output made without it is the same (:mod:`famarl_cli.artifacts.made`).
    ``renamed``: the option's old flags, still accepted, hidden, with a note that names the new one.
    ``former``: the option's old names in records (a setting renamed to the flag's name): a record written before
    still reads (:func:`from_json`, :func:`current_names`).
    ``placeholder``: what ``--help`` shows for the value where its type says too little (``<name=values>``).
    """
    metadata = {
        "help": help,
        "min": min,
        "max": max,
        "flags": flags,
        "path": path,
        "text": text,
        "parse": parse,
        "argument": argument,
        "affects": affects,
        "renamed": renamed,
        "former": former,
        "placeholder": placeholder,
    }
    if factory is not None:
        return dataclasses.field(default_factory=factory, metadata=metadata)
    return dataclasses.field(default=default, metadata=metadata)


def same_as(owner: type, name: str, default: Any = MISSING, **changes: Any) -> Any:
    """The field ``name`` of the declaration ``owner`` again, under another name or with another help (``changes``
    as :func:`option` takes them), or with another ``default`` where a command finds the file by itself: its
    bounds stay declared once, and it stays one concept with one flag on every command (:attr:`Declared.origin`)."""
    source = next(f for f in fields(owner) if f.name == name)
    metadata = {"origin": _origin(owner, source), **source.metadata, **changes}
    if default is not MISSING:
        return dataclasses.field(default=default, metadata=metadata)
    if source.default_factory is not MISSING:
        return dataclasses.field(default_factory=source.default_factory, metadata=metadata)
    return dataclasses.field(default=source.default, metadata=metadata)


def _origin(cls: type, field: dataclasses.Field) -> str:
    """Where the option ``field`` of ``cls`` was first declared, ``Class.field`` (:attr:`Declared.origin`)."""
    if "origin" in field.metadata:
        return field.metadata["origin"]
    owner = next(c for c in cls.__mro__ if field.name in vars(c).get("__annotations__", {}))
    return f"{owner.__qualname__}.{field.name}"


def default_of(owner: type, name: str) -> Any:
    """The default of ``owner``'s field ``name``, for a library class whose default must be the option's."""
    source = next(f for f in fields(owner) if f.name == name)
    return source.default_factory() if source.default_factory is not MISSING else source.default


@dataclass(frozen=True)
class Declared:
    """One option as the command line and a sweep see it."""

    name: str
    type: Any
    """The resolved type (``int | None``, an enum, ``Path``, ``list[float]``...)."""
    default: Any
    help: str = ""
    min: float | None = None
    max: float | None = None
    flags: tuple[str, ...] = ()
    path: str | None = None
    text: str | None = None
    parse: Callable[[str], Any] | None = None
    argument: bool = False
    affects: bool = True
    renamed: tuple[str, ...] = ()
    former: tuple[str, ...] = ()
    placeholder: str | None = None
    origin: str = ""
    """The declaration the option was first made in, ``Class.field``: options of one origin are one concept, with
    one name on every command (:func:`same_as` keeps it)."""

    @property
    def flag(self) -> str:
        long = [flag for flag in self.flags if flag.startswith("--")]
        return long[0] if long else "--" + self.name.replace("_", "-")

    @property
    def base(self) -> Any:
        """The type without ``None``: ``int | None`` -> ``int``."""
        args = [a for a in typing.get_args(self.type) if a is not type(None)]
        if isinstance(self.type, types.UnionType) or typing.get_origin(self.type) is typing.Union:
            return args[0] if len(args) == 1 else self.type
        return self.type


def declared(cls: type) -> list[Declared]:
    """The options of the declaration ``cls``, in their order."""
    hints = typing.get_type_hints(cls)
    return [
        Declared(
            f.name,
            hints[f.name],
            f.default_factory() if f.default_factory is not MISSING else f.default,
            **{**f.metadata, "origin": _origin(cls, f)},
        )
        for f in fields(cls)
    ]


def plain(value: Any) -> Any:
    """``value`` as JSON writes it: paths and enums as their text, tuples as lists, numpy scalars as Python's."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, enum.Enum):
        return value.value
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, list | tuple):
        return [plain(v) for v in value]
    if isinstance(value, dict):
        return {k: plain(v) for k, v in value.items()}
    return value


def to_json(options: Any) -> dict:
    """Every option of ``options`` by name, as JSON writes it (a sweep job's config, a stage's provenance)."""
    return {f.name: plain(getattr(options, f.name)) for f in fields(options)}


def affecting(options: Any) -> dict:
    """:func:`to_json` of the options that change what a command makes (all but those declared ``affects=False``)."""
    kept = {option.name for option in declared(type(options)) if option.affects}
    return {name: value for name, value in to_json(options).items() if name in kept}


def current_names(cls: type, values: dict) -> dict:
    """``values``, a record of ``cls``'s options, with each setting written under a former name of its option
    (``max_attempts``, now ``max_episodes``) under the option's name."""
    options = declared(cls)
    now = {option.name for option in options}
    # a former name that another option now has (``epochs``: the segmenter's once, the FAVAE's now) is that option's
    renamed = {old: option.name for option in options for old in option.former if old not in now}
    return {renamed.get(name, name): value for name, value in values.items()}


def from_json(cls: type, values: dict) -> Any:
    """The declaration ``cls`` back from :func:`to_json`'s dict (or one written before an option was renamed):
    paths, enums and tuples typed again."""
    known = {option.name: option for option in declared(cls)}
    values = current_names(cls, values)
    unknown = sorted(set(values) - set(known))
    if unknown:
        raise UsageError(f"{cls.__name__} has no options {', '.join(unknown)}")
    return cls(**{name: _typed(known[name].base, value) for name, value in values.items()})


def _typed(kind: Any, value: Any) -> Any:
    if value is None:
        return None
    if isinstance(kind, type) and issubclass(kind, enum.Enum | Path):
        return kind(value)
    if (collection := typing.get_origin(kind)) in (list, tuple):
        item = typing.get_args(kind)[0]  # one type for every item: the declarations' lists and tuples are uniform
        return collection(_typed(item, v) for v in value)
    return value


def pick(cls: type, source: Any, **values: Any) -> Any:
    """The declaration ``cls`` with every option ``source`` also has taken from it, and ``values`` for the rest: a
    stage's options narrowed to a part's (a FAVAE's options out of ``famarl macros``'s, a run's settings out of
    ``famarl train``'s)."""
    shared = {f.name: getattr(source, f.name) for f in fields(cls) if f.name not in values and hasattr(source, f.name)}
    return cls(**shared, **values)


def with_paths(options: Any) -> None:
    """In a frozen declaration's ``__post_init__``: turn the paths given as text (by a library caller) into Paths."""
    for option in declared(type(options)):
        value = getattr(options, option.name)
        if option.base is Path and isinstance(value, str):
            object.__setattr__(options, option.name, Path(value))
