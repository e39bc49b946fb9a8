"""Experts as a user writes them, named module:attribute in tests (``--expert user_experts:swing``)."""

import numpy as np


def swing(observation):
    """Pendulum: push the way the pendulum already swings (a policy function, no phases)."""
    return np.array([np.sign(observation[2]) or 1.0])


def two_phases(observation):
    """Pendulum: phase "left" while the pendulum leans left, "right" otherwise; returns (action, phase)."""
    phase = "left" if observation[1] < 0 else "right"
    return np.array([-1.0 if phase == "left" else 1.0]), phase


def wrong_shape(observation):
    return np.zeros(3)


def not_finite(observation):
    return np.array([np.nan])


class Counter:
    """A class expert without the env: its phases change every 5 steps, marked by the label it returns."""

    def reset(self, observation):
        self.t = 0

    def act(self, observation):
        self.t += 1
        return np.array([0.5]), (self.t - 1) // 5


NOT_CALLABLE = 3
