"""The simulated arm's reflexes and its URDF, in this process (no network)."""

from __future__ import annotations

from collections.abc import Iterator

import mujoco
import numpy as np
import pytest

from mjkdl.hw.franka_sim import wire
from mjkdl.hw.franka_sim.arm import LOST_CYCLES_LIMIT, SimulatedArm
from mjkdl.hw.franka_sim.limits import FR3, PANDA
from mjkdl.hw.franka_sim.scene import franka_scene
from mjkdl.hw.joint_impedance import START_Q


@pytest.fixture(scope="module")
def fr3() -> Iterator[SimulatedArm]:
    arm = SimulatedArm(franka_scene(), FR3)
    yield arm
    arm.env.close()


def _command(arm: SimulatedArm) -> np.void:
    cmd = np.zeros(1, wire.PROTOCOL_10.command)[0]
    cmd["q_c"] = arm.q_d
    return cmd


def _errors(arm: SimulatedArm) -> list[str]:
    return [n for n, on in zip(wire.ERRORS, arm.last_motion_errors, strict=True) if on]


def test_fr3_limits_are_reported_and_enforced(fr3):
    # the URDF libfranka builds its model and rate limits from carries FR3's joint 6 range
    assert 'lower="0.5445" upper="4.5169"' in fr3.urdf
    assert fr3.urdf.count("<position_based_velocity_limits") == 7
    fr3.recover()
    assert (
        fr3.start_motion(wire.ControllerMode.JOINT_IMPEDANCE, wire.MotionGenerator.JOINT_POSITION)
        == ""
    )
    cmd = _command(fr3)
    cmd["q_c"][5] = 0.5  # inside the Panda's range, outside FR3's
    fr3.step(cmd)
    assert fr3.event == "reflex" and fr3.robot_mode is wire.RobotMode.REFLEX
    assert _errors(fr3) == ["joint_motion_generator_position_limits_violation"]
    assert fr3.start_motion(
        wire.ControllerMode.JOINT_IMPEDANCE, wire.MotionGenerator.JOINT_POSITION
    )


def test_twenty_lost_cycles_stop_the_motion(fr3):
    fr3.recover()
    fr3.start_motion(wire.ControllerMode.JOINT_IMPEDANCE, wire.MotionGenerator.JOINT_POSITION)
    fr3.step(_command(fr3))
    for _ in range(LOST_CYCLES_LIMIT - 1):
        fr3.step(None)
        assert fr3.event == ""
    fr3.step(None)
    assert _errors(fr3) == ["communication_constraints_violation"]
    assert not fr3.moving


def test_a_torque_step_is_a_torque_discontinuity(fr3):
    fr3.recover()
    fr3.start_motion(wire.ControllerMode.EXTERNAL, wire.MotionGenerator.NONE)
    cmd = _command(fr3)
    cmd["tau_J_d"] = [0.0, 0.5, 0, 0, 0, 0, 0]  # 500 N·m/s: within the rate
    fr3.step(cmd)
    assert fr3.event == ""
    cmd["tau_J_d"] = [0.0, 2.5, 0, 0, 0, 0, 0]  # 2000 N·m/s
    fr3.step(cmd)
    assert _errors(fr3) == ["controller_torque_discontinuity"]
    fr3.recover()
    assert fr3.robot_mode is wire.RobotMode.IDLE and not fr3.errors.any()


# ---------------------------------------------------------------------- the external-force estimate


@pytest.fixture(scope="module")
def panda() -> Iterator[SimulatedArm]:
    arm = SimulatedArm(franka_scene("empty"), PANDA)
    yield arm
    arm.env.close()


def push_at_ee(arm: SimulatedArm, force: np.ndarray) -> np.ndarray:
    """Push the hand with `force` (N, base frame) at the EE point (MuJoCo applies
    `xfrc_applied` at the body's centre of mass: the lever arm's moment goes with it); the
    point."""
    d = arm.env.data
    hand = arm.env.model.body("hand").id
    at = arm._ee_pose(arm.q)[:3, 3]
    d.xfrc_applied[hand, :3] = force
    d.xfrc_applied[hand, 3:] = np.cross(at - d.xipos[hand], force)
    return at


def _settle(arm: SimulatedArm, cycles: int) -> None:
    for _ in range(cycles):
        arm.step(None)


def test_a_push_on_the_hand_is_reported_as_the_arms_force_on_its_pusher(panda):
    """libfranka's robot_state.h: O_F_ext_hat_K is the force the robot applies to the
    environment (the push's negative), tau_ext_hat_filtered the joint torque beyond the model."""
    d = panda.env.data
    panda.recover()
    push = np.array([6.0, -4.0, -10.0])  # N, on the hand at the EE point
    at = push_at_ee(panda, push)
    _settle(panda, 300)
    jac = panda._ee_jacobian(panda.q)
    np.testing.assert_allclose(panda.tau_ext, -jac.T @ np.r_[push, 0.0, 0.0, 0.0], atol=0.05)
    np.testing.assert_allclose(panda.F_ext[:3], -push, atol=0.05)
    np.testing.assert_allclose(panda.F_ext[3:], 0.0, atol=0.05)
    assert np.linalg.norm(panda.O_T_EE[:3, 3] - at) < 0.005  # the lever arm hardly moved
    d.xfrc_applied[:] = 0.0
    _settle(panda, 300)
    np.testing.assert_allclose(panda.tau_ext, 0.0, atol=1e-9)


def test_joint_limits_are_not_external_forces(panda):
    m, d = panda.env.model, panda.env.data
    joint = m.joint("joint4")
    d.qpos[joint.qposadr[0]] = joint.range[1] + 0.01  # past its range: MuJoCo's limit pushes
    mujoco.mj_forward(m, d)
    panda.robot.update()
    panda.recover()  # the arm holds where it is
    _settle(panda, 5)
    assert abs(d.qfrc_constraint[panda._dofs[3]]) > 1.0  # N·m, the limit's
    np.testing.assert_allclose(panda.tau_ext, 0.0, atol=1e-9)
    np.testing.assert_allclose(panda.F_ext, 0.0, atol=1e-9)
    panda.robot.set_joint_pos(START_Q)
    panda.recover()
