"""CartesianVelocityController: tracking, limits, moving frames, collision avoidance, errors."""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from conftest import (
    HOME,
    PANDA_HOME,
    PANDA_TCP,
    base_spec,
    gripper_tool,
    menagerie,
    panda_arm,
    panda_spec,
)
from hypothesis import given, settings
from hypothesis import strategies as st

import mjkdl as mjk
from mjkdl.urdf import example_robot_data_path

MODES = [mjk.CtrlMode.VELOCITY, mjk.CtrlMode.POSITION]
# Menagerie's Panda position servos (kv/kp = 0.1 s) trail a ramp by 0.1 s: in POSITION mode
# the arm is measured once it has caught up with the last command.
SERVO_LAG = 0.3


def drive(robot: mjk.Robot, ctrl: mjk.CartesianVelocityController, twist, seconds: float):
    """Command `twist` every physics step for `seconds`; return the commanded velocities."""
    steps = round(seconds / robot.scene.timestep())
    out = np.empty((steps, robot.n_joints))
    for k in range(steps):
        robot.update()
        out[k] = ctrl.command(twist)
        robot.step()
    robot.update()
    return out


def rotation_deg(a: pin.SE3, b: pin.SE3) -> float:
    return float(np.degrees(np.linalg.norm(pin.log3(a.rotation.T @ b.rotation))))


@pytest.fixture
def panda_env():
    with mjk.Env.build(panda_spec()) as env:
        yield env


def test_settings_are_the_resolved_terms(panda_env) -> None:
    robot = panda_arm(panda_env, mjk.CtrlMode.VELOCITY)
    ctrl = mjk.CartesianVelocityController(robot, max_joint_velocity=0.8, posture_gain=2.0)
    s = ctrl.settings
    np.testing.assert_array_equal(np.stack([s.joint_lower, s.joint_upper], 1), robot.joint_limits)
    # The Panda's model gives every joint a velocity limit (Pinocchio reads MuJoCo's none):
    # the constructor's bound applies to all.
    assert s.max_joint_velocity.tolist() == [0.8] * 7
    assert (s.max_joint_acceleration, s.posture_gain, s.damping) == (10.0, 2.0, 1e-5)
    assert s.posture.tolist() == robot.jnt_pos_msr.tolist()
    s.posture[0] = 9.0
    assert ctrl.settings.posture[0] != 9.0  # a copy


@pytest.mark.parametrize("mode", MODES, ids=lambda m: m.name)
@pytest.mark.parametrize("axis", [0, 1, 2])
def test_constant_twist_moves_tcp_10cm_in_2s(panda_env, mode, axis) -> None:
    robot = panda_arm(panda_env, mode)
    ctrl = mjk.CartesianVelocityController(robot)
    start = robot.fk_frame()
    twist = np.zeros(6)
    twist[axis] = 0.05
    drive(robot, ctrl, twist, 2.0)
    if mode is mjk.CtrlMode.POSITION:
        drive(robot, ctrl, np.zeros(6), SERVO_LAG)
    end = robot.fk_frame()
    moved = end.translation - start.translation
    assert moved[axis] == pytest.approx(0.10, rel=0.05)
    assert np.linalg.norm(np.delete(moved, axis)) < 0.005
    assert rotation_deg(start, end) < 2.0
    assert ctrl.last_status is mjk.SolveStatus.OPTIMAL


@pytest.mark.parametrize("mode", MODES, ids=lambda m: m.name)
def test_pure_angular_twist_turns_in_place(panda_env, mode) -> None:
    robot = panda_arm(panda_env, mode)
    ctrl = mjk.CartesianVelocityController(robot)
    start = robot.fk_frame()
    drive(robot, ctrl, [0, 0, 0, 0, 0, 0.3], 2.0)
    if mode is mjk.CtrlMode.POSITION:
        drive(robot, ctrl, np.zeros(6), SERVO_LAG)
    end = robot.fk_frame()
    assert np.linalg.norm(end.translation - start.translation) < 0.005
    turn = pin.log3(start.rotation.T @ end.rotation)
    world_turn = start.rotation @ turn  # the rotation vector, in world axes
    assert world_turn[2] == pytest.approx(0.6, rel=0.05)
    assert np.linalg.norm(world_turn[:2]) < np.radians(2.0)


def test_solution_makes_mujoco_tcp_velocity_equal_the_twist(panda_env) -> None:
    """Undamped and unconstrained, J qd is the twist; J here is MuJoCo's, not Pinocchio's."""
    robot = panda_arm(panda_env)
    ctrl = mjk.CartesianVelocityController(robot, damping=0.0, max_joint_acceleration=None)
    model, data = panda_env.model, panda_env.data
    hand = panda_env.body_id("hand")
    tcp = robot.fk_frame().translation
    jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    mujoco.mj_jac(model, data, jacp, jacr, tcp, hand)
    dofs = [model.joint(n).dofadr[0] for n in robot.joint_names]
    jac = np.vstack([jacp[:, dofs], jacr[:, dofs]])
    rng = np.random.default_rng(3)
    for _ in range(5):
        twist = rng.uniform(-0.1, 0.1, 6)
        qd = ctrl.solve(twist)
        assert np.abs(jac @ qd - twist).max() < 1e-9


