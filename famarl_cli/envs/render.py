"""A tiny rasteriser for environment frames: filled rectangles and discs in world coordinates.

Frames need no plotting library; numpy masks over a pixel grid are fast enough for GIFs and tests.
"""

from __future__ import annotations

import numpy as np


class Canvas:
    """An RGB image of the world rectangle ``[0, width] x [0, height]``, ``y`` pointing up."""

    def __init__(self, width: float, height: float, pixels: int = 256, background=(255, 255, 255)) -> None:
        self.scale = pixels / max(width, height)
        cols, rows = max(1, round(width * self.scale)), max(1, round(height * self.scale))
        self.image = np.empty((rows, cols, 3), dtype=np.uint8)
        self.image[:] = background
        # World coordinates of every pixel centre; row 0 is the top of the world.
        self._x = (np.arange(cols) + 0.5) / self.scale
        self._y = height - (np.arange(rows) + 0.5) / self.scale

    def rect(self, x0: float, y0: float, x1: float, y1: float, color) -> None:
        cols = (self._x >= min(x0, x1)) & (self._x <= max(x0, x1))
        rows = (self._y >= min(y0, y1)) & (self._y <= max(y0, y1))
        self.image[np.ix_(rows, cols)] = color

    def disc(self, x: float, y: float, radius: float, color) -> None:
        radius = max(radius, 0.5 / self.scale)
        inside = (self._y[:, None] - y) ** 2 + (self._x[None, :] - x) ** 2 <= radius**2
        self.image[inside] = color
