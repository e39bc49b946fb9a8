"""famarl's envs as gymnasium users meet them: registered by the package import, each passing gymnasium's own
env checker."""

import subprocess
import sys

import gymnasium as gym
import pytest
from gymnasium.utils.env_checker import check_env

import famarl_cli
from famarl_cli.envs import ENV_IDS

FAMARL_IDS = sorted(env_id for env_id in gym.registry if env_id.startswith("famarl/"))


def test_the_package_import_registers_every_env_id():
    # A fresh interpreter: this one has imported famarl_cli.envs long ago.
    code = (
        "import gymnasium as gym, famarl_cli; gym.register_envs(famarl_cli); "
        "print(sorted(i for i in gym.registry if i.startswith('famarl/'))); "
        "print(gym.make('famarl/ContinuousWorld-Maze-v0').spec.max_episode_steps)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split("\n")
    assert out[0] == str(sorted(ENV_IDS.values())) and out[1] == "400"


def test_registered_ids_are_the_ones_famarl_names():
    assert FAMARL_IDS == sorted(ENV_IDS.values())
    assert famarl_cli.envs.ENV_IDS is ENV_IDS


@pytest.mark.parametrize("env_id", FAMARL_IDS)
def test_every_registered_env_passes_gymnasiums_checker(env_id):
    env = gym.make(env_id)
    # The spec gymnasium.make builds: a time limit, the order enforcer and the passive checker, as for its own envs.
    assert env.spec.max_episode_steps is not None and env.spec.order_enforce and not env.spec.disable_env_checker
    check_env(env.unwrapped, skip_render_check=True)
    env.close()
