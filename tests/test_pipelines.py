"""Every DVC pipeline end to end on tiny parameters: the stages link up, every report is written, a second
``dvc repro`` does nothing, and a changed parameter re-runs only the stages that depend on it."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from cli_helpers import dvc, dvc_json

pytestmark = pytest.mark.slow  # DVC repro of real pipelines

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
    "pipelines/beta/params.yaml": {
        "seeds": "0-1",
        "betas": "0.1",
        "favae": TINY_FAVAE,
        "train": TINY_TRAIN,
        "evaluate": TINY_EVALUATE,
    },
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
    "pipelines/hybrid/params.yaml": {
        "seeds": "0-1",
        "maze": TINY_TRAIN,
        "robothand": TINY_TRAIN,
        "evaluate": TINY_EVALUATE,
    },
    "pipelines/bipedal/params.yaml": {
        "seeds": "0-1",
        "demos": {"episodes": 1, "min_return": -1000},
        "segment": TINY_SEGMENT,
        "favae": TINY_FAVAE,
        "train": TINY_TRAIN,
        "evaluate": TINY_EVALUATE,
    },
    "pipelines/skills/params.yaml": {
        "seeds": "0-1",
        "prior": {"epochs": 3},
        "maze": TINY_TRAIN,
        "pointmaze": {
            "steps": 1500,
            "large_demos": {"episodes": 4},
            "large_macros": {"segment_epochs": 3, "epochs": 3},
        },
        "robothand": TINY_TRAIN,
        "bipedal": {"seeds": "0-1", "steps": 1500},
        "evaluate": {"episodes": {"maze": 3, "pointmaze": 3, "reaching": 3, "bipedal": 3}},
    },
    "pipelines/pointmaze/params.yaml": {
        "seeds": "0-1",
        "mazes": "Medium",
        "demos": {"episodes": 4},
        "segment": TINY_SEGMENT,
        "favae": TINY_FAVAE,
        "train": TINY_TRAIN,
        "evaluate": TINY_EVALUATE,
    },
}
"""Overrides of each params file: two seeds (an interval needs two), one variant where a pipeline sweeps, a few
episodes, epochs and env steps. Every key must already exist, so the test fails if a params file is restructured
without it. down-and-up stays among the scripts: pipelines/traversal reads its segments."""

EXPERIMENTS = (
    "scripts",
    "beta",
    "demos-count",
    "traversal",
    "robothand",
    "macro-length",
    "hybrid",
    "bipedal",
    "pointmaze",
    "skills",
)
GOALS = ("hybrid", "pointmaze", "skills")
"""The experiments judged as goals beyond the paper rather than as the paper's claims."""


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
    shutil.copytree(ROOT / ".dvc" / "plots", root / ".dvc" / "plots")  # the learning-curves template
    dvc(root, "repro", "-P")
    return root


