import pytest
import torch
from cli_helpers import famarl

from famarl_cli.experts import Script
from famarl_cli.stages.demos import record_demos

# Small networks run fastest on one thread; with two, torch competes with any other process for the 2 cores and
# the suite slows down many times over.
torch.set_num_threads(1)


FIRST = "test_pipelines.py"
"""The longest module (its pipelines run end to end, whole in one worker): started first, so that the other
workers share everything else meanwhile instead of waiting for it at the end."""


def pytest_collection_modifyitems(items):
    items.sort(key=lambda item: item.path.name != FIRST)  # stable: the order within each part stays


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
