"""Environments, registered with gymnasium under the ``famarl/`` namespace when this package is imported.

``gymnasium.make("famarl_cli.envs:famarl/ContinuousWorld-Maze-v0")`` imports and registers in one call.
"""

import gymnasium

from famarl_cli.envs import continuous_world, robot_hand
from famarl_cli.envs.continuous_world import ContinuousWorldEnv
from famarl_cli.envs.robot_hand import RobotHandEnv

CONTINUOUS_WORLD_IDS = {
    "base": "famarl/ContinuousWorld-Base-v0",
    "maze": "famarl/ContinuousWorld-Maze-v0",
    "maze-blind": "famarl/ContinuousWorld-MazeBlind-v0",
}
ROBOT_HAND_IDS = {
    "base": "famarl/RobotHand-Base-v0",
    "reaching": "famarl/RobotHand-Reaching-v0",
    "reaching-no-penalty": "famarl/RobotHand-ReachingNoPenalty-v0",
    "ball-placing": "famarl/RobotHand-BallPlacing-v0",
}
ENV_IDS = {**CONTINUOUS_WORLD_IDS, **{f"robot-hand-{task}": env_id for task, env_id in ROBOT_HAND_IDS.items()}}

for _module, _cls, _ids in (
    (continuous_world, "ContinuousWorldEnv", CONTINUOUS_WORLD_IDS),
    (robot_hand, "RobotHandEnv", ROBOT_HAND_IDS),
):
    for _task, _env_id in _ids.items():
        if _env_id not in gymnasium.registry:
            gymnasium.register(
                id=_env_id,
                entry_point=f"{_module.__name__}:{_cls}",
                kwargs={"task": _task},
                max_episode_steps=_module.TASKS[_task].max_episode_steps,
            )

__all__ = ["CONTINUOUS_WORLD_IDS", "ENV_IDS", "ROBOT_HAND_IDS", "ContinuousWorldEnv", "RobotHandEnv"]
