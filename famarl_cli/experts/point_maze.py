"""PointMaze's expert (gymnasium-robotics): a planner over the maze's cells gives waypoints and a PD controller
drives the ball from one to the next, as Minari's own PointMaze datasets were collected.

``famarl demos --env PointMaze_UMaze-v3 --env-kwargs '{"continuing_task": false}' --expert
famarl_cli.experts.point_maze:PointMazeExpert``. The planner is a breadth-first search from the ball's cell to the
goal's over the free cells; straight runs of cells are merged, so each waypoint is a turn (or the goal) and each
*leg*, from one waypoint to the next, is a straight line through a corridor: a ground-truth phase. A leg's factors
are its direction (dx, dy, in cells, a unit step) and its length (cells).
"""

from __future__ import annotations

from collections import deque

import gymnasium as gym
import numpy as np

FACTOR_NAMES = ("dx", "dy", "cells")
P_GAIN, D_GAIN = 10.0, 1.0
"""Minari's PointMaze controller gains: action = P_GAIN * (waypoint - position) - D_GAIN * velocity."""
REACHED = 0.2
"""A waypoint counts as reached within this distance (m; a cell is 1 m), and the next leg begins."""


class PointMazeExpert:
    factor_names = FACTOR_NAMES

    def __init__(self, env: gym.Env) -> None:
        self.maze = env.unwrapped.maze
        self.free = np.array(self.maze.maze_map) != 1

    def reset(self, observation: dict) -> None:
        goal = np.asarray(observation["desired_goal"], dtype=np.float64)
        cells = self._path(self._cell(observation["achieved_goal"]), self._cell(goal))
        # The goal's own cell leg ends at the goal itself, not at its cell's centre.
        self.waypoints: list[np.ndarray] = [goal]
        self._factors: list[tuple[float, float, float]] = [(0.0, 0.0, 0.0)]
        if len(cells) > 1:
            self.waypoints, self._factors, run = [], [], 0
            for i in range(1, len(cells)):
                step = np.subtract(cells[i], cells[i - 1])
                run += 1
                last = i + 1 == len(cells)
                if last or tuple(np.subtract(cells[i + 1], cells[i])) != tuple(step):
                    # Rows grow downwards and y upwards: a step of +1 row is -1 in y.
                    self._factors.append((float(step[1]), float(-step[0]), float(run)))
                    centre = np.asarray(self.maze.cell_rowcol_to_xy(np.array(cells[i])), dtype=np.float64)
                    self.waypoints.append(goal if last else centre)
                    run = 0
        self.leg, self.step = 0, 0
        self.phase_starts: list[int] = []

    def act(self, observation: dict) -> np.ndarray:
        position, velocity = observation["observation"][:2], observation["observation"][2:4]
        while self.leg < len(self.waypoints) - 1 and np.linalg.norm(self.waypoints[self.leg] - position) < REACHED:
            self.leg += 1
        if len(self.phase_starts) <= self.leg:
            self.phase_starts.append(self.step)
        self.step += 1
        action = P_GAIN * (self.waypoints[self.leg] - position) - D_GAIN * velocity
        return np.clip(action, -1.0, 1.0).astype(np.float32)

    @property
    def phase_factors(self) -> np.ndarray:
        return np.array(self._factors[: len(self.phase_starts)], dtype=np.float64).reshape(-1, len(FACTOR_NAMES))

    def _cell(self, xy: np.ndarray) -> tuple[int, int]:
        return tuple(int(v) for v in self.maze.cell_xy_to_rowcol(np.asarray(xy)))

    def _path(self, start: tuple[int, int], goal: tuple[int, int]) -> list[tuple[int, int]]:
        """Cells from ``start`` to ``goal`` (both included) on a shortest path through free cells."""
        previous = {start: start}
        queue = deque([start])
        while queue:
            cell = queue.popleft()
            if cell == goal:
                break
            for dr, dc in ((0, 1), (1, 0), (0, -1), (-1, 0)):
                nxt = (cell[0] + dr, cell[1] + dc)
                if self.free[nxt] and nxt not in previous:
                    previous[nxt] = cell
                    queue.append(nxt)
        path = [goal]
        while path[-1] != start:
            path.append(previous[path[-1]])
        return path[::-1]
