"""One word per concept: records name a setting as the command line does (``--peak-neighbours`` is
``peak_neighbours``, ``--segment-epochs`` ``segment_epochs``, ``--max-episodes`` ``max_episodes``, ``oracle
--layouts`` ``layouts``), and a record written under a former name still reads as the same setting; what
``famarl segment`` and ``famarl favae fit`` print; the macro wrapper's ``loop``."""

import json
import warnings

import gymnasium
import h5py
import pytest
from cli_helpers import famarl

from famarl_cli.artifacts.made import option_names, what_changed
from famarl_cli.core.declare import from_json, to_json
from famarl_cli.stages.demos import DemosOptions
from famarl_cli.stages.macros import MacrosConfig
from famarl_cli.stages.method import SegmentOptions

FORMER = {"peak_neighbours": "neighbours", "segment_epochs": "epochs"}
"""The segmentation's settings as records named them before they took the command line's names."""


def _rename(options: dict, names: dict) -> dict:
    return {names.get(key, key): value for key, value in options.items()}


def test_records_name_settings_as_the_command_line_does():
    segment = to_json(SegmentOptions(margin=0.3))
    assert segment["peak_neighbours"] == 10 and segment["segment_epochs"] == 300
    assert "neighbours" not in segment and "epochs" not in segment
    assert to_json(DemosOptions(env="Pendulum-v1", expert="m:f", episodes=5, max_episodes=7))["max_episodes"] == 7
    assert option_names(SegmentOptions)["peak_neighbours"] == "--peak-neighbours"


def test_a_record_written_under_former_names_reads_as_the_same_settings():
    old = _rename(to_json(SegmentOptions(margin=0.3, peak_neighbours=6)), FORMER)
    assert from_json(SegmentOptions, old) == SegmentOptions(margin=0.3, peak_neighbours=6)
    demos = {**to_json(DemosOptions(env="Pendulum-v1", expert="m:f", episodes=5, min_return=0.0)), "max_episodes": None}
    demos = _rename(demos, {"max_episodes": "max_attempts"}) | {"max_attempts": 9}
    assert from_json(DemosOptions, demos).max_episodes == 9


def test_a_former_name_that_another_option_now_has_stays_that_option():
    """famarl macros records the FAVAE's ``epochs`` beside ``segment_epochs``: never read as the segmenter's."""
    back = from_json(MacrosConfig, to_json(MacrosConfig(demos="d.h5", epochs=5, segment_epochs=7)))
    assert (back.epochs, back.segment_epochs) == (5, 7)


def test_a_making_recorded_under_former_names_is_no_change_and_a_real_change_is_named_by_its_flag():
    names = option_names(SegmentOptions)
    now = {"command": "famarl segment", "options": {"peak_neighbours": 10, "margin": 0.7}, "inputs": {}}
    old = {**now, "options": {"neighbours": 10, "margin": 0.7}, "famarl_version": "x"}
    now = {**now, "famarl_version": "x"}
    assert what_changed(old, now, names) == []
    changed = {**old, "options": {"neighbours": 4, "margin": 0.7}}
    assert what_changed(changed, now, names) == ["--peak-neighbours 4 -> 10"]


def test_segment_says_the_tolerant_f1_first_and_reads_its_former_record(demos_file, tmp_path):
    out = tmp_path / "seg.h5"
    common = ("segment", "--demos", demos_file, "--out", out, "--segment-epochs", 3, "--margin", 0.3, "--no-plot")
    result = famarl(*common)
    assert result.exit_code == 0, result.output
    assert 0 <= result.stdout.index("boundary F1 (±2)") < result.stdout.index("boundary F1 (±0)")
    provenance = json.loads(h5py.File(out, "r").attrs["provenance"])
    assert provenance["params"]["peak_neighbours"] == 10 and provenance["params"]["segment_epochs"] == 3
    # the same segments, recorded as famarl wrote them before the settings took the command line's names
    made = provenance["made_from"]
    provenance["made_from"] = {**made, "options": _rename(made["options"], FORMER)}
    with h5py.File(out, "r+") as handle:
        handle.attrs["provenance"] = json.dumps(provenance)
    again = famarl(*common)
    assert again.exit_code == 0, again.output
    assert "nothing to do" in again.stderr
    refused = famarl(*common[:-1], "--peak-neighbours", 4, "--no-plot")
    assert refused.exit_code == 2 and "--peak-neighbours 10 -> 4" in refused.stderr


