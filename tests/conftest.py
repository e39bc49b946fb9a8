import pytest
import torch

from famarl_cli.demos import record_demos
from famarl_cli.experts import Script

# Small networks run fastest on one thread; with two, torch competes with any other process for the 2 cores and
# the suite slows down many times over.
torch.set_num_threads(1)


@pytest.fixture(scope="session")
def tiny_demos():
    """A few pushed-down-only episodes, shared by tests that only read them."""
    return record_demos(Script.PUSHED_DOWN_ONLY, n_episodes=6, seed=3)
