"""FrankaArm: the Robot ports of an arm at an address, driven through the vendor clients
against `python -m mjkdl.hw.franka_sim` (lockstep) in another process."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import time
from collections.abc import Iterator
from pathlib import Path

import mujoco
import numpy as np
import pytest
from conftest import needs_extra, sigint_as_from_a_terminal

import mjkdl as mjk
from mjkdl.hw.connection import ArmConnection
from mjkdl.hw.faults import ArmConnectionError, WatchdogWarning
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
        arm.update()
        before = arm.jnt_pos_msr[6]
        time.sleep(1.0)  # the user's loop stalls; the watchdog finishes the motion
        state = arm.link.connection.state()
        assert not state.moving and np.abs(state.dq).max() < 0.01
        # The first call after the stall reports it, and the ports read the arm at rest where
        # the watchdog stopped it (not the state before the stall).
        with pytest.warns(WatchdogWarning, match=r"no command came for 0\.1\d* s"):
            arm.update()
        assert np.abs(arm.jnt_vel_msr).max() < 0.01
        np.testing.assert_allclose(arm.jnt_pos_msr, arm.link.connection.state().q, atol=1e-12)
        # it ran on at 0.5 rad/s for 0.1 s of wall clock (fewer ticks of a loaded lockstep arm)
        assert arm.jnt_pos_msr[6] - before > 0.01


def test_the_stall_is_reported_at_the_first_call_while_the_arm_still_brakes(
    franka_server: str,
) -> None:
    with FrankaArm(franka_server, client="pylibfranka", watchdog=0.1) as arm:
        arm.ctrl_mode = mjk.CtrlMode.VELOCITY
        arm.jnt_vel_cmd = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0])
        for _ in range(400):
            arm.step()
        conn = arm.link.connection
        deadline = time.monotonic() + 5.0
        while conn.state().dq[6] > 0.9 and time.monotonic() < deadline:  # the loop stalls
            time.sleep(0.001)
        with pytest.warns(WatchdogWarning, match="is brought to rest"):
            arm.update()  # the first call after the watchdog fired, not the next step()
        assert arm.jnt_vel_msr[6] < 0.9  # the ports read the braking arm


def test_a_second_client_is_refused_by_name(franka_server: str) -> None:
    with FrankaArm(franka_server, client="pylibfranka") as arm:
        arm.update()
        with pytest.raises(ArmConnectionError) as caught:
            ArmConnection(franka_server, "panda", client="pylibfranka")
    text = str(caught.value)
    assert "libfranka: Connection to FCI refused" in text, text
    assert "the robot takes one client at a time" in text, text
    with FrankaArm(franka_server, client="pylibfranka") as again:  # served once the first left
        again.update()
        assert again.jnt_pos_msr.shape == (7,)


def test_the_flange_and_o_t_ee_by_name_are_libfranka_s(franka_server: str) -> None:
    with FrankaArm(franka_server, client="pylibfranka") as arm:
        arm.update()
        q = arm.jnt_pos_msr.copy()
        hand, flange, ee = arm.fk_frame(), arm.frame("flange"), arm.frame("O_T_EE")
        with pytest.raises(mjk.SpecError, match=r"frame: no frame 'tcp'; FrankaArm names"):
            arm.frame("tcp")
        with pytest.raises(mjk.SpecError, match="frame: q"):
            arm.frame("flange", np.zeros(6))
    assert np.linalg.norm(ee.translation - hand.translation) == pytest.approx(0.1034, abs=1e-12)
    assert np.allclose(flange.translation, hand.translation, atol=1e-12)
    # libfranka's own O_T_EE and F_T_EE at the same joints (the arm at rest)
    out = subprocess.run(
        [
            sys.executable,
            "-c",
            "import json, pylibfranka as plf\n"
            f"s = plf.Robot({franka_server!r}, plf.RealtimeConfig.kIgnore).read_once()\n"
            "print(json.dumps([list(s.q), list(s.O_T_EE), list(s.F_T_EE)]))",
        ],
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    ).stdout
    q_lf, o_t_ee, f_t_ee = (np.array(v) for v in json.loads(out.splitlines()[-1]))
    np.testing.assert_allclose(q_lf, q, atol=1e-9)
    o_t_ee, f_t_ee = o_t_ee.reshape(4, 4, order="F"), f_t_ee.reshape(4, 4, order="F")
    # (the server's pose comes from its own model and tick: equal to 2e-5)
    np.testing.assert_allclose(ee.homogeneous, o_t_ee, atol=2e-5)
    np.testing.assert_allclose(flange.homogeneous, o_t_ee @ np.linalg.inv(f_t_ee), atol=2e-5)


@pytest.mark.parametrize(
    ("code", "expected"),
    [
        ("import pylibfranka as f; f.Robot(IP)", "RealtimeException"),
        ("import pylibfranka as f; f.Robot(IP, f.RealtimeConfig.kIgnore); print('ok')", "ok"),
        (
            "import franky as f; f.Robot(IP, realtime_config=f.RealtimeConfig.Ignore); print('ok')",
            "ok",
        ),
    ],
)
def test_the_documented_realtime_setting_connects_without_preempt_rt(
    franka_server: str, code: str, expected: str
) -> None:
    """The vendors' examples enforce real-time scheduling; on a kernel without PREEMPT_RT (this
    machine's) they stop with RealtimeException, with the setting docs/hardware.md names they
    connect."""
    if expected != "ok" and os.path.exists("/sys/kernel/realtime"):
        pytest.skip("a PREEMPT_RT kernel")
    done = subprocess.run(
        [sys.executable, "-c", code.replace("IP", repr(franka_server))],
        capture_output=True,
        text=True,
        timeout=60,
    )
    out = done.stdout + done.stderr
    if expected == "ok":
        assert out.strip().splitlines()[-1] == "ok", out
    else:
        assert "RealtimeException: libfranka: Running kernel does not have realtime" in out, out
    docs = (Path(__file__).resolve().parents[1] / "docs" / "hardware.md").read_text()
    assert "RealtimeConfig.kIgnore" in docs and "realtime_config=RealtimeConfig.Ignore" in docs


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
        [sys.executable, "-c", script],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=sigint_as_from_a_terminal,
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