def test_posture_acts_in_the_null_space_only(panda_env) -> None:
    robot = panda_arm(panda_env)
    ctrl = mjk.CartesianVelocityController(
        robot, posture_gain=2.0, damping=0.0, max_joint_acceleration=None
    )
    jac = robot.jacobian()
    null = np.linalg.svd(jac)[2][6]  # the Panda's one self-motion direction
    ctrl.posture = robot.jnt_pos_msr + 0.2 * null
    qd = ctrl.solve(np.zeros(6))
    assert np.abs(jac @ qd).max() < 1e-9  # the TCP does not move
    assert qd @ null == pytest.approx(2.0 * 0.2, rel=1e-3)  # gain x distance along N
    twist = np.array([0.05, -0.02, 0.01, 0.1, 0.0, -0.1])
    qd = ctrl.solve(twist)
    assert np.abs(jac @ qd - twist).max() < 1e-9


@pytest.mark.parametrize("mode", MODES, ids=lambda m: m.name)
@pytest.mark.parametrize(
    "twist",
    [[0.5, 0, 0, 0, 0, 0], [0, 0, -0.5, 0, 0, 0], [-0.3, 0.3, 0.3, 0, 0, 0], [0, 0, 0, 0, 0, 2.0]],
)
def test_far_out_of_reach_respects_every_limit(panda_env, mode, twist) -> None:
    robot = panda_arm(panda_env, mode)
    ctrl = mjk.CartesianVelocityController(robot, max_joint_velocity=0.8)
    lower, upper = robot.joint_limits.T
    vmax = ctrl.velocity_limits
    np.testing.assert_array_equal(vmax, 0.8)  # Menagerie's Panda has no velocity limits
    worst_pos, worst_cmd, worst_vel = -np.inf, 0.0, 0.0
    for _ in range(round(4.0 / panda_env.timestep())):
        robot.update()
        q = robot.jnt_pos_msr
        assert np.isfinite(q).all()
        worst_pos = max(worst_pos, float(np.max(np.maximum(lower - q, q - upper))))
        worst_vel = max(worst_vel, float(np.max(np.abs(robot.jnt_vel_msr) / vmax)))
        qd = ctrl.command(twist)
        assert np.isfinite(qd).all()
        worst_cmd = max(worst_cmd, float(np.max(np.abs(qd) / vmax)))
        robot.step()
    assert worst_pos < 0.0  # every joint stayed strictly inside its range
    assert worst_cmd <= 1.0 + 1e-9
    assert worst_vel <= 1.05  # the servos follow the bounded commands without overshoot
    assert ctrl.last_status is mjk.SolveStatus.OPTIMAL


def test_model_velocity_limits_take_precedence(panda_env) -> None:
    robot = panda_arm(panda_env)
    robot.model.velocityLimit = np.array([2.0, 2.0, 2.0, 2.0, np.inf, 0.0, 3.0])
    ctrl = mjk.CartesianVelocityController(robot, max_joint_velocity=0.7)
    np.testing.assert_array_equal(ctrl.velocity_limits, [2.0, 2.0, 2.0, 2.0, 0.7, 0.7, 3.0])
    qd = ctrl.solve([2.0, 0, 0, 0, 0, 0])
    assert np.all(np.abs(qd) <= ctrl.velocity_limits + 1e-9)


def frame_object(name: str, yaw_deg: float) -> mjk.SceneObject:
    """A small fixed box whose body serves as a control frame turned `yaw_deg` about z."""
    return mjk.SceneObject(
        name=name,
        shape=mjk.Shape.BOX,
        size=[0.01, 0.01, 0.01],
        pos=[-0.5, -0.5, 0.01],
        euler=[0.0, 0.0, yaw_deg],
        fixed=True,
    )


@pytest.mark.parametrize("yaw", [90.0, -30.0])
def test_rotated_control_frame_maps_x_to_the_rotated_axis(yaw) -> None:
    with mjk.Env.build(panda_spec(objects=[frame_object("turned", yaw)])) as env:
        robot = panda_arm(env)
        ctrl = mjk.CartesianVelocityController(robot, control_frame="turned")
        start = robot.fk_frame().translation
        drive(robot, ctrl, [0.05, 0, 0, 0, 0, 0], 1.0)
        moved = robot.fk_frame().translation - start
        axis = np.array([np.cos(np.radians(yaw)), np.sin(np.radians(yaw)), 0.0])
        assert moved @ axis == pytest.approx(0.05, rel=0.05)
        assert np.linalg.norm(moved - (moved @ axis) * axis) < 0.002


