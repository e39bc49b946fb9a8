import pytest
import torch
from cli_helpers import famarl

from famarl_cli.experts import Script
from famarl_cli.stages.demos import record_demos

# Small networks run fastest on one thread; with two, torch competes with any other process for the 2 cores and
# the suite slows down many times over.
torch.set_num_threads(1)


FIRST = (
    "test_pipelines.py",
    "test_pipelines_gym.py",
    "test_sweep.py",
    "test_faults.py",
    "test_cli.py",
    "test_sweep_dvc.py",
    "test_prior.py",
    "test_report.py",
    "test_evaluate_compose.py",
    "test_docs_tables.py",
)
"""The longest modules, longest first (``--durations=0`` of the whole suite; test_pipelines.py's run whole in one
worker for several minutes): started first, so that the other workers share the short rest meanwhile instead of
one waiting at the end for a long module started late. The rest keep their order. xdist keeps this order only
with ``--no-loadscope-reorder`` (pyproject.toml); by default it starts the files with the most tests first."""


def pytest_collection_modifyitems(items):
    rank = {name: i for i, name in enumerate(FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(FIRST)))  # stable: the order within each part stays


@pytest.fixture(scope="session")
def tiny_demos():
    """A few pushed-down-only episodes, shared by tests that only read them."""
    return record_demos(Script.PUSHED_DOWN_ONLY, n_episodes=6, seed=3)


@pytest.fixture(scope="session")
def demos_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("demos") / "demos.h5"
    assert famarl("demos", "--episodes", 8, "--seed", 2, "--out", path, "--no-plot").exit_code == 0
    return path


@pytest.fixture(scope="session")
def segments_file(demos_file, tmp_path_factory):
    out = tmp_path_factory.mktemp("segments") / "seg.h5"
    result = famarl("segment", "--demos", demos_file, "--out", out, "--segment-epochs", 5, "--length", 48, "--no-plot")
    assert result.exit_code == 0, result.output
    return out


@pytest.fixture(scope="session")
def favae_file(segments_file, tmp_path_factory):
    out = tmp_path_factory.mktemp("favae") / "favae.pt"
    result = famarl("favae", "fit", "--segments", segments_file, "--epochs", 2, "--out", out)
    assert result.exit_code == 0, result.output
    return out
