"""Every option of every command by its name: the names table of docs/commands.md, and what the rule "one name, one
meaning; one meaning, one name" is checked on.

An option's *concept* is the declaration it was first made in (:attr:`famarl_cli.core.declare.Declared.origin`):
commands that take the same thing share that declaration (:func:`~famarl_cli.core.declare.same_as`), so they give
it one name. A few names are words every command uses for its own thing (:data:`OWN`), each with one meaning.
"""

from __future__ import annotations

from dataclasses import dataclass

from typer.core import TyperOption

from famarl_cli.cli.derived import click_command
from famarl_cli.core.declare import declared

OWN = {
    "--out": "where the command writes",
    "--seed": "the seed of everything random the command does",
    "--episodes": "how many episodes the command records, reads or plays",
    "--jobs": "how many runs the command works on at once",
    "--plot": "also draw the command's picture beside its output",
    "--env": "the gymnasium id of the env the command acts in",
    "--overwrite": "make the output afresh where it exists",
    "--hidden": "the width of the hidden layers of the networks the command trains",
    "--lr": "the Adam learning rate of the networks the command trains",
    "--root": "the project's root, where its dvc.yaml is",
    "--summary": "a summary.json of verdicts and intervals (famarl report's): the one the command writes or reads",
}
"""Names that every command may use for its own thing, with the one meaning they have everywhere."""


@dataclass(frozen=True)
class Named:
    command: str
    flag: str
    concept: str
    """``Class.field`` of its declaration, or ``command.parameter`` for an option typer declares itself."""
    help: str
    hidden: bool


def options() -> list[Named]:
    """Every option of every ``famarl`` command, its old spellings (hidden) included."""
    from famarl_cli.cli import app

    found: list[Named] = []

    def walk(command, path: str) -> None:
        if hasattr(command, "commands"):
            for name, sub in sorted(command.commands.items()):
                walk(sub, f"{path} {name}".strip())
            return
        declaration = getattr(command.callback, "declaration", None)
        origins = {o.name: o.origin for o in declared(declaration)} if declaration else {}
        for param in command.params:
            if not isinstance(param, TyperOption):
                continue
            name = param.name.removeprefix("renamed__")
            concept = origins.get(name, f"{path}.{name}")
            for flag in (f for f in param.opts if f.startswith("--")):
                found.append(Named(path, flag, concept, param.help or "", param.hidden))

    walk(click_command(app), "")
    return found


def clashes(named: list[Named]) -> list[str]:
    """Where the rule breaks, in words: a name with two concepts (but the words of :data:`OWN`), or a concept under
    two names (old spellings aside: they may be another command's name now, as ``--epochs`` is the FAVAE's)."""
    problems = []
    by_flag: dict[str, dict[str, list[str]]] = {}
    by_concept: dict[str, dict[str, list[str]]] = {}
    for n in named:
        if n.hidden:  # an old spelling, kept for one release, may be another command's name now
            continue
        by_flag.setdefault(n.flag, {}).setdefault(n.concept, []).append(n.command)
        by_concept.setdefault(n.concept, {}).setdefault(n.flag, []).append(n.command)
    for flag, concepts in sorted(by_flag.items()):
        if len(concepts) > 1 and flag not in OWN:
            problems.append(
                f"{flag} means {len(concepts)} things: "
                + "; ".join(f"{concept} in {', '.join(commands)}" for concept, commands in sorted(concepts.items()))
            )
    for concept, flags in sorted(by_concept.items()):
        if len(flags) > 1:
            problems.append(
                f"{concept} has {len(flags)} names: "
                + "; ".join(f"{flag} in {', '.join(commands)}" for flag, commands in sorted(flags.items()))
            )
    return problems


def names_table(named: list[Named] | None = None) -> str:
    """The names table: each option name, what it means (its first sentence of help, or :data:`OWN`'s words), the
    commands that take it, and its old spellings."""
    named = options() if named is None else named
    shown = [n for n in named if not n.hidden]
    old: dict[str, set[str]] = {}
    for n in named:
        if n.hidden:
            current = next((s.flag for s in shown if s.concept == n.concept and s.command == n.command), None)
            if current:
                old.setdefault(current, set()).add(f"{n.flag} (`{n.command}`)")
    rows = ["| option | means | commands | old spelling |", "|---|---|---|---|"]
    for flag in sorted({n.flag for n in shown}):
        using = [n for n in shown if n.flag == flag]
        meaning = OWN.get(flag) or _first_sentence(using[0].help)
        commands = ", ".join(sorted({f"`{n.command}`" for n in using}))
        rows.append(f"| `{flag}` | {meaning} | {commands} | {', '.join(sorted(old.get(flag, ())))} |")
    return "\n".join(rows) + "\n"


def _first_sentence(text: str) -> str:
    text = text.split("  [default")[0].strip().replace("|", "\\|")
    end = text.find(". ")
    return (text if end < 0 else text[: end + 1]).rstrip()
