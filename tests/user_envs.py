"""Envs as a user writes them, some broken, registered when gymnasium imports this module (``user_envs:Id``)."""

import os
from pathlib import Path

import gymnasium as gym
import numpy as np

HEARTBEAT = "FAMARL_TEST_HEARTBEAT"
"""Where an env writes, at its ``HEARTBEAT_STEP``-th step, that it is deep into an episode: a test waits for that
file, not a fixed time, before it interrupts the command stepping it."""
HEARTBEAT_STEP = 1000


class Plain(gym.Env):
    """A 1-D walk: the agent pushes a point; the episode terminates at step ``ends`` (never, with None), each step
    costs 1, and nothing in ``info`` says whether it succeeded."""

    observation_space = gym.spaces.Box(-np.inf, np.inf, (1,), np.float32)
    action_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)

    def __init__(self, ends: int | None = 5, fail: str = "", report: bool = False) -> None:
        if fail == "init":
            raise RuntimeError("no licence for the simulator")
        self.ends, self.fail, self.report = ends, fail, report

    def _info(self) -> dict:
        """With ``report``: success is ending beyond x = 2 (Minari wants the same keys at reset and every step)."""
        return {"success": bool(self.x[0] > 2)} if self.report else {}

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.t, self.x = 0, np.zeros(1, np.float32)
        return self.x.copy(), self._info()

    def step(self, action):
        if self.fail == "step":
            raise ValueError("physics exploded")
        self.t += 1
        if self.t == HEARTBEAT_STEP and HEARTBEAT in os.environ:
            Path(os.environ[HEARTBEAT]).write_text(str(os.getpid()))
        self.x = self.x + np.asarray(action, np.float32) * (1e200 if self.fail == "overflow" else 1.0)
        return self.x.copy(), -1.0, self.ends is not None and self.t >= self.ends, False, self._info()


for name, kwargs, threshold in (
    ("Plain-v0", {}, None),
    ("Crashing-v0", {}, -3.0),
    ("BrokenInit-v0", {"fail": "init"}, None),
    ("BrokenStep-v0", {"fail": "step"}, None),
    ("Endless-v0", {"ends": None}, None),
    ("Overflowing-v0", {"fail": "overflow"}, None),
    ("Reporting-v0", {"report": True}, -100.0),
):
    if name not in gym.registry:
        gym.register(name, entry_point="user_envs:Plain", kwargs=kwargs, reward_threshold=threshold)
