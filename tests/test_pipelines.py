"""Every DVC pipeline end to end on tiny parameters: the stages link up, every report is written, a second
``dvc repro`` does nothing, and a changed parameter re-runs only the stages that depend on it."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]

TINY_TRAIN = {"steps": 1500}
TINY_EVALUATE = {"episodes": 3}
TINY_FAVAE = {"epochs": 3}
TINY_SEGMENT = {"epochs": 3}
TINY = {
    "params.yaml": {
        "seeds": "0-1",
        "demos": {"episodes": 6},
        "segment": TINY_SEGMENT,
        "favae": TINY_FAVAE,
        "train": TINY_TRAIN,
        "evaluate": TINY_EVALUATE,
    },
    "pipelines/scripts/params.yaml": {
        "seeds": "0-1",
        "scripts": "down-and-up",
        "demos": {"episodes": 6},
        "segment": TINY_SEGMENT,
        "favae": TINY_FAVAE,
        "train": TINY_TRAIN,
        "evaluate": TINY_EVALUATE,
    },
    "pipelines/beta/params.yaml": {"seeds": "0-1", "betas": "0.1", "favae": TINY_FAVAE, "train": TINY_TRAIN, "evaluate": TINY_EVALUATE},
    "pipelines/demos-count/params.yaml": {
        "seeds": "0-1",
        "counts": "4",
        "segment": TINY_SEGMENT,
        "favae": TINY_FAVAE,
        "train": TINY_TRAIN,
        "evaluate": TINY_EVALUATE,
    },
    "pipelines/traversal/params.yaml": {"seeds": "0-1", "favae": TINY_FAVAE},
    "pipelines/robothand/params.yaml": {
        "seeds": "0-1",
        "demos": {"episodes": 4},
        "segment": TINY_SEGMENT,
        "favae": TINY_FAVAE,
        "train": TINY_TRAIN,
        "evaluate": TINY_EVALUATE,
    },
    "pipelines/macro-length/params.yaml": {"seeds": "0-1", "train": TINY_TRAIN, "evaluate": TINY_EVALUATE},
}
"""Overrides of each params file: two seeds (an interval needs two), one variant where a pipeline sweeps, a few
episodes, epochs and env steps. Every key must already exist, so the test fails if a params file is restructured
without it. down-and-up stays among the scripts: pipelines/traversal reads its segments."""

EXPERIMENTS = ("scripts", "beta", "demos-count", "traversal", "robothand", "macro-length")


def _override(values: dict, overrides: dict, where: str) -> None:
    for key, value in overrides.items():
        assert key in values, f"{where}: no {key!r} to override"
        if isinstance(value, dict):
            _override(values[key], value, f"{where}.{key}")
        else:
            values[key] = value


@pytest.fixture(scope="module")
def project(tmp_path_factory) -> Path:
    """A copy of the project's pipelines with tiny params, run once with ``dvc repro -P``."""
    root = tmp_path_factory.mktemp("pipelines")
    shutil.copy(ROOT / "dvc.yaml", root)
    shutil.copytree(ROOT / "pipelines", root / "pipelines")
    for name, overrides in TINY.items():
        path = ROOT / name
        values = yaml.safe_load(path.read_text())
        _override(values, overrides, name)
        (root / name).write_text(yaml.safe_dump(values))
    dvc(root, "init", "--no-scm")
    dvc(root, "repro", "-P")
    return root


def dvc(root: Path, *args: str) -> str:
    env = {
        **os.environ,
        "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}",
        "DVC_NO_ANALYTICS": "1",
        "DVC_SITE_CACHE_DIR": str(root / ".dvc-site"),
        "MPLBACKEND": "Agg",
    }
    done = subprocess.run(
        [sys.executable, "-m", "dvc", *args], cwd=root, env=env, capture_output=True, text=True, check=False
    )
    assert done.returncode == 0, f"dvc {' '.join(args)} failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return done.stdout + done.stderr


def test_every_pipeline_writes_its_report(project):
    headline = (project / "data/report/report.md").read_text()
    assert "## Maze: FaMARL vs PPO vs FiGAR" in headline
    assert "| FaMARL performs best |" in headline
    for figure in ("maze-curves.png", "maze-rollouts-famarl.png", "maze-traversal.png"):
        assert (project / "data/report" / figure).stat().st_size > 1000
    for name in EXPERIMENTS:
        text = (project / "data/report" / name / "report.md").read_text()
        assert text.startswith("# famarl report")
        assert "| the paper says | we test | ours | verdict |" in text
        assert "Not run yet" not in text
        summary = json.loads((project / "data/report" / name / "summary.json").read_text())
        assert set(summary) == {name}
        assert 0 <= summary[name]["claims_reproduced"] <= summary[name]["claims"]
    scripts = (project / "data/report/scripts/report.md").read_text()
    for label in ("pushed-down-only", "down-and-up"):
        assert f"| famarl ({label}) |" in scripts
    assert "| beta 0.1 |" in (project / "data/report/beta/report.md").read_text()
    assert "| 4 demos |" in (project / "data/report/demos-count/report.md").read_text()
    robothand = (project / "data/report/robothand/report.md").read_text()
    assert "reaching:" in robothand and "ballplacing:" in robothand
    assert "no time penalty" in (project / "data/report/macro-length/report.md").read_text()
    metrics = dvc(project, "metrics", "show")
    assert "data/favae/pushed-down-only.metrics.json" in metrics


def test_a_second_repro_does_nothing(project):
    assert "Running stage" not in dvc(project, "repro", "-P")
    assert "up to date" in dvc(project, "status")


def test_a_changed_parameter_reruns_only_its_dependents(project):
    params = yaml.safe_load((project / "params.yaml").read_text())
    params["evaluate"]["episodes"] += 1
    (project / "params.yaml").write_text(yaml.safe_dump(params))
    ran = {line.split("'")[1] for line in dvc(project, "repro", "-P").splitlines() if line.startswith("Running stage")}
    # The headline's evaluation, and every report that reads it; no training, nothing of the other pipelines.
    assert ran == {"evaluate", "report", "pipelines/scripts/dvc.yaml:report"}
