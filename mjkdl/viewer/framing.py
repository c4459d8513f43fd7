"""Where the free camera looks when the window opens: at the robots, all of them in view."""

from __future__ import annotations

import math

import mujoco
import numpy as np

_FILL = 1.25  # the bounding sphere of the robots spans this much of the vertical field of view
# (more than all of it: the box corners are rarely filled, and a tight view reads better)


def robots_box(model: mujoco.MjModel, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray] | None:
    """The axis-aligned box (low corner, high corner) around the geoms of the robots, as of
    the last `mj_forward`; None in a scene without robots.

    A robot is what hangs below a hinge, slide or ball joint, plus the body it is mounted on;
    free-floating objects and fixed furniture are not robots.
    """
    jointed = np.zeros(model.nbody, dtype=bool)
    hinged = model.jnt_type != int(mujoco.mjtJoint.mjJNT_FREE)
    jointed[model.jnt_bodyid[hinged]] = True
    robot = np.zeros(model.nbody, dtype=bool)
    for b in range(1, model.nbody):  # parents come before their children
        parent = model.body_parentid[b]
        robot[b] = jointed[b] or robot[parent]
        if robot[b] and not robot[parent] and parent != 0:
            robot[parent] = True  # the mount (base link)
    geoms = np.flatnonzero(robot[model.geom_bodyid] & (model.geom_rbound > 0))
    if geoms.size == 0:
        return None
    centres = data.geom_xpos[geoms]
    radii = model.geom_rbound[geoms, None]
    return (centres - radii).min(axis=0), (centres + radii).max(axis=0)


def frame(
    cam: mujoco.MjvCamera,
    model: mujoco.MjModel,
    data: mujoco.MjData,
    aspect: float,
    covered_right: float = 0.0,
) -> bool:
    """Point the free camera `cam` at the robots' box from the model's default azimuth and
    elevation, close enough for the box to fill the view; with `covered_right` (a fraction of
    the width, the figure column) the robots are centred in the part left free. `aspect` is
    the view's width over its height. False (camera untouched) when the scene has no robot."""
    box = robots_box(model, data)
    if box is None:
        return False
    low, high = box
    radius = 0.5 * float(np.linalg.norm(high - low))
    half_fovy = math.radians(model.vis.global_.fovy) / 2.0
    distance = radius / (_FILL * math.sin(half_fovy))
    azimuth = math.radians(model.vis.global_.azimuth)
    right = np.array([math.sin(azimuth), -math.cos(azimuth), 0.0])  # the view's right, level
    half_width = distance * math.tan(half_fovy) * aspect  # at the look-at point
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = 0.5 * (low + high) + covered_right * half_width * right
    cam.distance = distance
    cam.azimuth = model.vis.global_.azimuth
    cam.elevation = model.vis.global_.elevation
    return True
