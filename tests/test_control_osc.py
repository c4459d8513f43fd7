"""OperationalSpaceController: a 5 cm step response, its parity with robosuite's formula, and
bad input by name."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from conftest import menagerie, panda_arm, panda_spec

import mjkdl as mjk
from mjkdl.control import OperationalSpaceController


@pytest.fixture
def env():
    menagerie("franka_emika_panda")
    with mjk.Env.build(panda_spec()) as scene:
        yield scene


def step_response(env, robot, osc, offset, seconds=1.5):
    """Errors (m), progress along the step (m) and TCP rotation (deg) at every step."""
    start = robot.fk_frame()
    target = pin.SE3(start.rotation, start.translation + offset)
    direction = offset / np.linalg.norm(offset)
    error, along, turn = [], [], []
    for _ in range(round(seconds / env.timestep())):
        robot.update()
        osc.command(target)
        robot.step()
        robot.update()
        pose = robot.fk_frame()
        error.append(np.linalg.norm(pose.translation - target.translation))
        along.append((pose.translation - start.translation) @ direction)
        turn.append(math.degrees(np.linalg.norm(pin.log3(start.rotation.T @ pose.rotation))))
    return np.array(error), np.array(along), np.array(turn)


@pytest.mark.parametrize("offset", [[0.05, 0.0, 0.0], [0.0, -0.05, 0.0], [0.0, 0.0, 0.05]])
def test_a_5_cm_step_settles_within_2_mm_without_overshoot(env, offset) -> None:
    robot = panda_arm(env, mjk.CtrlMode.TORQUE)
    osc = OperationalSpaceController(robot)  # kp 150, critically damped
    error, along, turn = step_response(env, robot, osc, np.array(offset))
    settled = np.flatnonzero(error > 0.002)[-1] + 1  # first step after which it stays within 2 mm
    assert settled * env.timestep() < 1.0  # ~0.45 s here, well inside 1.5 s
    assert error[-1] < 1e-4
    assert along.max() - 0.05 <= 0.1 * 0.05  # overshoot at most 10 %
    assert turn.max() < 1.0  # orientation held within 1°


def test_decoupled_inertia_lets_the_orientation_swing_more(env) -> None:
    robot = panda_arm(env, mjk.CtrlMode.TORQUE)
    osc = OperationalSpaceController(robot, decoupled=True)  # robosuite's default
    error, _along, turn = step_response(env, robot, osc, np.array([0.05, 0.0, 0.0]))
    assert error[-1] < 0.002
    assert turn.max() > 1.0  # the coupling Λ leaves out shows as rotation


def test_torques_are_robosuites_formula_on_mujocos_numbers(env) -> None:
    """The same law written with MuJoCo's M, J and qfrc_bias and plain NumPy inverses."""
    import mujoco

    robot = panda_arm(env, mjk.CtrlMode.TORQUE)
    env.data.qvel[:7] = [0.3, -0.2, 0.1, 0.4, -0.5, 0.2, 0.6]
    mujoco.mj_forward(env.model, env.data)
    robot.update()
    posture = robot.jnt_pos_msr + 0.1
    osc = OperationalSpaceController(
        robot, kp=[100, 120, 140, 50, 60, 70], kp_null=8.0, posture=posture
    )
    start = robot.fk_frame()
    target = pin.SE3(
        start.rotation @ pin.exp3(np.array([0.05, -0.02, 0.1])),
        start.translation + np.array([0.03, -0.02, 0.04]),
    )
    tau = osc.torques(target)
    m, d = env.model, env.data
    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, full)
    M = full[:7, :7]
    jacp, jacr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    hand = m.body("hand").id
    tcp = d.xpos[hand] + d.xmat[hand].reshape(3, 3) @ [0, 0, 0.1034]
    mujoco.mj_jac(m, d, jacp, jacr, tcp, hand)
    J = np.vstack([jacp, jacr])[:, :7]
    R = d.xmat[hand].reshape(3, 3)
    kp = np.array([100, 120, 140, 50, 60, 70.0])
    kd = 2 * np.sqrt(kp)
    e = np.concatenate([target.translation - tcp, pin.log3(target.rotation @ R.T)])
    a = kp * e - kd * (J @ d.qvel[:7])
    Minv = np.linalg.inv(M)
    Lam = np.linalg.inv(J @ Minv @ J.T)
    N = np.eye(7) - Minv @ J.T @ Lam @ J
    q, v = d.qpos[:7], d.qvel[:7]
    expected = (
        J.T @ Lam @ a + N.T @ (M @ (8.0 * (posture - q) - 2 * math.sqrt(8.0) * v)) + d.qfrc_bias[:7]
    )
    assert np.abs(tau - expected).max() < 1e-4 * np.abs(expected).max()


def test_command_writes_the_torques_and_respects_gravity_compensation(env) -> None:
    robot = panda_arm(env, mjk.CtrlMode.TORQUE)
    osc = OperationalSpaceController(robot)
    target = pin.SE3(
        robot.fk_frame().rotation, robot.fk_frame().translation + np.array([0.02, 0.0, 0.0])
    )
    tau = osc.command(target)
    assert np.array_equal(robot.jnt_trq_cmd, tau)
    robot.gravity_compensation = True
    on_top = osc.command(target)
    assert np.allclose(on_top + robot.gravity_torques(), tau, atol=1e-9)


def test_bad_input_is_refused_by_name(env) -> None:
    robot = panda_arm(env, mjk.CtrlMode.POSITION)
    osc = OperationalSpaceController(robot)
    with pytest.raises(mjk.SpecError, match=r"needs the robot in TORQUE mode, not POSITION"):
        osc.command(robot.fk_frame())
    with pytest.raises(mjk.SpecTypeError, match=r"target must be a pinocchio.SE3"):
        osc.torques([0.4, 0.0, 0.5])
    with pytest.raises(mjk.SpecError, match=r"kp needs 6 values"):
        OperationalSpaceController(robot, kp=[150.0] * 3)
    with pytest.raises(mjk.SpecError, match=r"kp must be >= 0 on every axis"):
        OperationalSpaceController(robot, kp=[150.0] * 5 + [-1.0])
    with pytest.raises(mjk.SpecError, match=r"damping_ratio must be a finite number >= 0"):
        OperationalSpaceController(robot, damping_ratio=math.nan)
    with pytest.raises(mjk.SpecError, match=r"posture needs 7 values"):
        OperationalSpaceController(robot, posture=[0.0] * 6)
    with pytest.raises(mjk.SpecTypeError, match=r"decoupled must be True or False"):
        OperationalSpaceController(robot, decoupled=1)
    with pytest.raises(mjk.SpecTypeError, match=r"robot must be a Robot"):
        OperationalSpaceController(env)