def test_moving_control_frame_is_read_on_every_call() -> None:
    """A free body turned between two calls: the same twist follows it at once."""
    marker = mjk.SceneObject(
        name="marker", shape=mjk.Shape.SPHERE, size=[0.01], pos=[-0.5, 0.5, 0.5], mass=0.1
    )
    with mjk.Env.build(panda_spec(objects=[marker])) as env:
        robot = panda_arm(env)
        ctrl = mjk.CartesianVelocityController(
            robot, control_frame="marker", damping=0.0, max_joint_acceleration=None
        )
        jac = robot.jacobian()
        for yaw in (0.0, 90.0, 200.0):
            half = np.radians(yaw) / 2
            env.set_body_pose("marker", [-0.5, 0.5, 0.5], [np.cos(half), 0, 0, np.sin(half)])
            env.forward()
            v = jac @ ctrl.solve([0.05, 0, 0, 0, 0, 0])
            expected = 0.05 * np.array([np.cos(2 * half), np.sin(2 * half), 0.0])
            assert np.abs(v - np.r_[expected, 0, 0, 0]).max() < 1e-9


# ---------------------------------------------------------------------- collision avoidance


def block(height: float = 0.2) -> mjk.SceneObject:
    """A fixed 20 cm box below the Panda's hand at home (its top at `height`)."""
    return mjk.SceneObject(
        name="block",
        shape=mjk.Shape.BOX,
        size=[0.1, 0.1, height / 2],
        pos=[0.55, 0.0, height / 2],
        fixed=True,
    )


def hand_block_distance(env: mjk.Env, hand_geoms, block_geoms) -> float:
    model, data = env.model, env.data
    return min(
        mujoco.mj_geomDistance(model, data, a, b, 1.0, None)
        for a in hand_geoms
        for b in block_geoms
    )


def subtree_geoms(model: mujoco.MjModel, root: int) -> list[int]:
    bodies = {root}
    for b in range(root + 1, model.nbody):
        if model.body_parentid[b] in bodies:
            bodies.add(b)
    geoms = range(model.ngeom)
    return [g for g in geoms if model.geom_bodyid[g] in bodies and model.geom_contype[g]]


@pytest.mark.parametrize("mode", MODES, ids=lambda m: m.name)
@pytest.mark.parametrize("margin", [0.03, 0.08])
def test_collision_avoidance_keeps_the_margin_while_pushed(mode, margin) -> None:
    with mjk.Env.build(panda_spec(objects=[block()])) as env:
        robot = panda_arm(env, mode)
        ctrl = mjk.CartesianVelocityController(
            robot, avoid=[("hand", "block")], min_distance=margin
        )
        hand_geoms = subtree_geoms(env.model, env.body_id("hand"))
        block_geoms = subtree_geoms(env.model, env.body_id("block"))
        start = hand_block_distance(env, hand_geoms, block_geoms)
        assert start > 0.15
        closest = np.inf
        for _ in range(round(4.0 / env.timestep())):
            robot.update()
            ctrl.command([0.0, 0.0, -0.1, 0.0, 0.0, 0.0])  # straight down into the block
            robot.step()
            env.forward()
            closest = min(closest, hand_block_distance(env, hand_geoms, block_geoms))
        assert closest >= margin - 5e-4
        assert closest < margin + 0.005  # it did go as close as allowed
        assert ctrl.last_status is mjk.SolveStatus.OPTIMAL


def test_without_avoidance_the_same_push_reaches_the_block() -> None:
    """The reference run for the test above: the twist alone drives the hand into the box."""
    with mjk.Env.build(panda_spec(objects=[block()])) as env:
        robot = panda_arm(env)
        ctrl = mjk.CartesianVelocityController(robot)
        hand_geoms = subtree_geoms(env.model, env.body_id("hand"))
        block_geoms = subtree_geoms(env.model, env.body_id("block"))
        drive(robot, ctrl, [0.0, 0.0, -0.1, 0.0, 0.0, 0.0], 4.0)
        env.forward()
        assert hand_block_distance(env, hand_geoms, block_geoms) < 0.002


def test_infeasible_qp_gives_zero_and_a_flag_and_warns_once() -> None:
    """Inside the margin with tiny velocity limits: the required escape speed is out of reach."""
    with mjk.Env.build(panda_spec(objects=[block(height=0.46)])) as env:
        robot = panda_arm(env)
        ctrl = mjk.CartesianVelocityController(
            robot, avoid=[("hand", "block")], min_distance=0.1, max_joint_velocity=1e-3
        )
        with pytest.warns(RuntimeWarning, match="infeasible"):
            qd = ctrl.solve([0.05, 0, 0, 0, 0, 0])
        np.testing.assert_array_equal(qd, np.zeros(7))
        assert ctrl.last_status is mjk.SolveStatus.INFEASIBLE
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            for _ in range(3):
                robot.update()
                np.testing.assert_array_equal(ctrl.command([0.05, 0, 0, 0, 0, 0]), 0.0)
                robot.step()
        np.testing.assert_array_equal(robot.jnt_vel_cmd, 0.0)
        assert ctrl.last_status is mjk.SolveStatus.INFEASIBLE
        # Back with room to move: solved again.
        ctrl2 = mjk.CartesianVelocityController(robot)
        ctrl2.solve([0.05, 0, 0, 0, 0, 0])
        assert ctrl2.last_status is mjk.SolveStatus.OPTIMAL


