"""A sweep stage under DVC: runs added or removed with the seeds, nothing else re-run, and a killed stage resumed by
the next ``dvc repro``; the stage's command has no --overwrite, since a sweep that DVC runs as a stage deletes and
replaces runs as its plan says."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from cli_helpers import dvc, dvc_environment
from waiting import wait_for

pytestmark = pytest.mark.slow  # DVC repro of real pipelines

STAGE = {
    "stages": {
        "train": {
            "cmd": "famarl sweep train --seeds ${seeds} --jobs 2 --out runs -- --agent ppo --n-envs 2 --n-steps 64 "
            "--minibatches 2 --epochs 2 --steps ${steps} --checkpoint-every 2",
            "params": ["seeds", "steps"],
            "outs": [{"runs": {"persist": True}}],
        }
    }
}


def _params(root: Path, seeds: str, steps: int) -> None:
    (root / "params.yaml").write_text(yaml.safe_dump({"seeds": seeds, "steps": steps}))


def _complete(root: Path) -> dict[str, bool]:
    return {
        folder.name: json.loads((folder / "job.json").read_text())["complete"]
        for folder in sorted((root / "runs").iterdir())
        if folder.is_dir()
    }


@pytest.fixture(scope="module")
def project(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("sweep-dvc")
    (root / "dvc.yaml").write_text(yaml.safe_dump(STAGE))
    _params(root, "0-1", 1280)
    dvc(root, "init", "--no-scm")
    dvc(root, "repro")
    return root


def test_seeds_give_runs_and_an_added_seed_runs_exactly_one_more(project):
    assert _complete(project) == {"seed0": True, "seed1": True}
    before = {s: (project / f"runs/seed{s}/checkpoint.pt").stat().st_mtime_ns for s in (0, 1)}
    _params(project, "0-2", 1280)
    output = dvc(project, "repro")
    assert output.count("skipped") == 2 and "seed2 " in output
    assert _complete(project) == {"seed0": True, "seed1": True, "seed2": True}
    assert {s: (project / f"runs/seed{s}/checkpoint.pt").stat().st_mtime_ns for s in (0, 1)} == before
    assert "up to date" in dvc(project, "status")


def test_a_removed_seed_is_deleted(project):
    _params(project, "1-2", 1280)
    output = dvc(project, "repro")
    assert "deleted, no longer in the plan: seed0" in output
    assert _complete(project) == {"seed1": True, "seed2": True}
    assert "up to date" in dvc(project, "status")


def test_a_stage_killed_mid_sweep_resumes_on_the_next_repro(project):
    _params(project, "1-2", 12800)  # new keys: both runs start over
    process = subprocess.Popen(
        [sys.executable, "-m", "dvc", "repro"],
        cwd=project,
        env=dvc_environment(project),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    runs = [project / "runs" / f"seed{s}" for s in (1, 2)]
    assert wait_for(lambda: any(_checkpointed(run) for run in runs), 180)
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    assert not all(_complete(project).values())
    output = dvc(project, "repro")
    assert "(resumed)" in output
    assert _complete(project) == {"seed1": True, "seed2": True}
    assert all(json.loads((run / "run.json").read_text())["env_steps"] >= 12800 for run in runs)
    assert "up to date" in dvc(project, "status")


def _checkpointed(run: Path) -> bool:
    try:
        record = json.loads((run / "job.json").read_text())
        steps = json.loads((run / "run.json").read_text())["env_steps"]
    except (OSError, ValueError, KeyError):
        return False
    return not record["complete"] and 0 < steps < 12800
