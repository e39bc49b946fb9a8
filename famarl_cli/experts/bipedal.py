"""BipedalWalker's expert: gymnasium's own heuristic controller, with its state machine as the ground-truth phases.

``famarl demos --env BipedalWalker-v3 --expert famarl_cli.experts.bipedal:BipedalWalkerExpert``. The controller
(``gymnasium.envs.box2d.bipedal_walker.BipedalWalkerHeuristics``) walks by cycling three states per leg: stand on
one leg while the other swings forward, put the other leg down, push off; then the legs swap. A phase is one
(state, moving leg) pair, so a stride holds six. The heuristic often falls (it reached the end in 3 of 20
episodes of seeds 0-19): ``famarl demos --min-return 250`` keeps only the walks that reach the end.
"""

from __future__ import annotations

import numpy as np

FACTOR_NAMES = ("state", "moving_leg")
"""A phase's factors: the controller's state (1 stay on one leg, 2 put the other down, 3 push off) and which leg
(0 or 1) is the moving one."""


class BipedalWalkerExpert:
    factor_names = FACTOR_NAMES

    def reset(self, observation: np.ndarray) -> None:
        from gymnasium.envs.box2d.bipedal_walker import BipedalWalkerHeuristics

        self.controller = BipedalWalkerHeuristics()
        # The class keeps its last action in a class attribute, shared by every instance until the first step
        # replaces it: a fresh array keeps episodes independent.
        self.controller.a = np.zeros(4)
        self.step = 0
        self.phase_starts: list[int] = []
        self._factors: list[tuple[int, int]] = []

    def act(self, observation: np.ndarray) -> np.ndarray:
        action = np.array(self.controller.step_heuristic(observation), dtype=np.float32)
        phase = (int(self.controller.state), int(self.controller.moving_leg))
        if not self._factors or self._factors[-1] != phase:
            self.phase_starts.append(self.step)
            self._factors.append(phase)
        self.step += 1
        return action

    @property
    def phase_factors(self) -> np.ndarray:
        return np.array(self._factors, dtype=np.float64).reshape(-1, len(FACTOR_NAMES))
