"""One rule for an output that is there already, the same in every command (famarl_cli.artifacts.made): the same
command again does nothing, another option (named as the command line names it) or another input's content is
refused with what changed (but a result computed from a run that changed since is made again), --overwrite makes it
afresh."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
import torch
from cli_helpers import famarl, one_line_error

from famarl_cli.artifacts.made import claim_output, making, recorded_making, what_changed
from famarl_cli.core.errors import UsageError
from famarl_cli.stages.demos import DemosOptions
from famarl_cli.stages.method import SegmentOptions

TINY_PPO = ("--steps", 600, "--n-envs", 2, "--n-steps", 8, "--update-epochs", 1, "--minibatches", 2)


def edit(path: Path) -> None:
    """Change a file's content and keep it valid: an HDF5 attribute, a torch file's extra key, a run's checkpoint."""
    if path.is_dir():
        path = path / "checkpoint.pt"
    if path.suffix == ".h5":
        with h5py.File(path, "a") as handle:
            handle.attrs["edited"] = 1
    else:
        torch.save({**torch.load(path, weights_only=True), "edited": 1}, path)


@pytest.fixture
def inputs(tmp_path, demos_file, segments_file, favae_file):
    """Copies of the session's files, to edit; and a tiny trained run."""
    folder = tmp_path / "in"
    folder.mkdir()
    copies = {name: Path(shutil.copy(src, folder / src.name)) for name, src in
              (("demos", demos_file), ("segments", segments_file), ("favae", favae_file))}  # fmt: skip
    return copies


def _run(inputs, tmp_path) -> Path:
    run = tmp_path / "in" / "run"
    assert famarl("train", "--favae", inputs["favae"], *TINY_PPO, "--out", run).exit_code == 0
    return run


# command: (its arguments from inputs and out, the output that records its making, another value of an option,
#           the input whose content is changed)
CASES = {
    "demos": (lambda i, o: ["demos", "--episodes", 3, "--out", o / "d.h5", "--no-plot"], "d.h5",
              ("--episodes", 4), None),
    "segment": (lambda i, o: ["segment", "--demos", i["demos"], "--out", o / "s.h5", "--segment-epochs", 2,
                              "--length", 48, "--no-plot"], "s.h5", ("--margin", 0.5), "demos"),
    "favae calibrate": (lambda i, o: ["favae", "calibrate", "--segments", i["segments"], "--epochs", 2,
                                      "--out", o / "c.json"], "c.json", ("--calibration-beta", 0.2), "segments"),
    "favae fit": (lambda i, o: ["favae", "fit", "--segments", i["segments"], "--epochs", 2, "--out", o / "f.pt"],
                  "f.pt", ("--beta", 5), "segments"),
    "traverse": (lambda i, o: ["traverse", "--favae", i["favae"], "--out", o / "t.h5"], "t.h5", ("--ladder", 1),
                 "favae"),
    "prior fit": (lambda i, o: ["prior", "fit", "--demos", i["demos"], "--segments", i["segments"], "--favae",
                                i["favae"], "--prior-steps", 3, "--out", o / "p.pt", "--no-plot"], "p.pt",
                  ("--holdout", 0.5), "favae"),
    "train": (lambda i, o: ["train", "--favae", i["favae"], *TINY_PPO, "--out", o / "r"], "r/run.json",
              ("--seed", 1), "favae"),
    "evaluate": (lambda i, o: ["evaluate", "--run", i["run"], "--episodes", 2, "--no-film", "--jobs", 1, "--out",
                               o], "run/eval.json", ("--episodes", 3), "run"),
    "oracle": (lambda i, o: ["oracle", "--run", i["run"], "--layouts", 1, "--candidates", 2, "--iterations", 1,
                             "--decisions", 4, "--jobs", 1, "--out", o], "run/oracle.json", ("--candidates", 3),
               "run"),
}  # fmt: skip
SLOW = {"favae calibrate", "favae fit", "prior fit", "train", "evaluate", "oracle"}
DERIVED = {"evaluate", "oracle"}
"""Results computed from a run: made again where the run changed since (famarl_cli.artifacts.made)."""


@pytest.mark.parametrize(
    "command", [pytest.param(c, marks=pytest.mark.slow) if c in SLOW else c for c in CASES]
)  # fmt: skip
def test_the_same_command_again_does_nothing_and_other_inputs_or_options_are_refused(command, inputs, tmp_path):
    arguments, recorded, (flag, value), changed_input = CASES[command]
    if command in ("evaluate", "oracle"):
        inputs["run"] = _run(inputs, tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    args = arguments(inputs, out)
    assert famarl(*args).exit_code == 0
    record = recorded_making(out / recorded)
    assert record is not None and record["command"] == f"famarl {command}"
    written = {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()}

    again = famarl(*args)
    assert again.exit_code == 0 and ("nothing to do" in again.output or "not made again" in again.output)
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()} == written, "nothing may be rewritten"
    assert not re.search(r"^written ", again.stdout, re.M), "nor said to be"

    one_line_error(famarl(*args, flag, value), 2, f"{flag} ")
    if changed_input is not None and command in DERIVED:  # a result of a run trained further is out of date
        edit(inputs[changed_input])
        assert famarl(*args).exit_code == 0
        assert recorded_making(out / recorded)["inputs"] != record["inputs"]
    elif changed_input is not None:
        edit(inputs[changed_input])
        one_line_error(famarl(*args), 2, "the content of")
    fresh = famarl(*args, flag, value, "--overwrite")
    assert fresh.exit_code == 0, fresh.output
    assert recorded_making(out / recorded) != record


