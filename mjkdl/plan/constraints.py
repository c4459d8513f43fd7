"""Path constraints: an axis of the tool kept along a world direction (a cup kept upright).

`MotionPlanner.plan(goal, constraint=OrientationConstraint(...))` searches with the axis kept
within a loose cone (`SEARCH_CONE`, 45°) of its direction, then *projects* the path onto the
constraint: every `PROJECTION_STEP` (rad) along the path, the TCP's rotation is turned the
least that puts `tool_axis` on `world_axis` (the position and the rotation about the axis
stay), and IK, seeded with the previous projected state, finds the joints. The projected path
is checked for collisions and timed; the timed trajectory is then checked against the
tolerance. This is not OMPL's constrained planning (its Python bindings here cannot hand
states of a constrained space to Python): a path whose projection fails is searched anew
until the timeout.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..control.cartesian import _number, _vector
from ..errors import SpecError


@dataclass(frozen=True)
class OrientationConstraint:
    """Keep the TCP's `tool_axis` (in the TCP frame) within `tolerance` (rad) of
    `world_axis` along the whole motion."""

    tool_axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    world_axis: tuple[float, float, float] = (0.0, 0.0, -1.0)
    tolerance: float = math.radians(5.0)

    def __post_init__(self) -> None:
        for name in ("tool_axis", "world_axis"):
            axis = _vector(getattr(self, name), 3, f"OrientationConstraint.{name}")
            norm = float(np.linalg.norm(axis))
            if norm < 1e-9:
                raise SpecError(f"OrientationConstraint.{name} must be non-zero, got {axis}")
            object.__setattr__(self, name, tuple((axis / norm).tolist()))
        tolerance = _number(self.tolerance, "OrientationConstraint.tolerance", positive=True)
        object.__setattr__(self, "tolerance", tolerance)

    def error(self, rotation: np.ndarray) -> float:
        """The angle (rad) between the tool axis, as `rotation` turns it, and the world axis."""
        axis = rotation @ np.asarray(self.tool_axis)
        return float(math.acos(max(-1.0, min(1.0, float(axis @ np.asarray(self.world_axis))))))

    def project(self, rotation: np.ndarray) -> np.ndarray:
        """`rotation` turned the least that puts the tool axis on the world axis."""
        axis = rotation @ np.asarray(self.tool_axis)
        target = np.asarray(self.world_axis)
        cross = np.cross(axis, target)
        sine, cosine = float(np.linalg.norm(cross)), float(axis @ target)
        if sine < 1e-12:
            if cosine > 0:
                return rotation.copy()
            # Upside down: turn half a turn about any axis normal to it.
            normal = np.cross(axis, [1.0, 0.0, 0.0])
            if np.linalg.norm(normal) < 1e-6:
                normal = np.cross(axis, [0.0, 1.0, 0.0])
            cross, sine, cosine = normal / np.linalg.norm(normal), 0.0, -1.0
        else:
            cross = cross / sine
        k = np.array(
            [[0.0, -cross[2], cross[1]], [cross[2], 0.0, -cross[0]], [-cross[1], cross[0], 0.0]]
        )
        turn = np.eye(3) + sine * k + (1.0 - cosine) * (k @ k)
        return turn @ rotation