def test_nan_state_degrades_to_zero(panda_env) -> None:
    robot = panda_arm(panda_env)
    ctrl = mjk.CartesianVelocityController(robot)
    panda_env.data.qpos[0] = np.nan
    robot.update()
    with pytest.warns(RuntimeWarning, match="failed"):
        qd = ctrl.solve([0.05, 0, 0, 0, 0, 0])
    np.testing.assert_array_equal(qd, 0.0)
    assert ctrl.last_status is mjk.SolveStatus.FAILED


# ---------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    ("twist", "message"),
    [
        ([0.1, 0, 0], r"twist needs 6 values .* got shape \(3,\)"),
        (np.zeros((2, 6)), r"twist needs 6 values"),
        ([np.nan, 0, 0, 0, 0, 0], "twist must be finite"),
        ([0, 0, np.inf, 0, 0, 0], "twist must be finite"),
        (["a", 0, 0, 0, 0, 0], "twist must hold real numbers"),
        (None, "twist"),
    ],
)
def test_bad_twists_are_named(panda_env, twist, message) -> None:
    robot = panda_arm(panda_env)
    ctrl = mjk.CartesianVelocityController(robot)
    with pytest.raises(mjk.SpecError, match=message):
        ctrl.solve(twist)
    with pytest.raises(ValueError, match=message):
        ctrl.command(twist)


def test_unknown_names_are_named_with_close_matches(panda_env) -> None:
    robot = panda_arm(panda_env)
    with pytest.raises(mjk.UnknownNameError, match=r"no site or body named 'hnd'.*hand"):
        mjk.CartesianVelocityController(robot, control_frame="hnd")
    with pytest.raises(KeyError, match=r"no body named 'lnk7'.*link7"):
        mjk.CartesianVelocityController(robot, avoid=[("hand", "lnk7")])


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        ({"control_frame": 3}, "control_frame must be a site or body name"),
        ({"avoid": "hand"}, "avoid must be a sequence of"),
        ({"avoid": [("hand",)]}, r"avoid\[0\] must be a pair of body names"),
        ({"avoid": [("hand", "link7"), ("hand", 5)]}, r"avoid\[1\] must be a pair"),
        ({"avoid": [("hand", "link0")]}, "avoid: 'hand' and 'link0'"),
        ({"avoid": [("link6", "hand")]}, "avoid: 'link6' and 'hand'"),
        ({"min_distance": -0.1}, "min_distance must be a finite number >= 0"),
        ({"min_distance": np.nan}, "min_distance must be a finite number"),
        ({"min_distance": 0.2, "influence_distance": 0.1}, "influence_distance .* must exceed"),
        ({"max_joint_velocity": 0.0}, "max_joint_velocity must be a finite number > 0"),
        ({"max_joint_velocity": [1.0] * 6}, r"max_joint_velocity needs 7 values"),
        ({"max_joint_velocity": [1.0] * 6 + [-1.0]}, "max_joint_velocity must be positive"),
        ({"limit_gain": 1.5}, r"limit_gain must be in \(0, 1\]"),
        ({"posture": [0.0] * 3}, r"posture needs 7 values"),
        ({"posture": [np.inf] * 7}, "posture must be finite"),
        ({"dt": 0.0}, "dt must be a finite number > 0"),
    ],
)
def test_bad_settings_are_named(panda_env, kw, message) -> None:
    robot = panda_arm(panda_env)
    with pytest.raises(mjk.SpecError, match=message):
        mjk.CartesianVelocityController(robot, **kw)


def test_body_without_collision_geoms_is_named() -> None:
    free = mjk.SceneObject(
        name="ghost", shape=mjk.Shape.SPHERE, size=[0.02], pos=[1, 1, 0.5], mass=0.1
    )
    with mjk.Env.build(panda_spec(objects=[free])) as env:
        env.model.geom_contype[env.model.body_geomadr[env.body_id("ghost")]] = 0
        env.model.geom_conaffinity[env.model.body_geomadr[env.body_id("ghost")]] = 0
        robot = panda_arm(env)
        with pytest.raises(mjk.SpecError, match="body 'ghost' and its subtree have no collision"):
            mjk.CartesianVelocityController(robot, avoid=[("hand", "ghost")])


def test_command_checks_mode_and_period(panda_env) -> None:
    robot = panda_arm(panda_env, mjk.CtrlMode.TORQUE)
    ctrl = mjk.CartesianVelocityController(robot)
    with pytest.raises(mjk.SpecError, match="VELOCITY or POSITION mode, not TORQUE"):
        ctrl.command(np.zeros(6))
    assert ctrl.solve(np.zeros(6)).shape == (7,)  # solve alone works in any mode
    robot.ctrl_mode = mjk.CtrlMode.VELOCITY
    for dt in (-0.01, np.nan, "fast"):
        with pytest.raises(mjk.SpecError, match="dt must be a finite number > 0"):
            ctrl.command(np.zeros(6), dt=dt)


