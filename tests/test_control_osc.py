"""OperationalSpaceController: a 5 cm step response, its parity with robosuite's formula, and
bad input by name."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from conftest import gripper_tool, menagerie, panda_arm, panda_spec

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


def robosuite_formula(m, d, tcp, rotation, jac, target, kp, zeta, kp_null, posture, decoupled):
    """The law written out with MuJoCo's M, J and qfrc_bias and plain NumPy inverses (the
    arm is the model's first 7 dofs)."""
    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, full)
    M, J = full[:7, :7], jac[:, :7]
    q, v = d.qpos[:7], d.qvel[:7]
    kd = 2 * np.sqrt(kp) * zeta
    e = np.concatenate([target.translation - tcp, pin.log3(target.rotation @ rotation.T)])
    a = kp * e - kd * (J @ v)
    Minv = np.linalg.inv(M)
    Lam_inv = J @ Minv @ J.T

    def damped_inverse(A):  # the controller's 1e-6 share of the mean eigenvalue
        return np.linalg.inv(A + 1e-6 * np.trace(A) / len(A) * np.eye(len(A)))

    Lam = damped_inverse(Lam_inv)
    if decoupled:
        F = np.concatenate(
            [damped_inverse(Lam_inv[:3, :3]) @ a[:3], damped_inverse(Lam_inv[3:, 3:]) @ a[3:]]
        )
    else:
        F = Lam @ a
    N = np.eye(7) - Minv @ J.T @ Lam @ J
    p = kp_null * (posture - q) - 2 * math.sqrt(kp_null) * v
    return J.T @ F + N.T @ (M @ p) + d.qfrc_bias[:7]


@pytest.mark.parametrize("arm", ["panda", "gen3"])
def test_torques_are_robosuites_formula_on_mujocos_numbers(arm, request) -> None:
    """At random states, gains and targets, both inversions of the task-space inertia."""
    if arm == "panda":
        scene = request.getfixturevalue("env")
        robot = panda_arm(scene, mjk.CtrlMode.TORQUE)
        hand = scene.model.body("hand").id
    else:
        scene = request.getfixturevalue("tutorial_scene")()
        robot = scene.create_robot("base_link", "bracelet_link", tool=gripper_tool())
        pinch = scene.model.site("g_pinch").id
    m, d = scene.model, scene.data
    rng = np.random.default_rng(7)
    limits = np.clip(robot.joint_limits, -3.0, 3.0)
    jacp, jacr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    for _ in range(4):
        robot.set_joint_pos(rng.uniform(limits[:, 0], limits[:, 1]), call_forward=False)
        d.qvel[:] = rng.normal(0.0, 0.5, m.nv)  # the fingers' too: they count in the bias
        mujoco.mj_forward(m, d)
        robot.update()
        if arm == "panda":
            rotation = d.xmat[hand].reshape(3, 3)
            tcp = d.xpos[hand] + rotation @ [0.0, 0.0, 0.1034]
            mujoco.mj_jac(m, d, jacp, jacr, tcp, hand)
        else:
            rotation, tcp = d.site_xmat[pinch].reshape(3, 3), d.site_xpos[pinch]
            mujoco.mj_jacSite(m, d, jacp, jacr, pinch)
        target = pin.SE3(
            rotation @ pin.exp3(rng.normal(0.0, 0.2, 3)), tcp + rng.normal(0.0, 0.05, 3)
        )
        kp, zeta = rng.uniform(50.0, 200.0, 6), rng.uniform(0.5, 1.5, 6)
        posture = robot.jnt_pos_msr + rng.normal(0.0, 0.2, 7)
        for decoupled in (False, True):
            osc = OperationalSpaceController(
                robot, kp, zeta, kp_null=8.0, posture=posture, decoupled=decoupled
            )
            tau = osc.torques(target)
            expected = robosuite_formula(
                m,
                d,
                tcp,
                rotation,
                np.vstack([jacp, jacr]),
                target,
                kp,
                zeta,
                8.0,
                posture,
                decoupled,
            )
            assert np.abs(tau - expected).max() < 1e-8 * np.abs(expected).max()


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


def test_a_target_or_state_that_is_not_finite_is_refused(env) -> None:
    robot = panda_arm(env, mjk.CtrlMode.TORQUE)
    osc = OperationalSpaceController(robot)
    pose = robot.fk_frame()
    with pytest.raises(mjk.SpecError, match=r"target must be finite"):
        osc.torques(pin.SE3(pose.rotation, np.array([np.nan, 0.0, 0.5])))
    env.data.qvel[3] = np.nan  # a diverged simulation, read by update()
    robot.update()
    with pytest.raises(
        mjk.SimulationError,
        match=r"the torques at the measured state are not finite \(q = .*, "
        r"q̇ = \[0\.0, 0\.0, 0\.0, nan, .*has the simulation diverged",
    ):
        osc.torques(pose)


def test_a_singular_model_is_refused_by_name(env) -> None:
    """A Pinocchio model doctored so M, then J M⁻¹ Jᵀ, cannot be factorised."""
    robot = panda_arm(env, mjk.CtrlMode.TORQUE)
    osc = OperationalSpaceController(robot)
    target = robot.fk_frame()
    model = robot.model
    inertias, armature = list(model.inertias), model.armature.copy()
    for i in range(1, model.njoints):
        model.inertias[i] = pin.Inertia.Zero()
    model.armature[:] = 0.0
    with pytest.raises(
        mjk.SpecError,
        match=r"the arm's mass matrix M is not positive definite at the measured q = \[0\.0, "
        r".*\(links without mass\?\)",
    ):
        osc.torques(target)
    for i, inertia in enumerate(inertias):
        model.inertias[i] = inertia
    model.armature[:] = armature
    model.frames[robot.tcp_frame_id].parentJoint = 0  # the TCP on the world: J = 0
    with pytest.raises(mjk.SpecError, match=r"J M⁻¹ Jᵀ is not positive definite .*no joint moves"):
        osc.torques(target)


def test_a_call_allocates_no_matrices_and_the_loop_keeps_nothing(env) -> None:
    """Only Pinocchio's returned copies (M, J) and a few vectors live during a call; 2000
    control steps leave nothing behind."""
    import tracemalloc

    robot = panda_arm(env, mjk.CtrlMode.TORQUE)
    osc = OperationalSpaceController(robot)
    target = robot.fk_frame()

    def run(steps: int) -> None:
        for _ in range(steps):
            robot.update()
            osc.command(target)
            robot.step()

    run(10)
    tracemalloc.start()
    start = tracemalloc.get_traced_memory()[0]
    osc.torques(target)
    peak = tracemalloc.get_traced_memory()[1] - start
    run(100)
    before = tracemalloc.take_snapshot()
    run(2000)
    after = tracemalloc.take_snapshot()
    tracemalloc.stop()
    assert peak < 4096  # 1.4 kB here; computeAllTerms and np.linalg took 8.8 kB
    mjkdl_files = [s for s in after.compare_to(before, "filename") if "mjkdl" in str(s)]
    assert sum(s.size_diff for s in mjkdl_files) <= 0
