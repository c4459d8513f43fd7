"""A trajectory trace: world-frame line segments drawn in the viewer's user scene."""

from __future__ import annotations

import math
from collections.abc import Sequence

import mujoco
import numpy as np

from ..errors import SpecError

_LINE = int(mujoco.mjtGeom.mjGEOM_LINE)
_ZERO3 = np.zeros(3)
_EYE9 = np.eye(3).ravel()


class Trace:
    """Line segments in the viewer's `user_scn`, bounded by its `maxgeom` less `reserve`.

    The window copies the user scene into its own scene, which has the same `maxgeom` and
    holds the model's geoms and decorations too; a full user scene would overflow it (MuJoCo
    then warns into ``MUJOCO_LOG.TXT`` in the working folder and drops geoms), hence the reserve.

    Segments are kept as an array too (a, b, rgba per row), so offscreen renders (recordings,
    screenshots) and a relaunched window draw the same trace.
    """

    def __init__(self, scene: mujoco.MjvScene, reserve: int, width_px: float = 3.0) -> None:
        self._scene = scene
        self._reserve = int(reserve)
        self._width = float(width_px)
        self._segments = np.empty((self.capacity, 10))
        self._count = 0
        scene.ngeom = 0

    @property
    def count(self) -> int:
        """Segments drawn since the last `clear()`."""
        return self._count

    @property
    def capacity(self) -> int:
        """Most segments drawn at once."""
        return max(0, self._scene.maxgeom - self._reserve)

    def clear(self) -> None:
        """Remove every segment."""
        self._count = 0
        self._scene.ngeom = 0

    def add(self, a: Sequence[float], b: Sequence[float], rgba: Sequence[float]) -> bool:
        """Draw the segment from `a` to `b` (world frame, metres) in colour `rgba`.

        Returns False, drawing nothing, once the user scene is full.
        """
        n = self._count
        if n >= self.capacity:
            return False
        row = self._segments[n]
        try:
            row[0:3] = a
            row[3:6] = b
            row[6:10] = rgba
        except (TypeError, ValueError):
            raise SpecError(
                f"add_trace_segment(a, b, rgba) needs 3, 3 and 4 numbers, got {a!r}, {b!r}, "
                f"{rgba!r}"
            ) from None
        if not math.isfinite(row.sum()):
            raise SpecError(f"add_trace_segment: values must be finite, got {a!r}, {b!r}, {rgba!r}")
        _line(self._scene.geoms[n], row, self._width)
        self._count = n + 1
        self._scene.ngeom = n + 1
        return True

    def draw_into(self, scene: mujoco.MjvScene) -> None:
        """Append the segments to another scene (an offscreen renderer's), as far as it fits."""
        start = scene.ngeom
        n = min(self._count, scene.maxgeom - start)
        for i in range(n):
            _line(scene.geoms[start + i], self._segments[i], self._width)
        scene.ngeom = start + n

    def rebind(self, scene: mujoco.MjvScene, reserve: int) -> None:
        """Move the trace to a new user scene (a relaunched window), redrawing what fits."""
        self._scene, self._reserve = scene, int(reserve)
        if self.capacity != len(self._segments):
            self._segments = np.resize(self._segments, (self.capacity, 10))
        self._count = min(self._count, self.capacity)
        scene.ngeom = 0
        self.draw_into(scene)


def _line(geom: mujoco.MjvGeom, row: np.ndarray, width: float) -> None:
    """A LINE geom (width in pixels) for one segment row: a (3), b (3), rgba (4)."""
    mujoco.mjv_initGeom(geom, _LINE, _ZERO3, _ZERO3, _EYE9, row[6:10].astype(np.float32))
    mujoco.mjv_connector(geom, _LINE, width, row[0:3], row[3:6])
