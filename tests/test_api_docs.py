"""docs/api.md's examples run, in order, in one namespace, as a reader would paste them: the page cannot fall
behind the code."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

PAGE = Path(__file__).parents[1] / "docs" / "api.md"


def examples() -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", PAGE.read_text(), flags=re.S | re.M)


def test_the_page_has_an_example_for_every_step():
    code = "\n".join(examples())
    for call in ("record_demos(", "record_expert_demos(", "export_minari(", "learn_macros(", "decode_macro_actions(",
                 "MacroActionWrapper(", "Run.start(", "evaluate(", ".act(", "mean_interval("):  # fmt: skip
        assert call in code


@pytest.mark.slow
def test_every_example_on_the_api_page_runs(tmp_path, monkeypatch, capsys):
    pytest.importorskip("stable_baselines3")
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    for number, example in enumerate(examples(), start=1):
        try:
            exec(compile(example, f"docs/api.md example {number}", "exec"), namespace)  # noqa: S102
        except Exception as exc:  # the example that failed, not only the line
            pytest.fail(f"docs/api.md example {number} failed: {exc!r}\n{example}")
    printed = capsys.readouterr().out
    assert "one decision:" in printed and "MIG" in printed and "rollout:" in printed
    assert (tmp_path / "runs/famarl-seed0/train.csv").is_file() and (tmp_path / "macros/favae.pt").is_file()
    assert (tmp_path / "minari/famarl/umaze-expert-v0/data/metadata.json").is_file()