def test_a_file_that_records_no_making_is_refused_unless_overwrite(tmp_path):
    out = tmp_path / "d.h5"
    out.write_bytes(b"made by hand")
    one_line_error(famarl("demos", "--episodes", 2, "--out", out, "--no-plot"), 2, "does not record what it was made")
    assert out.read_bytes() == b"made by hand"
    assert famarl("demos", "--episodes", 2, "--out", out, "--no-plot", "--overwrite").exit_code == 0


@pytest.mark.parametrize("cut", [0, 40])
def test_a_truncated_output_is_refused_as_unreadable_not_as_made_by_hand(tmp_path, cut):
    out = tmp_path / "d.h5"
    assert famarl("demos", "--episodes", 2, "--out", out, "--no-plot").exit_code == 0
    out.write_bytes(out.read_bytes()[:cut])
    result = famarl("demos", "--episodes", 2, "--out", out, "--no-plot")
    one_line_error(result, 2, "cannot be read (truncated or corrupt?")
    assert "made by hand" not in result.output and out.stat().st_size == cut
    assert famarl("demos", "--episodes", 2, "--out", out, "--no-plot", "--overwrite").exit_code == 0


def test_a_missing_part_of_the_output_makes_it_again(tmp_path):
    out = tmp_path / "d.h5"
    assert famarl("demos", "--episodes", 2, "--out", out).exit_code == 0
    out.with_suffix(".png").unlink()
    again = famarl("demos", "--episodes", 2, "--out", out)
    assert again.exit_code == 0 and "nothing to do" not in again.output and out.with_suffix(".png").exists()


def test_where_and_how_a_command_shows_its_output_is_not_part_of_its_making(tmp_path, demos_file):
    a = making("famarl demos", DemosOptions(episodes=3, out=tmp_path / "a.h5", plot=True))
    b = making("famarl demos", DemosOptions(episodes=3, out=tmp_path / "b.h5", plot=False, overwrite=True))
    assert a == b and "out" not in a["options"] and "plot" not in a["options"]
    assert what_changed(a, making("famarl demos", DemosOptions(episodes=4))) == ["episodes 3 -> 4"]
    # a file counts by its content, not by the name it is given under
    copy = tmp_path / "elsewhere" / "copy.h5"
    copy.parent.mkdir()
    shutil.copy(demos_file, copy)
    named = [making("famarl segment", SegmentOptions(demos=path)) for path in (demos_file, copy)]
    assert "demos" not in named[0]["options"] and what_changed(*named) == []


def test_the_rule_names_nested_settings_inputs_and_the_version(tmp_path):
    source = tmp_path / "x.bin"
    source.write_bytes(b"a")
    before = making("famarl train", {"ppo": {"epochs": 1, "lr": 0.1}}, [source])
    source.write_bytes(b"b")
    after = {**making("famarl train", {"ppo": {"epochs": 2, "lr": 0.1}}, [source]), "famarl_version": "9"}
    assert what_changed(before, after) == ["ppo.epochs 1 -> 2", f"the content of {source}", "famarl 0.1.0 -> 9"]
    assert what_changed(before, before) == []
    assert what_changed(after, {**after, "inputs": {}}) == [f"{source}, read before and not now"]
    assert what_changed(after, {**after, "inputs": {"other.bin": "0" * 64}}) == [
        "the content of other.bin",
        f"{source}, read before and not now",
    ]
    missing = tmp_path / "nothing.h5"
    assert claim_output([missing], before, overwrite=False) is True
    (tmp_path / "plain.h5").write_bytes(np.zeros(4).tobytes())
    with pytest.raises(UsageError, match="does not record"):
        claim_output([tmp_path / "plain.h5"], before, overwrite=False)


def test_no_default_output_lies_in_a_dvc_stages_output_of_this_project(monkeypatch):
    """A command typed with its defaults after the main job (`famarl report` to read every experiment at once)
    writes beside the pipelines' outputs, which only `dvc repro` writes, and so is never refused by default."""
    from typer.core import TyperOption

    from famarl_cli.artifacts.tracked import tracked_output
    from famarl_cli.cli import app
    from famarl_cli.cli.derived import click_command

    root = Path(__file__).parents[1]
    monkeypatch.chdir(root)
    monkeypatch.delenv("DVC_STAGE", raising=False)
    assert tracked_output("data/report/report.md") is not None, "the main job's report stage is a DVC output"
    defaults = {}

    def walk(command, path: str) -> None:
        for name, sub in sorted(getattr(command, "commands", {}).items()):
            walk(sub, f"{path} {name}".strip())
        for param in getattr(command, "params", []):
            if isinstance(param, TyperOption) and param.name in ("out", "summary") and param.default:
                defaults[f"famarl {path} --{param.name}"] = param.default

    walk(click_command(app), "")
    written = {typed: Path(out) for typed, out in defaults.items()}
    written["famarl report --out"] /= "report.md"  # a folder beside the pipelines' own: its files are not theirs
    inside = {typed: str(out) for typed, out in written.items() if tracked_output(out) is not None}
    assert inside == {}
