"""The pipelines on gymnasium's envs (BipedalWalker, PointMaze) end to end at tiny parameters, in a DVC project of
their own: they read nothing of the default pipeline, so this module runs them on one worker while
tests/test_pipelines.py runs the default pipeline and the pipelines that read it on another. Every report is
written and read what its stages made, and a second ``dvc repro`` does nothing."""

from pathlib import Path

import pytest
from cli_helpers import dvc
from test_pipelines import GYM, check_reports, plot_titles, repro_tiny


@pytest.fixture(scope="module")
def project(tmp_path_factory) -> Path:
    """:data:`~test_pipelines.GYM`, without the default pipeline, run once."""
    return repro_tiny(tmp_path_factory.mktemp("gym-pipelines"), GYM, default=False)


@pytest.mark.slow  # DVC repro of real pipelines
def test_the_gymnasium_pipelines_write_their_reports_and_curves(project):
    check_reports(project, GYM)
    bipedal = (project / "data/report/bipedal/report.md").read_text()
    assert "| FaMARL fails BipedalWalker (it does not walk to the far end) |" in bipedal
    assert "gymnasium's heuristic controller kept 1 of 1 episodes" in bipedal
    assert "FaMARL's row counts the replicates added in blocks" in bipedal  # the block stages ran and were read
    pointmaze = (project / "data/report/pointmaze/report.md").read_text()
    assert "PointMaze Medium, sparse reward:" in pointmaze and "| hybrid |" in pointmaze
    for figure in ("bipedal/bipedal-traversal.png", "pointmaze/pointmaze-demos.png"):
        assert (project / "data/report" / figure).stat().st_size > 1000
    titles = plot_titles(project)
    assert "PointMaze, training success" in titles and "BipedalWalker, training return" in titles


@pytest.mark.slow  # DVC repro of real pipelines
def test_a_second_repro_of_them_does_nothing(project):
    assert "Running stage" not in dvc(project, "repro", "-P")
