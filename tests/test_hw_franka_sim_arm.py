"""The simulated arm's reflexes and its URDF, in this process (no network)."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from mjkdl.hw.franka_sim import wire
from mjkdl.hw.franka_sim.arm import LOST_CYCLES_LIMIT, SimulatedArm
from mjkdl.hw.franka_sim.limits import FR3
from mjkdl.hw.franka_sim.scene import franka_scene


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