def test_position_mode_integrates_over_dt_inside_the_limits(panda_env) -> None:
    robot = panda_arm(panda_env, mjk.CtrlMode.POSITION)
    ctrl = mjk.CartesianVelocityController(robot)
    before = robot.jnt_pos_cmd.copy()
    qd = ctrl.command([0.05, 0, 0, 0, 0, 0], dt=0.1)
    np.testing.assert_allclose(robot.jnt_pos_cmd, before + 0.1 * qd, atol=1e-15)
    # Turning the hand about its axis with long periods: the wrist (joint 7) runs up to its
    # limit and stops there, never past it.
    lower, upper = robot.joint_limits.T
    for _ in range(60):
        ctrl.command([0, 0, 0, 0, 0, -2.0], dt=0.5)
        assert np.all(robot.jnt_pos_cmd <= upper) and np.all(robot.jnt_pos_cmd >= lower)
    assert robot.jnt_pos_cmd[6] == pytest.approx(upper[6], abs=1e-3)


def test_rebuilt_scene_rebinds_the_controller(panda_env) -> None:
    robot = panda_arm(panda_env)
    ctrl = mjk.CartesianVelocityController(
        robot, control_frame="link0", damping=0.0, max_joint_acceleration=None
    )
    panda_env.add_object(block())  # new model and data: ids and views are resolved again
    robot.update()
    qd = ctrl.solve([0.05, 0, 0, 0, 0, 0])
    assert np.abs(robot.jacobian() @ qd - [0.05, 0, 0, 0, 0, 0]).max() < 1e-9


def test_collision_rows_are_the_distance_rate_mujoco_measures() -> None:
    """Each active row times qd equals -d(distance)/dt, by finite differences of MuJoCo's own
    mj_geomDistance after moving the joints along qd.

    The hand is tilted off the block's axes: with the pads parallel to the block's top the
    distance is the minimum over several corners, not differentiable.
    """
    with mjk.Env.build(panda_spec(objects=[block(height=0.4)])) as env:
        robot = panda_arm(env)
        robot.set_joint_pos(robot.jnt_pos_msr + np.array([0.05, 0.1, -0.08, 0.0, 0.15, 0.1, 0.2]))
        ctrl = mjk.CartesianVelocityController(robot, avoid=[("hand", "block")])
        ctrl.solve(np.zeros(6))
        n = robot.n_joints
        active = np.flatnonzero(ctrl._bu[n:] < 1e29)
        assert len(active) >= 5
        model, data = env.model, env.data
        pairs = [ctrl._pair_list[i] for i in active]
        q0 = robot.jnt_pos_msr.copy()
        rng = np.random.default_rng(5)
        eps = 1e-6
        for _ in range(3):
            qd = rng.normal(size=n)
            before = [mujoco.mj_geomDistance(model, data, a, b, 1.0, None) for a, b in pairs]
            robot.set_joint_pos(q0 + eps * qd)
            after = [mujoco.mj_geomDistance(model, data, a, b, 1.0, None) for a, b in pairs]
            robot.set_joint_pos(q0)
            rate = (np.array(after) - np.array(before)) / eps
            np.testing.assert_allclose(-ctrl._A[active] @ qd, rate, atol=1e-4 * np.abs(qd).max())


def test_closed_scene_makes_the_controller_raise() -> None:
    env = mjk.Env.build(panda_spec())
    robot = panda_arm(env)
    ctrl = mjk.CartesianVelocityController(robot)
    env.close()
    for call in (
        lambda: ctrl.solve(np.zeros(6)),
        lambda: ctrl.command(np.zeros(6)),
        ctrl.frame_rotation,
    ):
        with pytest.raises(RuntimeError, match="closed"):
            call()


@pytest.mark.parametrize("mode", MODES, ids=lambda m: m.name)
def test_gen3_with_its_2f85_tracks_on_its_authored_servos(tutorial_scene, mode) -> None:
    """The tutorial's Gen3 (TCP at the 2F-85's pinch site), on Menagerie's own actuators."""
    env = tutorial_scene(mjk.Env)
    robot = env.create_robot("base_link", "bracelet_link", tool=gripper_tool())
    env.on_reset = lambda ctx: robot.set_joint_pos(HOME, call_forward=False)
    robot.ctrl_mode = mode
    env.reset()
    robot.update()
    ctrl = mjk.CartesianVelocityController(robot)
    start = robot.fk_frame()
    drive(robot, ctrl, [0.0, 0.05, -0.03, 0.0, 0.0, 0.0], 2.0)
    drive(robot, ctrl, np.zeros(6), SERVO_LAG)
    end = robot.fk_frame()
    np.testing.assert_allclose(end.translation - start.translation, [0, 0.1, -0.06], atol=0.005)
    assert rotation_deg(start, end) < 2.0


@pytest.fixture(scope="module")
def panda_for_properties():
    with mjk.Env.build(panda_spec()) as env:
        yield panda_arm(env)


