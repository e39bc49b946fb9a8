"""Names a user reads stay apart and whole: a default output is named after its input, so two replicates' files
(every replicate's FAVAE is ``favae.pt``) never share one; at 80 columns, tables keep run names whole and the paths
a command wrote are never cut."""

from __future__ import annotations

import shutil
from pathlib import Path

from cli_helpers import famarl

from famarl_cli.rl import Agent
from famarl_cli.stages.defaults import named_after
from famarl_cli.stages.method import CalibrateOptions, FitOptions, SegmentOptions, TraverseOptions
from famarl_cli.stages.train import TrainOptions


def test_a_replicates_file_is_named_by_its_folders_any_other_by_its_stem(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert named_after(Path("data/favae/pushed-down-only.pt")) == "pushed-down-only"
    assert named_after(Path("data/maze/macros/seed1/favae.pt")) == "maze-macros-seed1"
    assert named_after(tmp_path / "data/beta/macros/beta50-seed1/segments.h5") == "beta-macros-beta50-seed1"
    assert named_after(Path("mine/down-only/demos.h5")) == "mine-down-only"
    elsewhere = Path("/somewhere/else/seed2/favae.pt")
    assert named_after(elsewhere) == "somewhere-else-seed2"


def test_the_replicate_file_names_are_the_ones_their_commands_write():
    from famarl_cli.artifacts.segments import REPLICATE_FILE
    from famarl_cli.stages import defaults
    from famarl_cli.stages.demos import DEMOS_FILE
    from famarl_cli.stages.macros import FAVAE

    assert (defaults.REPLICATE_DEMOS, defaults.REPLICATE_FAVAE) == (DEMOS_FILE, FAVAE)
    assert named_after(Path(f"data/x/seed3/{REPLICATE_FILE}")) == "x-seed3"


def test_replicates_default_outputs_never_collide():
    """Every command whose default output is named after a per-replicate input, given two replicates' inputs."""
    replicates = [Path(f"data/maze/macros/seed{s}") for s in (0, 1)]

    def destinations(make) -> set[Path]:
        return {make(folder).destination for folder in replicates}

    made = {
        "segment": destinations(lambda f: SegmentOptions(demos=f / "demos.h5")),
        "favae calibrate": destinations(lambda f: CalibrateOptions(segments=f / "segments.h5")),
        "favae fit": destinations(lambda f: FitOptions(segments=f / "segments.h5")),
        "traverse": destinations(lambda f: TraverseOptions(favae=f / "favae.pt")),
        "train": destinations(lambda f: TrainOptions(agent=Agent.FAMARL, favae=f / "favae.pt")),
    }
    assert {command: len(paths) for command, paths in made.items()} == dict.fromkeys(made, 2)
    assert TraverseOptions(favae=replicates[1] / "favae.pt").destination == Path("data/traverse/maze-macros-seed1.h5")


def test_traversing_a_second_replicate_is_not_refused_by_the_firsts_output(favae_file, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for seed in (0, 1):
        replicate = tmp_path / f"data/maze/macros/seed{seed}/favae.pt"
        replicate.parent.mkdir(parents=True)
        shutil.copy(favae_file, replicate)
        result = famarl("traverse", "--favae", replicate.relative_to(tmp_path), "--ladder", 3, "--index", 1)
        assert result.exit_code == 0, result.output
    assert sorted(p.name for p in (tmp_path / "data/traverse").glob("*.h5")) == [
        "maze-macros-seed0-ladder3-index1.h5",
        "maze-macros-seed1-ladder3-index1.h5",
    ]


def test_at_80_columns_run_names_and_written_paths_are_whole(tmp_path, monkeypatch):
    monkeypatch.setenv("COLUMNS", "80")
    out = tmp_path / "a-folder-with-a-long-name-that-a-table-would-cut" / "and-deeper-still" / "sweep"
    result = famarl("sweep", "demos", "--seeds", "0-9", "--name", "famarl-seed{seed}", "--jobs", 1, "--out", out,
                    "--", "--episodes", 1, "--no-plot")  # fmt: skip
    assert result.exit_code == 0, result.output
    assert len(str(out)) > 80 and str(out) in result.stdout
    assert all(f"famarl-seed{s} " in result.stdout for s in range(10)), result.stdout
    assert "…" not in result.stdout


def test_at_80_columns_the_paths_a_command_wrote_are_whole(favae_file, tmp_path, monkeypatch):
    monkeypatch.setenv("COLUMNS", "80")
    out = tmp_path / "a-folder-with-a-long-name-that-a-table-would-cut" / "and-deeper-still" / "traversal.h5"
    result = famarl("traverse", "--favae", favae_file, "--ladder", 3, "--index", 1, "--out", out)
    assert result.exit_code == 0, result.output
    assert len(str(out)) > 80 and f"written {out}, {out.with_suffix('.png')}" in result.stdout
