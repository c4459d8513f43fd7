"""`python -m mjkdl.hw.franka_sim --viewer`: the simulated arm in MuJoCo's window while a client
moves it, under a virtual display (Xvfb; skipped without one unless MJKDL_REQUIRE_DISPLAY=1, as
tests/test_viewer.py does), and a clear error where there is no display."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from conftest import ROOT, _franka_host, franka_sim, needs_extra
from test_hw_franka_sim_server import client
from test_viewer import display, tool  # noqa: F401  (the display fixture)

from mjkdl.hw.joint_impedance import START_Q

needs_extra("franka")


@pytest.mark.usefixtures("display")
def test_the_viewer_shows_the_arm_a_client_moves_and_the_server_exits_cleanly():
    xdotool = tool("xdotool")
    with franka_sim("--lockstep", "--command-timeout", "10", "--viewer") as sim:
        q = client(
            sim.host,
            """
            q = list(robot.read_once().q)
            q[0] += 0.3
            move_to(q, 1.0)
            print(list(robot.read_once().q))
            """,
        )
        np.testing.assert_allclose(eval(q)[0], START_Q[0] + 0.3, atol=1e-3)
        windows = subprocess.run(
            [xdotool, "search", "--name", "^MuJoCo"], capture_output=True, text=True, timeout=10
        )
        assert windows.stdout.split(), "no MuJoCo window on the display"
        sim.proc.terminate()  # what Ctrl+C or a service manager does
        assert sim.proc.wait(timeout=30) == 0, sim.log[-5:]  # the window closed, no crash
    assert not any("Traceback" in line for line in sim.log), sim.log


def test_no_display_is_a_clear_error_before_the_ports_are_taken():
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    done = subprocess.run(
        [sys.executable, "-m", "mjkdl.hw.franka_sim", "--host", _franka_host(), "--viewer"],
        capture_output=True,
        text=True,
        timeout=60,
        env=env,
        cwd=ROOT,
    )
    assert done.returncode == 2, done.stderr
    assert "franka_sim: --viewer: " in done.stderr and "DISPLAY is not set" in done.stderr
    assert "leave --viewer out" in done.stderr
