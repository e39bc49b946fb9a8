"""A sweep never loses a result silently: deleting a run no longer in the plan or replacing one made otherwise is
refused without --overwrite, before anything changes; a stopped run is continued and a complete one skipped without
asking; a sweep that DVC runs as a pipeline's stage may delete and replace (the pipeline is its plan)."""

from __future__ import annotations

import json
from pathlib import Path

import yaml
from cli_helpers import famarl, one_line_error

from famarl_cli.artifacts.runs import CURVES_FILES
from famarl_cli.sweep.driver import run_sweep
from famarl_cli.sweep.executors import SerialExecutor
from famarl_cli.sweep.plan import JOB_FILE, Action, Job, job_record


def _demos(out: Path, seeds: str, episodes: int, *before: str):
    """famarl sweep demos, tiny: a second each."""
    options = ["--", "--episodes", episodes, "--no-plot"]
    return famarl("sweep", "demos", "--seeds", seeds, "--jobs", 1, *before, "--out", out, *options)


def _tree(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` and its content."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _recorded_episodes(folder: Path) -> int:
    return json.loads((folder / JOB_FILE).read_text())["config"]["episodes"]


def test_deleting_or_replacing_runs_is_refused_without_overwrite_and_changes_nothing(tmp_path):
    out = tmp_path / "sweep"
    assert _demos(out, "0-1", 2).exit_code == 0
    before = _tree(out)
    refused = _demos(out, "0", 3)
    one_line_error(
        refused,
        2,
        "it would delete seed1 (no longer in the plan) and replace seed0 (made from other options or inputs)",
    )
    assert "Add --overwrite to let it" in refused.stderr
    assert _tree(out) == before
    allowed = _demos(out, "0", 3, "--overwrite")
    assert allowed.exit_code == 0, allowed.output
    assert sorted(p.name for p in out.iterdir()) == ["seed0", "sweep.json"]
    assert _recorded_episodes(out / "seed0") == 3
    words = " ".join(allowed.stdout.split())
    assert "deleted, no longer in the plan: seed1" in words and "replaced, made otherwise: seed0" in words


def test_runs_that_fail_to_replace_the_old_ones_leave_them_as_they_were(tmp_path):
    """--overwrite with an option every run fails on (an env that is not there, found when the run starts)
    replaces nothing: each old run is put back once its new one has failed; one that succeeds replaces its old
    one and keeps nothing of it."""
    out = tmp_path / "sweep"

    def sweep(*options, overwrite: bool = True):
        tiny = ("--agent", "ppo", "--steps", 64, "--n-envs", 1, "--n-steps", 64, "--checkpoint-every", 1)
        ours = ("sweep", "train", "--seeds", "0-1", "--jobs", 1, "--out", out, *(("--overwrite",) if overwrite else ()))
        return famarl(*ours, "--", *tiny, *options)

    assert sweep(overwrite=False).exit_code == 0
    before = {name: data for name, data in _tree(out).items() if name != "sweep.json"}
    failed = sweep("--env", "famarl/NoSuch-v0")
    assert failed.exit_code == 1 and "2 of 2 runs failed" in failed.stderr and "replaced" not in failed.stdout
    assert {name: data for name, data in _tree(out).items() if name in before} == before
    assert not list(out.rglob(".famarl-replaced"))
    assert not [*out.rglob(".lease"), *out.rglob(".progress")]  # what only a running attempt needs
    assert sweep("--lr", 0.001).exit_code == 0
    assert json.loads((out / "seed0" / "run.json").read_text())["spec"]["ppo"]["learning_rate"] == 0.001
    assert not list(out.rglob(".famarl-replaced"))


def test_the_curves_famarl_evaluate_draws_beside_a_sweeps_runs_do_not_stop_the_sweep(tmp_path):
    """famarl evaluate --run SWEEP draws the runs' learning curves into the sweep's folder by default: the sweep
    takes more seeds there afterwards, and leaves the curves as they are."""
    out = tmp_path / "sweep"
    assert _demos(out, "0", 2).exit_code == 0
    curves = {name: f"{name} of famarl evaluate".encode() for name in CURVES_FILES}
    for name, data in curves.items():
        (out / name).write_bytes(data)
    more = _demos(out, "0-1", 2)
    assert more.exit_code == 0, more.output
    assert {name: (out / name).read_bytes() for name in CURVES_FILES} == curves
    assert (out / "seed1" / JOB_FILE).is_file()


def test_a_run_folder_holding_files_no_sweep_recorded_is_not_replaced_unasked(tmp_path):
    out = tmp_path / "sweep"
    (out / "seed0").mkdir(parents=True)
    (out / "seed0" / "notes.txt").write_text("mine")
    one_line_error(_demos(out, "0", 2), 2, "replace seed0 (files no sweep recorded)")
    assert _tree(out) == {"seed0/notes.txt": b"mine"}


def test_adding_a_seed_asks_nothing_and_keeps_the_complete_runs(tmp_path):
    out = tmp_path / "sweep"
    assert _demos(out, "0", 2).exit_code == 0
    kept = (out / "seed0" / "demos.h5").read_bytes()
    added = _demos(out, "0-1", 2)
    assert added.exit_code == 0, added.output
    assert (out / "seed0" / "demos.h5").read_bytes() == kept and _recorded_episodes(out / "seed1") == 2
    assert "skipped" in added.stdout


def test_a_stopped_run_is_continued_and_a_complete_one_skipped_without_asking(tmp_path):
    stopped = Job("stopped", "sweep_jobs:echo", {"n": 0}, resumable=True)
    restarted = Job("restarted", "sweep_jobs:echo", {"n": 1})  # cannot continue: the same job from the start
    done = Job("done", "sweep_jobs:echo", {"n": 2})
    for job, complete in ((stopped, False), (restarted, False), (done, True)):
        (tmp_path / job.name).mkdir()
        (tmp_path / job.name / JOB_FILE).write_text(json.dumps(job_record(job, complete)))
        (tmp_path / job.name / "partial.txt").write_text("work so far")
    with SerialExecutor() as executor:
        state = run_sweep(tmp_path, [stopped, restarted, done], executor)
    actions = {s.job.name: (s.action, s.status) for s in state.jobs}
    assert actions == {
        "stopped": (Action.RESUME, "done"),
        "restarted": (Action.RUN, "done"),
        "done": (Action.SKIP, "skipped"),
    }
    assert (tmp_path / "stopped" / "partial.txt").is_file() and not (tmp_path / "restarted" / "partial.txt").exists()
    assert state.deleted == [] and state.replaced == []


def test_a_sweep_run_by_dvc_as_a_stage_deletes_and_replaces_without_asking(tmp_path, monkeypatch):
    out = tmp_path / "sweep"
    assert _demos(out, "0-1", 2).exit_code == 0
    monkeypatch.setenv("DVC_STAGE", "demos")
    result = _demos(out, "0", 3)
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in out.iterdir()) == ["seed0", "sweep.json"]
    assert _recorded_episodes(out / "seed0") == 3


def test_a_sweep_into_a_dvc_stages_output_is_refused_before_it_deletes_anything(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("DVC_STAGE", raising=False)
    assert _demos(Path("runs"), "0-1", 2).exit_code == 0
    (tmp_path / ".dvc").mkdir()
    (tmp_path / "dvc.yaml").write_text(yaml.safe_dump({"stages": {"demos": {"cmd": "famarl sweep demos"}}}))
    lock = {"schema": "2.0", "stages": {"demos": {"cmd": "famarl sweep demos", "outs": [{"path": "runs"}]}}}
    (tmp_path / "dvc.lock").write_text(yaml.safe_dump(lock))
    before = _tree(tmp_path / "runs")
    one_line_error(_demos(Path("runs"), "0", 2, "--overwrite"), 2, "the output of the DVC stage demos")
    assert _tree(tmp_path / "runs") == before


def test_overwrite_among_the_commands_options_names_the_sweeps_own(tmp_path):
    result = famarl("sweep", "demos", "--out", tmp_path / "s", "--", "--episodes", 2, "--overwrite")
    one_line_error(result, 2, "--overwrite is the sweep's own option: give it before --")
    assert not (tmp_path / "s").exists()