@settings(max_examples=60, deadline=None, derandomize=True)
@given(
    q=st.lists(st.floats(0.0, 1.0), min_size=7, max_size=7),
    twist=st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6),
    dt=st.sampled_from([0.002, 0.02, 0.1]),
)
def test_any_state_and_twist_give_a_bounded_finite_answer(panda_for_properties, q, twist, dt):
    """Anywhere in the joint box, for any twist: finite, within the velocity limits, and one
    period (at least the limit horizon) at that velocity stays inside the position limits."""
    robot = panda_for_properties
    lower, upper = robot.joint_limits.T
    # Clipped: lower + 1.0 * (upper - lower) can round one ulp past the upper limit.
    robot.set_joint_pos(np.clip(lower + np.array(q) * (upper - lower), lower, upper))
    robot.update()
    ctrl = mjk.CartesianVelocityController(robot, max_joint_acceleration=None)
    qd = ctrl.solve(twist, dt=dt)
    assert ctrl.last_status is mjk.SolveStatus.OPTIMAL
    assert np.isfinite(qd).all()
    assert np.all(np.abs(qd) <= ctrl.velocity_limits + 1e-9)
    ahead = robot.jnt_pos_msr + qd * max(dt, 0.05)
    assert np.all(ahead <= upper + 1e-12) and np.all(ahead >= lower - 1e-12)


def test_two_arms_driven_into_each_other_keep_the_margin() -> None:
    """Each arm's controller avoids the other's hand; both hands are pushed together."""
    arms = [
        mjk.RobotSpec(path=menagerie("franka_emika_panda"), prefix=prefix, pos=[0.0, y, 0.0])
        for prefix, y in (("a_", 0.3), ("b_", -0.3))
    ]
    with mjk.Env.build(base_spec(robots=arms)) as env:
        robots, ctrls = {}, {}
        for prefix in ("a_", "b_"):
            robot = env.create_robot(
                "link0", "hand", prefix=prefix, tool=mjk.ToolFrameSpec(tcp_pos=PANDA_TCP)
            )
            robot.ctrl_mode = mjk.CtrlMode.POSITION
            robots[prefix] = robot
        env.on_reset = lambda ctx: [r.set_joint_pos(PANDA_HOME, False) for r in robots.values()]
        env.reset()
        for prefix, other in (("a_", "b_"), ("b_", "a_")):
            robots[prefix].update()
            ctrls[prefix] = mjk.CartesianVelocityController(
                robots[prefix], avoid=[(f"{prefix}hand", f"{other}hand")], min_distance=0.06
            )
        model = env.model
        hands = [subtree_geoms(model, env.body_id(f"{p}hand")) for p in ("a_", "b_")]
        closest = np.inf
        for _ in range(round(4.0 / env.timestep())):
            for prefix, vy in (("a_", -0.1), ("b_", 0.1)):
                robots[prefix].update()
                ctrls[prefix].command([0.0, vy, 0.0, 0.0, 0.0, 0.0])
            env.step()
            env.forward()
            closest = min(closest, hand_block_distance(env, *hands))
        assert 0.06 - 5e-4 <= closest < 0.065


def test_acceleration_window_restarts_after_a_reset(panda_env) -> None:
    robot = panda_arm(panda_env)
    ctrl = mjk.CartesianVelocityController(robot)  # 10 rad/s² by default
    step = 10.0 * panda_env.timestep()
    twist = [0.3, 0.0, 0.0, 0.0, 0.0, 0.0]
    first = ctrl.command(twist)
    assert np.abs(first).max() == pytest.approx(step)  # from rest: one window
    drive(robot, ctrl, twist, 0.2)
    assert np.abs(ctrl.solve(twist)).max() > 20 * step  # up to speed
    panda_env.reset()  # the clock goes back: taken for a reset
    robot.update()
    assert np.abs(ctrl.solve(twist)).max() == pytest.approx(step)
    drive(robot, ctrl, twist, 0.2)
    # A reset to the same time (a one-step episode) is not visible: reset() says so.
    panda_env.data.qvel[:] = 0.0  # back at rest, at the same time
    robot.set_joint_pos(PANDA_HOME)
    robot.sync_commands()
    robot.update()
    assert np.abs(ctrl.solve(twist)).max() > 20 * step  # still the old episode's speed
    ctrl.reset()
    assert np.abs(ctrl.solve(twist)).max() == pytest.approx(step, rel=1e-6)


