"""The simulated Franka pushed, as pylibfranka sees it: the robot's Cartesian impedance (the
deflection is force / stiffness, the stiffness libfranka's set_cartesian_impedance sets) and the
external wrench and torques it reports (their signs are libfranka's). The server runs in this
process (lockstep, empty scene) so the test can push its hand; the client in its own."""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator

import numpy as np
import pytest
from conftest import _franka_host, needs_extra
from test_hw_franka_sim_arm import push_at_ee
from test_hw_franka_sim_server import client

from mjkdl.hw.franka_sim import FrankaSimServer

needs_extra("franka")

PUSH = np.array([8.0, -5.0, -10.0])  # N on the hand at the EE point, base frame

# A pylibfranka program: Cartesian impedance `K` (translation, N/m), the pose held for 1.5 s
# in ControllerMode.CartesianImpedance; prints the hold pose and the last state.
HOLD = """
import json
robot.set_collision_behavior([100.0] * 7, [100.0] * 7, [100.0] * 6, [100.0] * 6)
robot.set_cartesian_impedance([K, K, K, 300.0, 300.0, 300.0])
ctrl = robot.start_cartesian_pose_control(plf.ControllerMode.CartesianImpedance)
state, _ = ctrl.readOnce()
hold = list(state.O_T_EE_d)
for i in range(1500):
    state, _ = ctrl.readOnce()
    cmd = plf.CartesianPose(hold)
    cmd.motion_finished = i == 1499
    ctrl.writeOnce(cmd)
jac = robot.load_model().zero_jacobian(state)
print(json.dumps(dict(hold=hold, pose=list(state.O_T_EE), wrench=list(state.O_F_ext_hat_K),
    tau=list(state.tau_ext_hat_filtered), jac=list(jac))))
"""


@pytest.fixture(scope="module")
def pushed() -> Iterator[FrankaSimServer]:
    """A lockstep server whose hand is pushed with `PUSH` from the start."""
    server = FrankaSimServer(_franka_host(), lockstep=True, command_timeout=10.0, scene="empty")
    push_at_ee(server.arm, PUSH)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield server
    server.stop()
    thread.join(timeout=30)
    assert not thread.is_alive()


def _hold(server: FrankaSimServer, stiffness: float) -> dict[str, np.ndarray]:
    out = client(server.host, HOLD.replace("K, K, K", ", ".join([str(stiffness)] * 3)))
    return {k: np.array(v) for k, v in json.loads(out).items()}


@pytest.mark.parametrize("stiffness", [3000.0, 1000.0])
def test_the_hand_gives_way_by_force_over_the_cartesian_stiffness(pushed, stiffness):
    got = _hold(pushed, stiffness)
    hold = got["hold"].reshape(4, 4, order="F")
    pose = got["pose"].reshape(4, 4, order="F")
    # the push moves the hand along it by F / K (3.3 mm at the robot's default 3000 N/m)
    np.testing.assert_allclose(pose[:3, 3] - hold[:3, 3], PUSH / stiffness, rtol=0.03, atol=5e-5)
    # the rotational spring (300 N·m/rad) meets no moment: the hand keeps its orientation
    assert np.linalg.norm(pose[:3, :3] - hold[:3, :3]) < 1e-3


def test_the_reported_wrench_is_the_arms_force_on_its_pusher(pushed):
    """libfranka's robot_state.h: "forces applied by the robot to the environment are
    positive, while forces applied by the environment on the robot are negative"."""
    got = _hold(pushed, 3000.0)
    np.testing.assert_allclose(got["wrench"][:3], -PUSH, atol=0.2)  # N, 2 % of the push
    np.testing.assert_allclose(got["wrench"][3:], 0.0, atol=0.05)  # N·m
    # the joint torques are the Jacobian's transpose of it (libfranka's own Jacobian)
    jac = got["jac"].reshape(6, 7, order="F")
    np.testing.assert_allclose(got["tau"], jac.T @ got["wrench"], atol=0.05)
    np.testing.assert_allclose(got["tau"], -jac.T @ np.r_[PUSH, 0.0, 0.0, 0.0], atol=0.1)
