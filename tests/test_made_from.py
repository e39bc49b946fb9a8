"""A folder says what it was made from: ``famarl macros`` continues or skips only work made from the same inputs and
options, and refuses, naming what changed, anything else (unless --overwrite)."""

import json
import shutil

import pytest
from cli_helpers import famarl

from famarl_cli.artifacts.made import option_names
from famarl_cli.core.errors import UsageError
from famarl_cli.stages.macros import MacrosConfig
from famarl_cli.sweep.plan import JOB_FILE, Action, Job, folder_action, job_record

TINY = ["--segment-epochs", 2, "--epochs", 2, "--length", 48]


def _job(tmp_path, **config) -> Job:
    source = tmp_path / "in.txt"
    if not source.exists():
        source.write_text("one")
    return Job("macros", "m:f", {"epochs": 2, **config}, (str(source),), resumable=True)


def test_a_folder_is_run_resumed_skipped_or_refused_by_its_record(tmp_path):
    folder = tmp_path / "out"
    job = _job(tmp_path)
    assert folder_action(folder, job, overwrite=False) == Action.RUN
    folder.mkdir()
    (folder / ".famarl.lock").touch()
    assert folder_action(folder, job, overwrite=False) == Action.RUN
    (folder / JOB_FILE).write_text(json.dumps(job_record(job, complete=False)))
    assert folder_action(folder, job, overwrite=False) == Action.RESUME
    (folder / JOB_FILE).write_text(json.dumps(job_record(job, complete=True)))
    assert folder_action(folder, job, overwrite=False) == Action.SKIP
    assert folder_action(folder, job, overwrite=True) == Action.RUN
    with pytest.raises(UsageError, match=r"made from other inputs or options: epochs 2 -> 3; add --overwrite"):
        folder_action(folder, _job(tmp_path, epochs=3), overwrite=False)
    with pytest.raises(UsageError, match=r"other inputs or options: --epochs 2 -> 3; add"):
        folder_action(folder, _job(tmp_path, epochs=3), overwrite=False, names=option_names(MacrosConfig))
    (tmp_path / "in.txt").write_text("two")
    with pytest.raises(UsageError, match=r"other inputs or options: the content of .*in\.txt; add --overwrite"):
        folder_action(folder, job, overwrite=False)
    assert folder_action(folder, job, overwrite=True) == Action.RUN


def test_files_no_job_recorded_are_refused_unless_overwrite(tmp_path):
    folder = tmp_path / "out"
    folder.mkdir()
    (folder / "favae.pt").write_text("someone's")
    with pytest.raises(UsageError, match=r"holds files no famarl job recorded \(favae\.pt, \.\.\.\).*--overwrite"):
        folder_action(folder, _job(tmp_path), overwrite=False)
    assert folder_action(folder, _job(tmp_path), overwrite=True) == Action.RUN


@pytest.mark.slow
def test_famarl_macros_skips_its_own_work_and_refuses_work_from_other_inputs(demos_file, tmp_path):
    demos = tmp_path / "demos.h5"
    shutil.copy(demos_file, demos)
    out = tmp_path / "macros"
    assert famarl("macros", "--demos", demos, "--out", out, *TINY).exit_code == 0
    record = json.loads((out / JOB_FILE).read_text())
    assert record["complete"] and record["inputs"] == {str(demos): record["inputs"][str(demos)]}
    made = {path.name: path.stat().st_mtime_ns for path in out.iterdir()}

    again = famarl("macros", "--demos", demos, "--out", out, *TINY)
    assert again.exit_code == 0 and "already holds these macros, complete; nothing to do" in again.output
    assert {path.name: path.stat().st_mtime_ns for path in out.iterdir()} == made

    changed = famarl("macros", "--demos", demos, "--out", out, *TINY[:2], "--epochs", 3, "--length", 48)
    assert changed.exit_code == 2
    last = changed.output.strip().splitlines()[-1]
    assert last.startswith(f"error: {out} was made from other inputs or options: --epochs 2 -> 3")
    other = tmp_path / "other.h5"
    assert famarl("demos", "--episodes", 8, "--seed", 5, "--out", other, "--no-plot").exit_code == 0
    shutil.copy(other, demos)
    refused = famarl("macros", "--demos", demos, "--out", out, *TINY)
    assert refused.exit_code == 2 and f"the content of {demos}" in refused.output and "--overwrite" in refused.output
    assert {path.name: path.stat().st_mtime_ns for path in out.iterdir()} == made

    # A folder stopped after its fit continues with the traversal alone; the fit it made stays.
    shutil.copy(demos_file, demos)
    (out / JOB_FILE).write_text(json.dumps({**record, "complete": False}))
    (out / "traverse.json").unlink()
    resumed = famarl("macros", "--demos", demos, "--out", out, *TINY)
    assert resumed.exit_code == 0, resumed.output
    assert (out / "traverse.json").is_file() and (out / "favae.pt").stat().st_mtime_ns == made["favae.pt"]
    assert json.loads((out / JOB_FILE).read_text())["complete"]

    # Replacing work that is refused, or fails, leaves the old work as it was.
    kept = {path.name: path.read_bytes() for path in out.iterdir()}
    failed = famarl("macros", "--demos", demos, "--out", out, *TINY, "--device", "cuda", "--overwrite")
    assert failed.exit_code == 1 and "CUDA" in failed.output
    assert {path.name: path.read_bytes() for path in out.iterdir()} == kept, "the old macros must stay whole"
    fresh = famarl("macros", "--demos", demos, "--out", out, *TINY[:2], "--epochs", 3, "--length", 48, "--overwrite")
    assert fresh.exit_code == 0, fresh.output
    assert json.loads((out / JOB_FILE).read_text())["config"]["epochs"] == 3
    assert (out / "favae.pt").stat().st_mtime_ns != made["favae.pt"]
