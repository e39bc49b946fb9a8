"""One name per concept on every command (famarl_cli.cli.names), old spellings as hidden aliases, and every long
command's help saying how long it takes."""

from __future__ import annotations

import re

import pytest
from cli_helpers import famarl, one_line_error

from famarl_cli.cli.names import OWN, Named, clashes, names_table, options


def test_no_name_has_two_meanings_and_no_meaning_two_names():
    assert clashes(options()) == []


def test_the_rule_finds_both_kinds_of_clash():
    named = [
        Named("a", "--epochs", "Segmenter.epochs", "", False),
        Named("b", "--epochs", "Favae.epochs", "", False),
        Named("c", "--model", "Favae.path", "", False),
        Named("d", "--favae", "Favae.path", "", False),
        Named("e", "--seed", "E.seed", "", False),
        Named("f", "--seed", "F.seed", "", False),
        Named("g", "--beta", "Calibration.beta", "", True),  # an old spelling: another command's name now
        Named("h", "--beta", "Fit.beta", "", False),
    ]
    found = clashes(named)
    assert len(found) == 2 and found[0].startswith("--epochs means 2 things") and "has 2 names" in found[1]
    assert "--seed" in OWN


def test_the_names_table_gives_each_name_once_with_its_old_spelling():
    table = names_table()
    rows = [line.split(" | ")[0].strip("| `") for line in table.splitlines()[2:]]
    assert len(rows) == len(set(rows))
    assert re.search(r"^\| `--favae` \| .* \| --model \(`traverse`\) \|$", table, re.M)
    assert re.search(r"^\| `--segment-epochs` \| .*`segment`.* \| --epochs \(`segment`\) \|$", table, re.M)


@pytest.mark.parametrize(
    ("command", "old", "new"),
    [
        (["traverse"], "--model", "--favae"),
        (["favae", "calibrate"], "--beta", "--calibration-beta"),
        (["train"], "--epochs", "--update-epochs"),
        (["demos"], "--max-attempts", "--max-episodes"),
    ],
)
def test_an_old_spelling_works_with_a_note_and_not_beside_the_new_one(command, old, new, tmp_path):
    value = tmp_path / "missing.pt" if old == "--model" else 3
    result = famarl(*command, old, value, "--help")
    assert result.exit_code == 0 and old not in result.stdout, "old spellings stay out of --help"
    both = famarl(*command, old, value, new, value)
    one_line_error(both, 2, f"{old} is the old spelling of {new}")


def test_an_old_spelling_runs_as_the_new_one(tmp_path):
    out = tmp_path / "d.h5"
    result = famarl("demos", "--episodes", 2, "--out", out, "--no-plot", "--env-kwargs", "{}")
    assert result.exit_code == 0
    from cli_helpers import runner

    from famarl_cli.cli import app

    old = runner.invoke(app, ["segment", "--demos", str(out), "--epochs", "2", "--out", str(tmp_path / "s.h5")])
    assert old.exit_code == 0, old.output
    assert "note: --epochs is now --segment-epochs" in old.stderr


QUICK = {"sequences", "export-minari", "inspect", "status", "docs", "power"}
"""Commands that take a second or two whatever they are given: their help need not say how long."""
RECORDS = ("docs/performance.md", "docs/pipelines.md's wall table")
"""Where a command's time is recorded: benchmarks/command_times.py's row ("each command with its defaults"), or the
pipelines' stages."""


def test_every_long_command_says_where_its_time_is_recorded():
    commands = sorted({n.command for n in options()} - QUICK)
    helps = {c: " ".join(famarl(*c.split(), "--help").stdout.split()) for c in commands}
    assert [c for c, text in helps.items() if not any(record in text for record in RECORDS)] == []


def test_every_placeholder_is_one_word_a_path_file_or_dir():
    from famarl_cli.cli.names import options as every

    odd = set()
    for command in sorted({n.command for n in every()}):
        for line in famarl(*command.split(), "--help").stdout.splitlines():
            found = re.match(r"^\s+(?:-\w, )?--[a-z-]+ <([^>]+)>", line)
            if found and (found[1].startswith(("list[", "path")) or "[" in found[1]):
                odd.add(f"{command}: {line.strip()}")
    assert odd == set()