def test_six_joint_urdf_arm_has_no_posture_task_and_tracks() -> None:
    """A UR5 from its URDF (motor actuators, VELOCITY mode): six joints, no null space."""
    arm = mjk.RobotSpec(path=example_robot_data_path("ur_description/urdf/ur5_robot.urdf"))
    with mjk.Env.build(base_spec(robots=[arm])) as env:
        robot = env.create_robot("base_link", "tool0")
        start_q = [0.3, -1.2, 1.4, -1.5, -1.57, 0.2]
        env.on_reset = lambda ctx: robot.set_joint_pos(start_q, call_forward=False)
        robot.ctrl_mode = mjk.CtrlMode.VELOCITY
        env.reset()
        robot.update()
        ctrl = mjk.CartesianVelocityController(robot)
        start = robot.fk_frame()
        drive(robot, ctrl, [0.0, 0.0, 0.05, 0.0, 0.0, 0.0], 1.0)
        end = robot.fk_frame()
        np.testing.assert_allclose(end.translation - start.translation, [0, 0, 0.05], atol=0.0025)
        assert rotation_deg(start, end) < 2.0


def test_near_singular_pose_is_damped(panda_env) -> None:
    """Arm straight up: the smallest singular value (0.04) is inside the damped zone (0.05)."""
    robot = panda_arm(panda_env)
    robot.set_joint_pos([0.0, 0.0, 0.0, -0.0698, 0.0, 0.0, 0.0])
    robot.update()
    jac = robot.jacobian()
    _, sigma, vt = np.linalg.svd(jac)
    assert sigma[5] < 0.05
    weak = jac @ vt[5]  # the twist direction J can barely produce
    weak *= 0.05 / np.linalg.norm(weak)
    plain = mjk.CartesianVelocityController(
        robot,
        singular_damping=0.0,
        damping=0.0,
        max_joint_acceleration=None,
        max_joint_velocity=100.0,
    )
    damped = mjk.CartesianVelocityController(
        robot, max_joint_acceleration=None, max_joint_velocity=100.0
    )
    fast, calm = plain.solve(weak), damped.solve(weak)
    assert np.abs(jac @ fast - weak).max() < 1e-9  # undamped: exact, at any speed
    lam = 0.05 * (1 - (sigma[5] / 0.05) ** 2) + 1e-5
    # Damped least squares along that direction: speed scaled by σ² / (σ² + λ).
    ratio = sigma[5] ** 2 / (sigma[5] ** 2 + lam)
    assert np.linalg.norm(calm) == pytest.approx(ratio * np.linalg.norm(fast), rel=1e-6)
    assert np.linalg.norm(calm) < 0.5 * np.linalg.norm(fast)


@pytest.mark.parametrize(
    ("kw", "error", "message"),
    [
        (
            {"posture": ["0"] * 7},
            mjk.SpecTypeError,
            f"posture must hold real numbers, got {['0'] * 7}",
        ),
        (
            {"posture": [True] * 7},
            mjk.SpecTypeError,
            f"posture must hold real numbers, got {[True] * 7}",
        ),
        # NumPy makes [0.0, ..., True] a float64 array: the bool must be found by looking.
        (
            {"posture": [0.0] * 6 + [True]},
            mjk.SpecTypeError,
            f"posture must hold real numbers, got {[0.0] * 6 + [True]}",
        ),
        (
            {"max_joint_velocity": ["1"] * 7},
            mjk.SpecTypeError,
            f"max_joint_velocity must hold real numbers, got {['1'] * 7}",
        ),
        (
            {"max_joint_velocity": np.full(7, 1 + 1j)},
            mjk.SpecTypeError,
            "max_joint_velocity must hold real numbers, got "
            "array([1.+1.j, 1.+1.j, 1.+1.j, 1.+1.j, 1.+1.j, 1.+1.j, 1.+1.j])",
        ),
        (
            {"max_joint_velocity": True},
            mjk.SpecTypeError,
            "max_joint_velocity must be a finite number > 0, got True",
        ),
        (
            {"max_joint_velocity": 1 + 0j},
            mjk.SpecTypeError,
            "max_joint_velocity must be a finite number > 0, got (1+0j)",
        ),
        (
            {"min_distance": "0.05"},
            mjk.SpecTypeError,
            "min_distance must be a finite number >= 0, got '0.05'",
        ),
        ({"damping": True}, mjk.SpecTypeError, "damping must be a finite number >= 0, got True"),
        (
            {"collision_gain": False},
            mjk.SpecTypeError,
            "collision_gain must be a finite number >= 0, got False",
        ),
        ({"dt": True}, mjk.SpecTypeError, "dt must be a finite number > 0, got True"),
        (
            {"max_joint_acceleration": "10"},
            mjk.SpecTypeError,
            "max_joint_acceleration must be a finite number > 0, got '10'",
        ),
        ({"damping": 1e155}, mjk.SpecError, "damping must lie in [0, 1000], got 1e+155"),
        (
            {"singular_damping": 1e4},
            mjk.SpecError,
            "singular_damping must lie in [0, 1000], got 10000.0",
        ),
        (
            {"posture": [100] * 7},
            mjk.SpecError,
            "posture[0] (joint 'joint1') must lie in [-2.8973, 2.8973], got 100",
        ),
        (
            {"posture": [*PANDA_HOME[:3], 0.5, *PANDA_HOME[4:]]},
            mjk.SpecError,
            "posture[3] (joint 'joint4') must lie in [-3.0718, -0.0698], got 0.5",
        ),
    ],
)
def test_settings_that_are_not_sane_numbers_are_refused(panda_env, kw, error, message) -> None:
    robot = panda_arm(panda_env)
    with pytest.raises(error) as err:
        mjk.CartesianVelocityController(robot, **kw)
    assert type(err.value) is error
    assert str(err.value) == message