def test_favae_fit_lists_the_calibration_it_wrote(segments_file, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # short paths: the table shows them whole
    result = famarl("favae", "fit", "--segments", segments_file, "--epochs", 2, "--out", "f.pt")
    assert result.exit_code == 0, result.output
    written = result.stdout.split("written", 1)[1]  # the table's last row, maybe wrapped
    assert (tmp_path / "f.calibration.json").is_file() and "f.calibration.json" in written
    reused = famarl("favae", "fit", "--segments", segments_file, "--calibration", "f.calibration.json", "--epochs", 2,
                    "--out", "g.pt")  # fmt: skip
    assert reused.exit_code == 0, reused.output
    assert "g.metrics.json" in reused.stdout and "calibration" not in reused.stdout.split("written", 1)[1]


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    run = tmp_path_factory.mktemp("oracle") / "run"
    tiny = ("--steps", 600, "--n-envs", 2, "--n-steps", 8, "--update-epochs", 1, "--minibatches", 2)
    result = famarl("train", "--env", "famarl/RobotHand-Reaching-v0", "--agent", "figar", *tiny, "--out", run)
    assert result.exit_code == 0, result.output
    return run


ORACLE = ("--candidates", 4, "--iterations", 1, "--decisions", 10, "--jobs", 1)


def test_oracle_searches_layouts_under_their_name_and_its_former_one(tiny_run, tmp_path):
    out = tmp_path / "oracle"
    result = famarl("oracle", "--run", tiny_run, "--layouts", 2, *ORACLE, "--out", out)
    assert result.exit_code == 0, result.output
    path = out / "run" / "oracle.json"
    found = json.loads(path.read_text())
    assert len(found["episodes"]) == 2 and found["provenance"]["params"]["layouts"] == 2
    assert found["provenance"]["made_from"]["options"]["layouts"] == 2
    # an oracle.json written when the setting was "episodes" holds the same search: read, not refused
    made = found["provenance"]["made_from"]
    found["provenance"]["made_from"] = {**made, "options": _rename(made["options"], {"layouts": "episodes"})}
    path.write_text(json.dumps(found))
    before = path.read_text()
    old = famarl("oracle", "--run", tiny_run, "--episodes", 2, *ORACLE, "--out", out)
    assert old.exit_code == 0, old.output
    assert "--episodes is now --layouts" in old.stderr and "already held this search" in old.stderr
    assert path.read_text() == before
    assert "--episodes" not in famarl("oracle", "--help").stdout


def test_the_macro_wrapper_takes_loop_and_its_former_name_decoder(favae_file):
    from famarl_cli.wrappers import MacroActionWrapper

    base = "famarl/ContinuousWorld-Base-v0"
    env = MacroActionWrapper(gymnasium.make(base), favae_file, loop="open")
    assert env._saved_kwargs["loop"] == "open"  # what env.spec remakes the wrapper from
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        old = MacroActionWrapper(gymnasium.make(base), favae_file, decoder="open")
    assert any("now loop=" in str(w.message) and w.category is DeprecationWarning for w in caught)
    assert old.action_space == env.action_space
    with pytest.raises(ValueError, match="loop="):
        MacroActionWrapper(gymnasium.make(base), favae_file, loop="closed", decoder="open")
    with pytest.raises(ValueError, match="loop must be 'open' or 'closed'"):
        MacroActionWrapper(gymnasium.make(base), favae_file, loop="sideways")


def test_a_run_records_its_loop_as_the_command_line_names_it_and_older_runs_still_read():
    """run.json's spec says ``loop`` (famarl train --loop), as MacroActionWrapper does; a spec recorded as
    ``decoder`` reads back the same."""
    from famarl_cli.rl import Agent, MacroDecoder
    from famarl_cli.rl.ppo import PPOConfig
    from famarl_cli.rl.spec import RunSpec
    from famarl_cli.stages.train import setting_options

    spec = RunSpec("famarl/ContinuousWorld-Maze-v0", Agent.FAMARL, 0, PPOConfig(), loop=MacroDecoder.CLOSED)
    written = spec.to_dict()
    assert written["loop"] == "closed" and "decoder" not in written
    older = {("decoder" if name == "loop" else name): value for name, value in written.items()}
    assert RunSpec.from_dict(older) == spec == RunSpec.from_dict(written)
    assert setting_options()["loop"] == setting_options()["decoder"] == "--loop"
