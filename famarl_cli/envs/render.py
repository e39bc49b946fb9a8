"""A tiny rasteriser for environment frames: rectangles, discs, convex polygons and thick segments in world
coordinates.

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

    def polygon(self, vertices, color) -> None:
        """A convex polygon, vertices in either winding order."""
        points = np.asarray(vertices, dtype=float)
        inside = np.ones(self.image.shape[:2], dtype=bool)
        orientation = np.sign(_cross(points[1] - points[0], points[2] - points[1]))
        for a, b in zip(points, np.roll(points, -1, axis=0), strict=True):
            side = (b[0] - a[0]) * (self._y[:, None] - a[1]) - (b[1] - a[1]) * (self._x[None, :] - a[0])
            inside &= orientation * side >= 0
        self.image[inside] = color

    def segment(self, a, b, radius: float, color) -> None:
        """A thick line: every pixel within ``radius`` of the segment from ``a`` to ``b``."""
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        along = b - a
        px, py = self._x[None, :] - a[0], self._y[:, None] - a[1]
        t = np.clip((px * along[0] + py * along[1]) / max(float(along @ along), 1e-12), 0.0, 1.0)
        radius = max(radius, 0.5 / self.scale)
        self.image[(px - t * along[0]) ** 2 + (py - t * along[1]) ** 2 <= radius**2] = color


def _cross(u: np.ndarray, v: np.ndarray) -> float:
    return float(u[0] * v[1] - u[1] * v[0])