def test_posture_setter_checks_the_joint_limits(panda_env) -> None:
    robot = panda_arm(panda_env)
    ctrl = mjk.CartesianVelocityController(robot)
    with pytest.raises(mjk.SpecError) as err:
        ctrl.posture = [*PANDA_HOME[:6], -3.0]
    assert str(err.value) == "posture[6] (joint 'joint7') must lie in [-2.8973, 2.8973], got -3"
    np.testing.assert_array_equal(ctrl.posture, PANDA_HOME)  # unchanged


@pytest.mark.parametrize("robot", [None, "link0"])
def test_controller_needs_a_robot(robot) -> None:
    with pytest.raises(TypeError) as err:
        mjk.CartesianVelocityController(robot)
    assert isinstance(err.value, mjk.SpecTypeError)
    assert str(err.value) == f"CartesianVelocityController: robot must be a Robot, got {robot!r}"


@pytest.mark.parametrize(
    "value", [np.float32(0.5), np.int64(2), np.array(0.25), 0.5, 2], ids=lambda v: repr(v)
)
def test_one_velocity_limit_of_any_real_type_applies_to_every_joint(panda_env, value) -> None:
    robot = panda_arm(panda_env)
    ctrl = mjk.CartesianVelocityController(robot, max_joint_velocity=value)
    np.testing.assert_array_equal(ctrl.velocity_limits, np.full(7, float(value)))


@pytest.mark.parametrize(
    "twist",
    [
        ["0.1", "0", "0", "0", "0", "0"],
        [True] * 6,
        [0.1, 0.0, 0.0, 0.0, 0.0, True],  # a float64 array to NumPy
        np.array([None] * 6),
        np.full(6, 0.1 + 0j),
        np.zeros(6, dtype=bool),
    ],
    ids=["text", "bools", "one-bool", "objects", "complex", "bool-array"],
)
def test_twists_that_are_not_real_numbers_are_refused(panda_env, twist) -> None:
    robot = panda_arm(panda_env)
    ctrl = mjk.CartesianVelocityController(robot)
    for call in (ctrl.solve, ctrl.command):
        with pytest.raises(mjk.SpecTypeError) as err:
            call(twist)
        assert str(err.value) == f"twist must hold real numbers, got {twist!r}"


@pytest.mark.parametrize("dt", ["0.01", True, 0.01j], ids=repr)
def test_solve_period_must_be_a_real_number(panda_env, dt) -> None:
    robot = panda_arm(panda_env)
    ctrl = mjk.CartesianVelocityController(robot)
    with pytest.raises(mjk.SpecTypeError) as err:
        ctrl.solve(np.zeros(6), dt=dt)
    assert str(err.value) == f"dt must be a finite number > 0, got {dt!r}"


@pytest.mark.parametrize("first", ["setup", "update"])
def test_a_qp_daqp_cannot_set_up_gives_zero_and_failed(panda_env, first) -> None:
    """DAQP refuses a cost it cannot factor in setup() or update() (exit flag -5); solving then
    would raise "Model has not been set up" or return NaN. The damping bound keeps such a
    cost out of reach, so it is forced here past the checks."""
    robot = panda_arm(panda_env)
    ctrl = mjk.CartesianVelocityController(robot)
    twist = np.array([0.05, 0, 0, 0, 0, 0])
    if first == "update":
        ctrl.solve(twist)
    ctrl._damping = 1e155
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        qd = ctrl.solve(twist)
    assert [str(w.message) for w in caught] == [
        "CartesianVelocityController: no solution (failed: DAQP exit flag -5); commanding zero "
        "joint velocity (reported in last_status, warned once)"
    ]
    np.testing.assert_array_equal(qd, np.zeros(7))
    assert ctrl.last_status is mjk.SolveStatus.FAILED
    ctrl._damping = 1e-5
    assert np.abs(ctrl.solve(twist)).max() > 0.0
    assert ctrl.last_status is mjk.SolveStatus.OPTIMAL


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        (
            {"control_frame": "hand\x00junk"},
            "no site or body named 'hand\\x00junk' in the scene (control_frame); "
            "close matches: hand",
        ),
        (
            {"avoid": [("hand\x00junk", "link0")]},
            "no body named 'hand\\x00junk' in the scene (avoid pair 'hand\\x00junk', 'link0'); "
            "close matches: hand",
        ),
    ],
)
def test_names_with_a_nul_byte_are_not_found(panda_env, kw, message) -> None:
    """MuJoCo would read 'hand\\0junk' as 'hand' (C strings end at the NUL)."""
    robot = panda_arm(panda_env)
    with pytest.raises(mjk.UnknownNameError) as err:
        mjk.CartesianVelocityController(robot, **kw)
    assert str(err.value) == message
