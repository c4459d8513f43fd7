"""JointImpedanceDrive: the Panda's actuators become the Franka robot's joint impedance, the
same torques as the server's per-tick law, its weight cancelled by MuJoCo; bad drives are
named."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest
from conftest import base_spec, menagerie

import mjkdl as mjk
from mjkdl.compile import compile_scene
from mjkdl.hw.joint_impedance import START_Q, TAU_MAX, FrankaImpedanceDrive, JointImpedance


def impedance_spec(drive: mjk.JointImpedanceDrive | None = None, prefix: str = "") -> mjk.SceneSpec:
    arm = mjk.RobotSpec(
        path=menagerie("franka_emika_panda"),
        prefix=prefix,
        impedance=mjk.JointImpedanceDrive.franka() if drive is None else drive,
    )
    return base_spec(timestep=0.001, robots=[arm])


def test_the_actuators_carry_the_law_the_server_evaluates() -> None:
    """At any state, MuJoCo's actuator torque is `JointImpedance.torque` (the server's law,
    damping from the robot's own mass matrix) plus the arm's weight; clipped alike."""
    env = mjk.Env.build(impedance_spec(prefix="p/"))
    plain = mjk.Env.build(
        base_spec(timestep=0.001, robots=[mjk.RobotSpec(path=menagerie("franka_emika_panda"))])
    )
    robot = env.create_robot("link0", "hand", prefix="p/")
    reference = plain.create_robot("link0", "hand")
    law = JointImpedance(np.diag(reference.mass_matrix(START_Q)))
    m, d = env.model, env.data
    joints = [m.joint(f"p/joint{i}") for i in range(1, 8)]
    ids, dofs = robot.actuator_ids, [j.dofadr[0] for j in joints]
    qadr = [j.qposadr[0] for j in joints]
    damping = law.damping()
    np.testing.assert_allclose(-m.actuator_biasprm[ids, 2], damping, rtol=1e-9)
    np.testing.assert_array_equal(m.actuator_forcerange[ids, 1], TAU_MAX)
    rng = np.random.default_rng(0)
    clipped = 0
    for _ in range(20):
        q = START_Q + rng.uniform(-0.3, 0.3, 7)
        dq, q_d, dq_d = (
            rng.uniform(-1, 1, 7),
            q + rng.uniform(-0.02, 0.02, 7),
            rng.uniform(-1, 1, 7),
        )
        d.qpos[qadr] = q
        d.qvel[dofs] = dq
        d.ctrl[ids] = q_d + damping / law.stiffness * dq_d
        mujoco.mj_forward(m, d)
        tau = law.torque(q_d, dq_d, q, dq)
        clipped += int(np.any(np.abs(tau) == TAU_MAX))
        np.testing.assert_allclose(d.actuator_force[ids], tau, atol=1e-9)
        reference.set_joint_pos(q)
        weight = reference.gravity_torques()
        np.testing.assert_allclose(d.qfrc_gravcomp[dofs], weight, atol=1e-9)
        # through the actuators: the joint torques measured include the weight
        np.testing.assert_allclose(d.qfrc_actuator[dofs], tau + weight, atol=1e-9)
    assert clipped > 0  # the wrists' 12 N·m bind at these errors
    env.close()
    plain.close()


def test_the_arm_holds_its_pose_by_itself() -> None:
    """Setpoints where the arm is: it stays there, its weight cancelled (no droop of the
    servos' kind, no feed-forward)."""
    env = mjk.Env.build(impedance_spec())
    robot = env.create_robot("link0", "hand")
    robot.set_joint_pos(START_Q)
    env.data.ctrl[robot.actuator_ids] = START_Q
    env.step(1000)
    robot.update()
    assert np.abs(robot.jnt_pos_msr - START_Q).max() < 1e-6
    env.close()


def test_a_scene_without_the_impedance_is_refused_by_the_drive() -> None:
    env = mjk.Env.build(
        base_spec(timestep=0.001, robots=[mjk.RobotSpec(path=menagerie("franka_emika_panda"))])
    )
    robot = env.create_robot("link0", "hand")
    with pytest.raises(
        mjk.SpecError,
        match=r"actuators \['actuator1', .*'actuator7'\] are not "
        r"a joint impedance.*RobotSpec\(impedance=JointImpedanceDrive.franka",
    ):
        FrankaImpedanceDrive(env, robot)
    env.close()


FRANKA = mjk.JointImpedanceDrive.franka()


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (
            {"actuators": [*FRANKA.actuators[:6], "actuator9"]},
            r"no actuator named 'actuator9' in robots\[0\].impedance.actuators\[6\]; "
            r"close matches: actuator8",
        ),
        (
            {
                "actuators": ["actuator8"],
                "stiffness": [1.0],
                "torque_limit": [1.0],
                "damping_pose": [0.0],
            },
            r"actuators\[0\]: actuator 'actuator8' does not drive a "
            r"joint directly \(its transmission is mjTRN_TENDON\)",
        ),
        ({"actuators": []}, r"robots\[0\].impedance.actuators is empty"),
        (
            {
                "actuators": ["actuator1", "actuator1"],
                "stiffness": [1.0, 1.0],
                "torque_limit": [1.0, 1.0],
                "damping_pose": [0.0, 0.0],
            },
            r"actuators\[1\]: 'actuator1' is named twice",
        ),
        ({"stiffness": [3000.0] * 6}, r"impedance.stiffness must have 7 values, got 6"),
        ({"torque_limit": [87.0] * 6 + [0.0]}, r"impedance.torque_limit must be positive"),
        ({"damping_pose": [0.0] * 6 + [float("nan")]}, r"impedance.damping_pose must be finite"),
    ],
)
def test_bad_drives_are_named(change: dict, message: str) -> None:
    with pytest.raises((mjk.SpecError, mjk.UnknownNameError), match=message):
        compile_scene(impedance_spec(dataclasses.replace(FRANKA, **change)))


def test_a_drive_of_another_type_is_refused() -> None:
    spec = impedance_spec()
    spec.robots[0].impedance = mjk.GripperDrive.franka_hand()  # type: ignore[assignment]
    with pytest.raises(
        mjk.SpecTypeError,
        match=r"robots\[0\].impedance must be a "
        "JointImpedanceDrive",
    ):
        compile_scene(spec)
