"""docs/api.md's examples run, in order, in one namespace, as a reader would paste them: the page cannot fall
behind the code. An example that needs an extra says so on its first line, and the page is skipped, naming the
extra, only where one it needs is not installed."""

from __future__ import annotations

import importlib.metadata
import re
from pathlib import Path

import pytest

PAGE = Path(__file__).parents[1] / "docs" / "api.md"
NEEDS = re.compile(r'^# needs: pip install "famarl\[([\w,-]+)\]"$')


def examples() -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", PAGE.read_text(), flags=re.S | re.M)


def extras_of(example: str) -> set[str]:
    """The extras an example's first line says it needs."""
    found = NEEDS.match(example.splitlines()[0])
    return set(found.group(1).split(",")) if found else set()


def requirements() -> dict[str, list[str]]:
    """famarl's extras, each with the names of the distributions it installs."""
    extras: dict[str, list[str]] = {}
    for line in importlib.metadata.requires("famarl") or []:
        name, _, marker = line.partition(";")
        for extra in re.findall(r'extra == "([\w-]+)"', marker):
            extras.setdefault(extra, []).append(re.match(r"[\w.-]+", name).group())
    return extras


def missing(extra: str) -> bool:
    for name in requirements()[extra]:
        try:
            importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            return True
    return False


def test_the_page_has_an_example_for_every_step():
    code = "\n".join(examples())
    for call in ("record_demos(", "record_expert_demos(", "export_minari(", "learn_macros(", "decode_macro_actions(",
                 "MacroActionWrapper(", "Run.start(", "evaluate(", ".act(", ".predict(", "mean_interval("):  # fmt: skip
        assert call in code


def test_every_example_that_needs_an_extra_names_it_on_its_first_line():
    known = requirements()
    uses = {"stable_baselines3": "bench", "PointMaze": "mujoco", "minari": "minari", "ray": "ray"}
    for number, example in enumerate(examples(), start=1):
        named = extras_of(example)
        assert named <= set(known), f"example {number} names extras famarl does not have: {named - set(known)}"
        for word, extra in uses.items():
            if re.search(rf"\b{word}", example):
                assert extra in named, f"example {number} uses {word} but does not say it needs the {extra} extra"


@pytest.mark.slow
def test_every_example_on_the_api_page_runs(tmp_path, monkeypatch, capsys):
    absent = sorted(extra for example in examples() for extra in extras_of(example) if missing(extra))
    if absent:
        pytest.skip(f"docs/api.md's examples need the extras {', '.join(absent)}")
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    for number, example in enumerate(examples(), start=1):
        try:
            exec(compile(example, f"docs/api.md example {number}", "exec"), namespace)  # noqa: S102
        except Exception as exc:  # the example that failed, not only the line
            pytest.fail(f"docs/api.md example {number} failed: {exc!r}\n{example}")
    printed = capsys.readouterr().out
    assert "one decision:" in printed and "MIG" in printed and "rollout:" in printed and "predict:" in printed
    assert (tmp_path / "runs/famarl-seed0/train.csv").is_file() and (tmp_path / "macros/favae.pt").is_file()
    assert (tmp_path / "minari/famarl/umaze-expert-v0/data/metadata.json").is_file()
