"""Helper of make_pictures.py, run on a virtual display: the viewer with four figures, grabbed
into the PNG named on the command line."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "examples"), str(ROOT / "tests")]
from common import HOME, create_arm, tutorial_spec  # noqa: E402
from screen import grab_window  # noqa: E402

import mjkdl as mjk  # noqa: E402

with mjk.Env.build(tutorial_spec()) as env:
    robot = create_arm(env)
    env.on_reset = lambda ctx: robot.set_joint_pos(HOME, call_forward=False)
    env.reset()
    viewer = mjk.SimulateViewer.open(robot, "mjkdl viewer")
    viewer.add_signal("TCP height [m]", lambda: [robot.fk_frame().translation[2]])
    viewer.add_signal(
        "TCP speed [m/s]", lambda: [np.linalg.norm(robot.jacobian()[:3] @ robot.jnt_vel_msr)]
    )
    sway = np.array([0.6, 0.0, 0.0, 0.4, 0.0, 0.5, 0.0])
    while env.time() < 3.0:
        robot.update()
        robot.jnt_pos_cmd = HOME + sway * np.sin(np.pi * env.time())
        viewer.step()
    time.sleep(2.0)
    cv2.imwrite(sys.argv[1], grab_window())
    viewer.close()
