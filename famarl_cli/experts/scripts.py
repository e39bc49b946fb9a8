"""The names of the scripted experts, and which environment each one demonstrates in."""

from __future__ import annotations

from enum import StrEnum


class Environment(StrEnum):
    CONTINUOUS_WORLD = "continuous-world"
    ROBOT_HAND = "robot-hand"


class Script(StrEnum):
    """The paper's four ContinuousWorld scripts (its Figure 3), RobotHand's pegging script (ours too: with the
    baskets raised to varied heights, BaseVaried; with phases of varied lengths, pegging-phases), and the scripted
    controllers of RobotHand's two target tasks (positive controls, :mod:`famarl_cli.experts.robot_hand_tasks`)."""

    DOWN_ONLY = "down-only"
    DOWN_AND_UP = "down-and-up"
    PUSHED_DOWN_ONLY = "pushed-down-only"
    PUSHED_DOWN_AND_UP = "pushed-down-and-up"
    PEGGING = "pegging"
    PEGGING_VARIED = "pegging-varied"
    PEGGING_PHASES = "pegging-phases"
    REACHING = "reaching"
    BALL_PLACING = "ball-placing"

    @property
    def environment(self) -> Environment:
        continuous_world = (Script.DOWN_ONLY, Script.DOWN_AND_UP, Script.PUSHED_DOWN_ONLY, Script.PUSHED_DOWN_AND_UP)
        return Environment.CONTINUOUS_WORLD if self in continuous_world else Environment.ROBOT_HAND

    @property
    def goal_rows(self) -> tuple[str, ...]:
        """ContinuousWorld: the goal rows this script's demos are drawn from ("only" scripts never see a goal on
        top)."""
        return ("bottom",) if self.value.endswith("down-only") else ("top", "bottom")

    @property
    def pushed(self) -> bool:
        return self.value.startswith("pushed")
