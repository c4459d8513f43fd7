"""The simulated Franka driven by the real client libraries, each in its own process: the
unmodified pylibfranka examples and short pylibfranka programs, against a server run in
lockstep (deterministic: every state waits for its command, whatever the machine's load)."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from collections.abc import Iterator

import numpy as np
import pytest
from conftest import FRANKA_EXAMPLES, franka_sim, run_franka_example

from mjkdl.hw.franka_sim.scene import START_Q

pytest.importorskip("pylibfranka")

PYLIBFRANKA = FRANKA_EXAMPLES / "pylibfranka"


@pytest.fixture(scope="module")
def server() -> Iterator[str]:
    with franka_sim("--lockstep") as (host, _proc):
        yield host


def client(host: str, body: str, timeout: float = 120) -> str:
    """A pylibfranka program in its own process: `robot` connected to `host`; its stdout."""
    code = "import numpy as np, pylibfranka as plf\n"
    code += f"robot = plf.Robot({host!r}, plf.RealtimeConfig.kIgnore)\n"
    code += textwrap.dedent(body)
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout
    )
    assert done.returncode == 0, done.stdout + done.stderr
    return done.stdout


def state_q(host: str) -> np.ndarray:
    out = client(host, "print(list(robot.read_once().q))")
    return np.array(eval(out))


def test_print_robot_state_example_reads_the_start_pose(server):
    out = run_franka_example(PYLIBFRANKA / "print_robot_state.py", "--ip", server)
    assert "Robot Mode: Idle" in out, out
    # the example rounds to 4 decimals
    assert f"{START_Q[3]:.4f}" in out and "Position: [0.3069, 0.0, 0.4869]" in out, out


def test_joint_position_example_moves_and_returns(server):
    q0 = state_q(server)
    out = run_franka_example(PYLIBFRANKA / "joint_position_example.py", "--ip", server, stdin="\n")
    assert "Finished motion" in out and "Error" not in out, out
    # its cosine profile ends where it began, and the arm with it
    np.testing.assert_allclose(state_q(server), q0, atol=1e-3)


def test_move_gripper_example_grasps_the_cube(server):
    out = run_franka_example(PYLIBFRANKA / "move_gripper.py", "--ip", server, "--width", "0.04")
    assert "Gripper width: 0.08" in out, out
    assert "Grasped object, will release it now." in out, out
