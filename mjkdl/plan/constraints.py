"""Path constraints: an axis of the tool kept along a world direction (a cup kept upright).

`MotionPlanner.plan(goal, constraint=OrientationConstraint(...))` searches with the axis kept
within a loose cone (`SEARCH_CONE`, 45°) of its direction, then *projects* the path onto the
constraint: every `PROJECTION_STEP` (rad) along the path, the state is moved the least in
joint space that puts `tool_axis` on `world_axis` (`project_joints`: damped Gauss-Newton on
the axis alone, the TCP's position free; IK to a fixed TCP position planned 75 of 90 queries
where this plans 89). The projected path is checked for collisions and timed; the timed
trajectory is then checked against the tolerance. This is not OMPL's constrained planning
(its Python bindings here cannot hand states of a constrained space to Python): a path whose
projection fails is searched anew until the timeout.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..control.cartesian import _number, _vector
from ..errors import SpecError

# The joint-space projection (`OrientationConstraint.project_joints`): converged when the
# tool axis is this close (its chord, ~rad) to the world axis; damping of its least squares.
PROJECTION_TOLERANCE = 1e-5
PROJECTION_ITERATIONS = 30
PROJECTION_DAMPING = 1e-6


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


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

    def project_joints(
        self,
        q: np.ndarray,
        fk: Callable[[np.ndarray], Any],
        jacobian: Callable[[np.ndarray], np.ndarray],
        hold: int | None = None,
        sphere: tuple[np.ndarray, float] | None = None,
    ) -> np.ndarray | None:
        """Joint positions near `q` whose tool axis is on the world axis (within
        `PROJECTION_TOLERANCE`): damped Gauss-Newton on the axis alone, the TCP's position
        left free (a 2-D constraint, not a 6-D pose); None when it does not converge.
        `fk(q)` gives the TCP pose, `jacobian(q)` its 6×n world-aligned Jacobian; joint
        `hold` (an index), if given, is not moved; `sphere` (centre, radius in m), if given,
        puts the TCP that far from the centre too (one more row)."""
        tool, world = np.asarray(self.tool_axis), np.asarray(self.world_axis)
        q = np.array(q, dtype=float)
        rows = 3 if sphere is None else 4
        for _ in range(PROJECTION_ITERATIONS):
            pose = fk(q)
            axis = pose.rotation @ tool
            error = axis - world
            if sphere is not None:
                offset = pose.translation - sphere[0]
                distance = float(np.linalg.norm(offset))
                if distance < 1e-9:
                    return None
                error = np.append(error, distance - sphere[1])
            if float(np.linalg.norm(error)) <= PROJECTION_TOLERANCE:
                return q
            jac = jacobian(q)
            # d(axis)/dq = omega × axis, omega the angular rows of the Jacobian.
            j = -_skew(axis) @ jac[3:]
            if sphere is not None:
                j = np.vstack([j, (offset / distance) @ jac[:3]])
            if hold is not None:
                j[:, hold] = 0.0
            q -= j.T @ np.linalg.solve(j @ j.T + PROJECTION_DAMPING * np.eye(rows), error)
        return None