def test_every_pipeline_writes_its_report(project):
    headline = (project / "data/report/report.md").read_text()
    assert "## Maze: FaMARL vs PPO vs FiGAR" in headline
    assert "| FaMARL performs best |" in headline
    for figure in ("maze-curves.png", "maze-intervals.png", "maze-rollouts-famarl.png", "maze-traversal.png"):
        assert (project / "data/report" / figure).stat().st_size > 1000
    for name in EXPERIMENTS:
        text = (project / "data/report" / name / "report.md").read_text()
        assert text.startswith("# famarl report")
        first = "goal" if name in GOALS else "the paper says"
        assert f"| {first} | per seed we measure | rule (95% intervals) |" in text
        assert "Not run yet" not in text
        summary = json.loads((project / "data/report" / name / "summary.json").read_text())
        assert set(summary) == {name}
        counts = [summary[name][f"claims_{kind}"] for kind in ("reproduced", "not_reproduced", "inconclusive")]
        assert sum(counts) == summary[name]["claims"] > 0
    scripts = (project / "data/report/scripts/report.md").read_text()
    for label in ("pushed-down-only", "down-and-up"):
        assert f"| famarl ({label}) |" in scripts
    assert "| beta 0.1 |" in (project / "data/report/beta/report.md").read_text()
    assert "| 4 demos |" in (project / "data/report/demos-count/report.md").read_text()
    robothand = (project / "data/report/robothand/report.md").read_text()
    assert "reaching:" in robothand and "ballplacing:" in robothand
    macro_length = (project / "data/report/macro-length/report.md").read_text()
    assert "| famarl, no time penalty, semi-MDP |" in macro_length
    hybrid = (project / "data/report/hybrid/report.md").read_text()
    for label in ("famarl", "ppo", "figar", "hybrid", "hybrid-whole", "hybrid-no-residual", "hybrid-per-decision"):
        assert f"| {label} |" in hybrid
    assert "Semi-MDP (`steps`, the hybrid's default) against per-decision" in hybrid
    bipedal = (project / "data/report/bipedal/report.md").read_text()
    assert "| FaMARL fails BipedalWalker (it does not walk to the far end) |" in bipedal
    assert "gymnasium's heuristic controller kept 1 of 1 episodes" in bipedal
    pointmaze = (project / "data/report/pointmaze/report.md").read_text()
    assert "PointMaze Medium, sparse reward:" in pointmaze and "| hybrid |" in pointmaze
    skills = (project / "data/report/skills/report.md").read_text()
    for label in ("famarl", "ppo", "famarl+prior", "famarl+closed", "famarl+prior+closed", "hybrid+prior+closed"):
        assert f"| {label} |" in skills
    assert "PointMaze Large, sparse, Large demos:" in skills and "| famarl-h10 |" in skills
    assert "action MSE, closed-loop" in skills  # the priors' held-out scores
    for figure in (
        "bipedal/bipedal-traversal.png",
        "pointmaze/pointmaze-demos.png",
        "skills/skills-maze-curves.png",
        "skills/skills-maze-prior.png",
    ):
        assert (project / "data/report" / figure).stat().st_size > 1000
    assert "data/report/summary.json" in dvc(project, "metrics", "show")
    # Each replicate's macro actions: segments, C_last, FAVAE and traversal, all from its own seed.
    for seed in (0, 1):
        replicate = project / "data/maze/macros" / f"seed{seed}"
        for name in ("segments.h5", "favae.calibration.json", "favae.pt", "favae.metrics.json", "traverse.json"):
            assert (replicate / name).is_file()
        provenance = json.loads((replicate / "favae.calibration.json").read_text())["provenance"]
        assert provenance["seed"] == seed and provenance["platform"]["threads"] == 1
        # no latent, no ladder carries more information than the segments can hold
        metrics = json.loads((replicate / "favae.metrics.json").read_text())
        bound = np.log(metrics["segments"])
        assert metrics["information_bound"] == pytest.approx(bound)
        assert max(metrics["information_per_dim"] + metrics["information_per_ladder"]) <= bound + 1e-6
        assert 0 <= metrics["length_accuracy"] <= metrics["length_within_one"] <= 1


def test_learning_curves_are_dvc_plots_and_headline_numbers_are_metrics(project):
    shown = dvc_json(project, "plots", "show")
    assert not shown.get("errors"), shown.get("errors")
    maze = shown["data"]["Maze, training success (last 100 episodes)"][0]["content"]
    assert maze["encoding"]["color"]["field"] == "series" and maze["encoding"]["y"]["field"] == "success"
    rows = maze["data"]["values"]
    assert {row["run"] for row in rows} == {
        f"{agent}-seed{seed}" for agent in ("famarl", "ppo", "figar") for seed in (0, 1)
    }
    assert {row["series"] for row in rows} == {"famarl", "ppo", "figar"}
    assert all(0 <= float(row["success"]) <= 1 for row in rows if row["success"] != "nan")
    titles = " / ".join(shown["data"])
    for title in ("Scripts", "beta", "Demos count", "RobotHand", "Macro length", "Hybrid", "PointMaze", "Skills"):
        assert f"{title}, training success" in titles
    assert "BipedalWalker, training return" in titles
    metrics = dvc_json(project, "metrics", "show")[""]["data"]
    famarl = metrics["data/report/summary.json"]["data"]["maze"]["headline"]["famarl"]
    assert famarl["n"] == 2 and famarl["success_low"] <= famarl["success"] <= famarl["success_high"]
    assert "headline" in metrics["data/report/robothand/summary.json"]["data"]["robothand"]


def test_a_second_repro_does_nothing(project):
    assert "Running stage" not in dvc(project, "repro", "-P")
    assert "up to date" in dvc(project, "status")


def test_a_changed_parameter_reruns_only_its_dependents(project):
    params = yaml.safe_load((project / "params.yaml").read_text())
    params["evaluate"]["episodes"] += 1
    (project / "params.yaml").write_text(yaml.safe_dump(params))
    ran = {line.split("'")[1] for line in dvc(project, "repro", "-P").splitlines() if line.startswith("Running stage")}
    # The headline's evaluation, and every report that reads it; no training, nothing else of the other pipelines.
    assert ran == {
        "evaluate",
        "report",
        "pipelines/scripts/dvc.yaml:report",
        "pipelines/beta/dvc.yaml:report",
        "pipelines/demos-count/dvc.yaml:report",
        "pipelines/hybrid/dvc.yaml:report",
        "pipelines/skills/dvc.yaml:report",
    }
