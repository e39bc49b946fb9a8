"""famarl report on hand-made evaluations: each claim's criterion, the verdicts, missing data and bad files."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from famarl_cli.cli import app
from famarl_cli.errors import ArtifactError
from famarl_cli.report import MAZE, REACHING, REACHING_NO_PENALTY, write_report


def make_run(
    data: Path,
    experiment: str,
    name: str,
    label: str,
    agent: str,
    success: float,
    env: str = MAZE,
    macro_lengths: tuple[float, ...] = (20.0, 20.0),
    learned: float | None = None,
) -> None:
    """An evaluated run as the pipelines leave it: <experiment>/runs/<name>/train.csv (whose training success climbs
    to ``learned``, by default the deterministic ``success``) and <experiment>/eval/<name>/eval.json."""
    learned = success if learned is None else learned
    run = data / experiment / "runs" / name
    run.mkdir(parents=True)
    with open(run / "train.csv", "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["env_steps", "episode_success", "episode_return", "macro_length"])
        for i, length in enumerate(macro_lengths):
            writer.writerow([(i + 1) * 1000, learned * (i + 1) / len(macro_lengths), -100 + i, length])
    evaluation = {
        "label": label,
        "agent": agent,
        "env": env,
        "seed": 0,
        "run": str(run),
        "success_rate": success,
        "return_mean": -100.0,
        "macro_length": macro_lengths[-1],
        "env_steps": 1000 * len(macro_lengths),
        "train_wall_s": 10.0,
    }
    (data / experiment / "eval" / name).mkdir(parents=True)
    (data / experiment / "eval" / name / "eval.json").write_text(json.dumps(evaluation))


def make_maze(data: Path, famarl: float, ppo: float, figar: float) -> None:
    for seed in (0, 1):
        make_run(data, "maze", f"famarl-seed{seed}", "famarl (pushed-down-only)", "famarl", famarl)
        make_run(data, "maze", f"ppo-seed{seed}", "ppo", "ppo", ppo, macro_lengths=(1.0, 1.0))
        make_run(data, "maze", f"figar-seed{seed}", "figar", "figar", figar)


def test_the_papers_maze_result_reproduces_when_only_famarl_solves_it(tmp_path):
    make_maze(tmp_path / "data", famarl=0.9, ppo=0.1, figar=0.2)
    sections = write_report(["maze"], tmp_path / "data", tmp_path / "report", "test")
    assert sections["maze"].verdict == "reproduces"
    text = (tmp_path / "report/report.md").read_text()
    assert "Fig. 4a, 4b): reproduces" in text
    assert "**does not reproduce**" not in text
    assert (tmp_path / "report/maze-curves.png").stat().st_size > 1000
    summary = json.loads((tmp_path / "report/summary.json").read_text())
    assert summary == {"maze": {"verdict": "reproduces", "claims_reproduced": 4, "claims": 4}}


def test_a_baseline_that_solves_the_maze_breaks_the_claims_about_it(tmp_path):
    make_maze(tmp_path / "data", famarl=0.9, ppo=1.0, figar=0.3)
    claims = write_report(["maze"], tmp_path / "data", tmp_path / "report", "test")["maze"].claims
    held = {claim.paper: claim.holds for claim in claims}
    assert held == {
        "FaMARL with pushed-down-only macro actions completes the Maze": True,
        "PPO with primitive actions fails to converge": False,
        "FiGAR fails to converge": True,
        "FaMARL performs best": False,
    }
    text = (tmp_path / "report/report.md").read_text()
    assert "partly reproduces (2 of 4 claims)" in text
    assert "best: ppo (1.00)" in text


def test_experiments_without_data_are_listed_with_their_command(tmp_path):
    make_maze(tmp_path / "data", famarl=0.9, ppo=0.1, figar=0.2)
    write_report(["maze", "beta", "robothand"], tmp_path / "data", tmp_path / "report", "test")
    text = (tmp_path / "report/report.md").read_text()
    assert "- beta: `dvc repro pipelines/beta/dvc.yaml`" in text
    assert "- robothand: `dvc repro pipelines/robothand/dvc.yaml`" in text
    with pytest.raises(ArtifactError, match="nothing to report"):
        write_report(["beta"], tmp_path / "data", tmp_path / "other", "test")


def test_macro_length_claims_read_the_start_and_end_of_training(tmp_path):
    data = tmp_path / "data"
    shortening = (30.0,) * 10 + (20.0,) * 10
    for seed in (0, 1):
        make_run(data, "robothand", f"r{seed}", "famarl (pegging)", "famarl", 0.2, REACHING, shortening)
        make_run(data, "macro-length", f"n{seed}", "famarl (pegging)", "famarl", 0.1, REACHING_NO_PENALTY, (30.0,) * 20)
    section = write_report(["macro-length"], data, tmp_path / "report", "test")["macro-length"]
    assert [claim.ours for claim in section.claims] == ["0.67", "1.00"]
    assert section.verdict == "reproduces"
    assert "| 30.0 -> 20.0 |" in (tmp_path / "report/report.md").read_text()


def test_beta_claims_use_each_favaes_mig(tmp_path):
    data = tmp_path / "data"
    for beta, success, mig in ((0.1, 0.2, 0.05), (1, 0.9, 0.2), (50, 0.85, 0.3)):
        favae = data / "beta" / "favae" / f"beta{beta}.pt"
        favae.parent.mkdir(parents=True, exist_ok=True)
        favae.with_suffix(".metrics.json").write_text(json.dumps({"mig": mig, "beta": beta}))
        make_run(data, "beta", f"beta{beta}-seed0", f"beta {beta}", "famarl", success)
        run = data / "beta" / "runs" / f"beta{beta}-seed0"
        (run / "run.json").write_text(json.dumps({"schema": "famarl.run", "spec": {"favae": str(favae)}}))
    section = write_report(["beta"], data, tmp_path / "report", "test")["beta"]
    assert [claim.holds for claim in section.claims] == [True, True, True]
    text = (tmp_path / "report/report.md").read_text()
    assert "beta 0.1: MIG 0.05, beta 1: MIG 0.20, beta 50: MIG 0.30" in text


def test_cli_refuses_unknown_experiments_and_bad_evaluations(tmp_path):
    runner = CliRunner()
    result = runner.invoke(app, ["report", "--experiment", "fig9", "--data", str(tmp_path)])
    assert result.exit_code == 2 and "unknown experiment fig9" in result.output
    make_maze(tmp_path / "data", famarl=0.9, ppo=0.1, figar=0.2)
    broken = tmp_path / "data/maze/eval/ppo-seed0/eval.json"
    broken.write_text(json.dumps({k: v for k, v in json.loads(broken.read_text()).items() if k != "env"}))
    result = runner.invoke(app, ["report", "--data", str(tmp_path / "data"), "--out", str(tmp_path / "r")])
    assert result.exit_code == 1
    assert result.output.strip().splitlines()[-1].startswith("error: ")
    assert "has no 'env'" in result.output
    assert not (tmp_path / "r/report.md").exists()


def test_learning_claims_read_training_success_and_show_the_deterministic_one(tmp_path):
    data = tmp_path / "data"
    make_run(data, "maze", "famarl-seed0", "famarl (pushed-down-only)", "famarl", 0.9)
    make_run(data, "maze", "ppo-seed0", "ppo", "ppo", 0.2)
    make_run(data, "maze", "figar-seed0", "figar", "figar", 0.01, learned=0.87)
    claims = {c.paper: c for c in write_report(["maze"], data, tmp_path / "report", "test")["maze"].claims}
    assert not claims["FiGAR fails to converge"].holds
    assert claims["FiGAR fails to converge"].ours == "0.87 (deterministic 0.01)"
    assert "| figar | 1 | 2,000 | 0.87 | 0.01 |" in (tmp_path / "report/report.md").read_text()
