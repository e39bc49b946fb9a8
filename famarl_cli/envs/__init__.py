"""Environments, registered with gymnasium under the ``famarl/`` namespace when this package is imported, which
``import famarl_cli`` does (then ``gymnasium.make("famarl/ContinuousWorld-Maze-v0")``).

``gymnasium.make("famarl_cli.envs:famarl/ContinuousWorld-Maze-v0")`` imports and registers in one call.
"""

from enum import StrEnum

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
    "base-varied": "famarl/RobotHand-BaseVaried-v0",
    "reaching": "famarl/RobotHand-Reaching-v0",
    "reaching-no-penalty": "famarl/RobotHand-ReachingNoPenalty-v0",
    "reaching-far": "famarl/RobotHand-Reaching-v1",
    "reaching-far-no-penalty": "famarl/RobotHand-ReachingNoPenalty-v1",
    "ball-placing": "famarl/RobotHand-BallPlacing-v0",
    "ball-placing-no-escape": "famarl/RobotHand-BallPlacingNoEscape-v0",
}
ENV_IDS = {**CONTINUOUS_WORLD_IDS, **{f"robot-hand-{task}": env_id for task, env_id in ROBOT_HAND_IDS.items()}}
WORLDS = {"continuous-world": continuous_world, "robot-hand": robot_hand}
"""famarl's env families by name. Each module provides its env class, ``TASKS``, ``ACTION_SPACE`` and
``traversal_paths(actions, lengths)``: the empty world a latent traversal runs macro actions in."""
World = StrEnum("World", {name.upper().replace("-", "_"): name for name in WORLDS})
"""The names of WORLDS, as a type that options take."""
DEFAULT_WORLD = "continuous-world"
"""Where a latent traversal runs macro actions when no world or env is given: the paper's env."""
_FAMILIES = {
    "continuous-world": ("ContinuousWorldEnv", CONTINUOUS_WORLD_IDS),
    "robot-hand": ("RobotHandEnv", ROBOT_HAND_IDS),
}


def world_of(env_id: str) -> str | None:
    """The family (a key of WORLDS) of one of famarl's env ids; None for any other env."""
    return next((name for name, (_, ids) in _FAMILIES.items() if env_id in ids.values()), None)


for _world, (_cls, _ids) in _FAMILIES.items():
    _module = WORLDS[_world]
    for _task, _env_id in _ids.items():
        if _env_id not in gymnasium.registry:
            gymnasium.register(
                id=_env_id,
                entry_point=f"{_module.__name__}:{_cls}",
                kwargs={"task": _task},
                max_episode_steps=_module.TASKS[_task].max_episode_steps,
            )

__all__ = [
    "CONTINUOUS_WORLD_IDS",
    "DEFAULT_WORLD",
    "ENV_IDS",
    "ROBOT_HAND_IDS",
    "WORLDS",
    "ContinuousWorldEnv",
    "RobotHandEnv",
    "World",
    "world_of",
]
