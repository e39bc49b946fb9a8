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


def words(observation):
    return "left"


def complex_action(observation):
    return np.array([1.0 + 2.0j])


def array_label(observation):
    return np.array([0.5]), np.array([1, 2])


def raises(observation):
    raise RuntimeError("the policy server is down")


class NeedsGain:
    def __init__(self, env, gain):
        self.gain = gain

    def act(self, observation):
        return np.array([self.gain])


class FailsToStart:
    def __init__(self, env):
        raise KeyError("weights.pt")

    def act(self, observation):
        return np.zeros(1)


class BadFactors:
    """Keeps famarl's expert protocol, with factors that are not numbers."""

    factor_names = ("side",)

    def reset(self, observation):
        self.phase_starts, self.phase_factors = [0], [["left"]]

    def act(self, observation):
        return np.zeros(1)


def full_push(observation):
    return np.ones(1)


def full_throttle(observation):
    """LunarLander: both engines at full power, every step."""
    return np.ones(2)


class Backwards:
    """Keeps famarl's expert protocol with phases that start out of order."""

    factor_names = ("side",)

    def reset(self, observation):
        self.phase_starts, self.phase_factors = [0, 5, 3], [[0.0], [1.0], [0.0]]

    def act(self, observation):
        return np.zeros(1)


def pump(observation):
    """MountainCarContinuous: push the way the car already moves, full power; it reaches the goal every episode
    with a return just short of the env's reward_threshold (90), the cost of its pushes."""
    return np.array([1.0 if observation[1] >= 0 else -1.0])
