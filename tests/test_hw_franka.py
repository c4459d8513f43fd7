"""FrankaArm: the Robot ports of an arm at an address, driven through the vendor clients
against `python -m mjkdl.hw.franka_sim` (lockstep) in another process."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import time
from collections.abc import Iterator

import mujoco
import numpy as np
import pytest
from conftest import needs_extra

import mjkdl as mjk
from mjkdl.hw.connection import ArmConnection
from mjkdl.hw.faults import WatchdogWarning
from mjkdl.hw.franka import FrankaArm

HOME = np.array([0.0, -0.785398, 0.0, -2.356194, 0.0, 1.570796, 0.785398])  # the server's


@pytest.fixture(scope="class", params=["pylibfranka", "panda-py"])
def arm(franka_server: str, request: pytest.FixtureRequest) -> Iterator[FrankaArm]:
    """The handle through each client: pylibfranka (libfranka 0.21, protocol 10) and panda-py
    (libfranka 0.9.2, protocol 5, the Panda's default)."""
    needs_extra("franka")
    with FrankaArm(franka_server, client=request.param) as arm:
        yield arm


class TestOneConnection:
    """One connection for these tests (the server takes one client at a time)."""

    def test_the_measured_ports_are_the_arm_s_state(self, arm: FrankaArm) -> None:
        arm.update()
        state = arm.link.connection.state()
        np.testing.assert_allclose(arm.jnt_pos_msr, state.q, atol=1e-3)
        np.testing.assert_allclose(arm.jnt_vel_msr, state.dq, atol=1e-2)
        # jnt_trq_msr is tau_J: the arm holding itself against gravity (joint 4 carries most).
        np.testing.assert_allclose(arm.jnt_trq_msr, state.tau_J, atol=0.5)
        assert abs(arm.jnt_trq_msr[3]) > 5.0
        assert arm.ext_trq_msr.shape == (7,) and arm.ext_wrench_msr.shape == (6,)

    def test_a_position_command_moves_the_arm_there_and_kinematics_follow(
        self, arm: FrankaArm
    ) -> None:
        arm.ctrl_mode = mjk.CtrlMode.POSITION
        arm.update()
        target = arm.jnt_pos_msr + np.array([0.2, -0.1, 0.15, 0.1, -0.2, 0.1, 0.3])
        arm.jnt_pos_cmd = target
        for _ in range(800):  # 0.8 s of the arm's clock
            arm.step()
        arm.update()
        np.testing.assert_allclose(arm.jnt_pos_msr, target, atol=5e-3)
        # The twin's kinematics at the measured joints: the hand's frame as MuJoCo puts it.
        scene = arm.scene
        mujoco.mj_forward(scene.model, scene.data)
        hand = scene.body_frame("hand")
        np.testing.assert_allclose(arm.fk_frame().translation, hand.translation, atol=1e-9)
        assert arm.jacobian().shape == (6, 7)
        np.testing.assert_allclose(arm.gravity_torques(), arm.jnt_trq_msr, atol=2.0)

    def test_velocity_then_torque_mode(self, arm: FrankaArm) -> None:
        arm.ctrl_mode = mjk.CtrlMode.VELOCITY
        arm.update()
        q0 = arm.jnt_pos_msr.copy()
        arm.jnt_vel_cmd = np.array([0.2, 0, 0, 0, 0, 0, -0.2])
        for _ in range(500):
            arm.step()
        arm.update()
        moved = arm.jnt_pos_msr - q0
        # 0.5 s at 0.2 rad/s less the jerk-limited start (tens of ms): about 0.1 rad.
        assert 0.08 < moved[0] < 0.101 and -0.101 < moved[6] < -0.08
        assert np.abs(moved[1:6]).max() < 5e-3
        # TORQUE with gravity compensation: the arm compensates gravity itself, zero holds.
        arm.ctrl_mode = mjk.CtrlMode.TORQUE
        arm.gravity_compensation = True
        arm.jnt_trq_cmd = np.zeros(7)
        for _ in range(300):
            arm.step()
        arm.update()
        q1 = arm.jnt_pos_msr.copy()
        for _ in range(300):
            arm.step()
        arm.update()
        assert np.abs(arm.jnt_pos_msr - q1).max() < 0.02
        arm.gravity_compensation = False

    def test_bad_commands_are_refused_before_they_leave(self, arm: FrankaArm) -> None:
        arm.ctrl_mode = mjk.CtrlMode.POSITION
        with pytest.raises(mjk.SpecError, match="jnt_pos_cmd"):
            arm.jnt_pos_cmd = np.full(6, 0.1)
        with pytest.raises(mjk.SpecError, match="jnt_vel_cmd"):
            arm.jnt_vel_cmd = np.array([np.nan] * 7)
        with pytest.raises(AttributeError, match="FrankaArm has no writable attribute 'q'"):
            arm.q = np.zeros(7)


def test_the_watchdog_brings_the_arm_to_rest_when_the_loop_stops(
    franka_server: str, capsys: pytest.CaptureFixture[str]
) -> None:
    ArmConnection._announced = False  # as in a fresh process
    with FrankaArm(franka_server, model="fr3", client="pylibfranka", watchdog=0.1) as arm:
        # The first connection of a process says which limits apply.
        out = capsys.readouterr().out
        assert out.count("rate-limited to the fr3 limits") == 1
        assert "acceleration [9.999" in out and "jerk [5000" in out
        arm.ctrl_mode = mjk.CtrlMode.VELOCITY
        arm.jnt_vel_cmd = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.5])
        for _ in range(300):
            arm.step()
        state = arm.link.connection.state()
        assert state.moving and state.dq[6] > 0.4
        time.sleep(1.0)  # the user's loop stalls; the watchdog finishes the motion
        state = arm.link.connection.state()
        assert not state.moving and np.abs(state.dq).max() < 0.01
        with pytest.warns(WatchdogWarning, match=r"no command came for 0\.1\d* s"):
            arm.link.connection.check()


def test_ctrl_c_stops_the_arm_and_closes_the_connection(franka_server: str) -> None:
    script = textwrap.dedent(
        f"""
        import numpy as np, mjkdl as mjk
        from mjkdl.hw.franka import FrankaArm
        arm = FrankaArm({franka_server!r}, client="pylibfranka", watchdog=5.0)
        arm.ctrl_mode = mjk.CtrlMode.VELOCITY
        arm.jnt_vel_cmd = np.array([0, 0, 0, 0, 0, 0, -0.4])
        for _ in range(200):
            arm.step()
        print("moving", flush=True)
        while True:
            arm.step()
        """
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        assert proc.stdout is not None
        assert "rate-limited to the panda limits" in proc.stdout.readline()
        assert proc.stdout.readline().strip() == "moving"
        proc.send_signal(subprocess.signal.SIGINT)  # type: ignore[attr-defined]
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert "KeyboardInterrupt" in err
    # The connection is closed (a new client is accepted) and the arm is at rest.
    with FrankaArm(franka_server, client="pylibfranka") as after:
        after.update()
        assert np.abs(after.jnt_vel_msr).max() < 0.01
