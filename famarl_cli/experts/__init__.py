"""Scripted experts: each acts from observations alone and records where its phases begin and their factors.

Every expert has ``reset(observation)``, ``act(observation) -> action``, ``phase_starts`` (first step of each phase
begun so far) and ``phase_factors`` ((phases, factors) ground truth). :func:`demonstration` says which expert,
environment and factor names a script uses.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from famarl_cli.envs import ENV_IDS
from famarl_cli.experts import continuous_world, pegging
from famarl_cli.experts.continuous_world import ContinuousWorldExpert
from famarl_cli.experts.pegging import PeggingExpert, PhasedHand
from famarl_cli.experts.robot_hand_tasks import BallPlacingControl, ReachingControl
from famarl_cli.experts.scripts import Script


@dataclass(frozen=True)
class Demonstration:
    env_id: str
    env_kwargs: dict = field(default_factory=dict)
    factor_names: tuple[str, ...] = ()


ROBOT_HAND_TASKS = {
    Script.PEGGING: "base",
    Script.PEGGING_VARIED: "base-varied",
    Script.PEGGING_PHASES: "base",
    Script.REACHING: "reaching-far",
    Script.BALL_PLACING: "ball-placing",
}
"""The RobotHand task each RobotHand script acts in: the reaching control in Reaching-v1, the version
pipelines/robothand judges agents on (goals at least 2 m from the grip's start, docs/robothand.md)."""


def demonstration(script: Script) -> Demonstration:
    script = Script(script)
    if script in ROBOT_HAND_TASKS:
        return Demonstration(ENV_IDS[f"robot-hand-{ROBOT_HAND_TASKS[script]}"], {}, pegging.FACTOR_NAMES)
    return Demonstration(ENV_IDS["base"], {"goal_rows": list(script.goal_rows)}, continuous_world.FACTOR_NAMES)


def make_expert(script: Script) -> ContinuousWorldExpert | PhasedHand:
    script = Script(script)
    controllers = {
        Script.PEGGING: PeggingExpert,
        Script.PEGGING_VARIED: PeggingExpert,
        Script.PEGGING_PHASES: lambda: PeggingExpert(varied=True),
        Script.REACHING: ReachingControl,
        Script.BALL_PLACING: BallPlacingControl,
    }
    return controllers[script]() if script in controllers else ContinuousWorldExpert(script)


__all__ = [
    "BallPlacingControl",
    "ContinuousWorldExpert",
    "Demonstration",
    "PeggingExpert",
    "ReachingControl",
    "Script",
    "demonstration",
    "make_expert",
]
