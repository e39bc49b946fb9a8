"""Scripted controllers of RobotHand's target tasks: the positive controls that show each task can be solved in
its own physics and time limit, which no agent's failure can show.

They move the hand the way the pegging expert does (:class:`~famarl_cli.experts.pegging.PhasedHand`: straight moves
that cruise and arrive, the hand held level), so a task they solve is solved by the kind of motion the pegging demos
hold:

- **Reaching**: one move, the grip point straight to the goal;
- **BallPlacing**: approach above the ball with the fingers open, descend until the grip point is at the ball's
  centre, close the fingers, lift to the goal's height and carry the ball across to the goal (the episode succeeds
  on arrival, held: BallPlacing asks for the ball at the goal, not for it let go).

Their phases carry the pegging expert's factors (the grip point's displacement and the grasp command), so their
episodes are demos as well as controls.
"""

from __future__ import annotations

import numpy as np

from famarl_cli.experts.pegging import HOVER_CLEARANCE, Phase, PhasedHand

GRASP_STEPS = 6
"""Steps the fingers close on the ball (as on the rod)."""


class ReachingControl(PhasedHand):
    """RobotHand Reaching: the grip point straight to the goal (observation's target)."""

    def plan_for(self, observation: np.ndarray) -> list[Phase]:
        return [Phase("reach", (float(observation[14]), float(observation[15])), 0.0)]


class BallPlacingControl(PhasedHand):
    """RobotHand BallPlacing: take the ball from its cup, lift it to the goal's height, carry it to the goal."""

    def plan_for(self, observation: np.ndarray) -> list[Phase]:
        ball_x, ball_y = float(observation[8]), float(observation[9])
        goal_x, goal_y = float(observation[14]), float(observation[15])
        carry_y = max(goal_y, ball_y + HOVER_CLEARANCE)
        return [
            Phase("approach", (ball_x, ball_y + HOVER_CLEARANCE), -1.0),
            Phase("descend", (ball_x, ball_y), -1.0),
            Phase("grasp", None, 1.0, GRASP_STEPS),
            Phase("lift", (ball_x, carry_y), 1.0),
            Phase("carry", (goal_x, carry_y), 1.0),
        ]
