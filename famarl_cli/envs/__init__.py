"""Environments, registered with gymnasium under the ``famarl/`` namespace when this package is imported.

``gymnasium.make("famarl_cli.envs:famarl/ContinuousWorld-Maze-v0")`` imports and registers in one call.
"""

import gymnasium

from famarl_cli.envs.continuous_world import TASKS, ContinuousWorldEnv

ENV_IDS = {
    "base": "famarl/ContinuousWorld-Base-v0",
    "maze": "famarl/ContinuousWorld-Maze-v0",
    "maze-blind": "famarl/ContinuousWorld-MazeBlind-v0",
}

for _name, _env_id in ENV_IDS.items():
    if _env_id not in gymnasium.registry:
        gymnasium.register(
            id=_env_id,
            entry_point="famarl_cli.envs.continuous_world:ContinuousWorldEnv",
            kwargs={"task": _name},
            max_episode_steps=TASKS[_name].max_episode_steps,
        )

__all__ = ["ENV_IDS", "ContinuousWorldEnv"]
