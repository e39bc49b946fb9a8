import pytest

from famarl_cli.demos import record_demos
from famarl_cli.experts import Script


@pytest.fixture(scope="session")
def tiny_demos():
    """A few pushed-down-only episodes, shared by tests that only read them."""
    return record_demos(Script.PUSHED_DOWN_ONLY, n_episodes=6, seed=3)
