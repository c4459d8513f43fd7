"""TrajectoryFollower: feed-forward closes the position servos' lag; computed torque tracks."""

from __future__ import annotations

import math
import re
import warnings

import numpy as np
import pinocchio as pin
import pytest
from conftest import (
    PANDA_HOME,
    menagerie,
    panda_arm,
    panda_spec,
    untested_arm,
    untested_robot,
)

import mjkdl as mjk
from mjkdl.plan import JointTrajectory, TrajectoryFollower

RADIUS = 0.1  # the figure eight of examples/cartesian_velocity.py: 0.2 m wide, 0.1 m tall


@pytest.fixture
def env():
    menagerie("franka_emika_panda")
    with mjk.Env.build(panda_spec()) as scene:
        yield scene


def eight(robot: mjk.Robot) -> tuple[JointTrajectory, callable]:
    """One lap (2π s) of the eight through IK every 10 ms, and the TCP path it should trace."""
    start = robot.fk_frame()
    times = np.arange(0.0, 2.0 * math.pi, 0.01)

    def path(t: np.ndarray) -> np.ndarray:
        offset = [RADIUS * np.sin(t), 0.5 * RADIUS * np.sin(2.0 * t), 0.0 * t]
        return start.translation + np.array(offset).T

    q, positions = robot.jnt_pos_msr.copy(), []
    for point in path(times):
        result = robot.ik(pin.SE3(start.rotation, point), q)
        assert result.success
        q = result.q
        positions.append(q)
    positions = np.array(positions)
    velocities = np.gradient(positions, times, axis=0)
    return JointTrajectory(
        times, positions, velocities, np.gradient(velocities, times, axis=0)
    ), path


def tcp_error(
    env: mjk.Env, robot: mjk.Robot, mode: mjk.CtrlMode, feedforward: bool = True
) -> float:
    """The largest distance of the measured TCP from the eight over one lap."""
    traj, path = eight(robot)
    follower = TrajectoryFollower(robot)
    follower.start(traj)
    t0, worst = env.time(), 0.0
    while not follower.finished:
        robot.update()
        worst = max(
            worst, float(np.linalg.norm(robot.fk_frame().translation - path(env.time() - t0)))
        )
        follower.command()
        if not feedforward:  # the plain setpoint, as a position controller would send it
            robot.jnt_pos_cmd = traj.sample(env.time() - t0)[0]
        robot.step()
    return worst


def test_position_mode_tracks_the_eight_within_3_mm_with_feedforward(env) -> None:
    robot = panda_arm(env, mjk.CtrlMode.POSITION)
    with_ff = tcp_error(env, robot, mjk.CtrlMode.POSITION)
    env.reset()
    robot.update()
    plain = tcp_error(env, robot, mjk.CtrlMode.POSITION, feedforward=False)
    assert with_ff <= 0.003
    assert plain > 5 * with_ff  # the setpoint alone trails by the servos' kv/kp = 0.1 s


def test_torque_mode_tracks_the_eight_with_computed_torque(env) -> None:
    robot = panda_arm(env, mjk.CtrlMode.TORQUE)
    assert tcp_error(env, robot, mjk.CtrlMode.TORQUE) <= 0.003


def test_torque_mode_with_gravity_compensation_does_not_add_gravity_twice(env) -> None:
    robot = panda_arm(env, mjk.CtrlMode.TORQUE)
    robot.gravity_compensation = True
    assert tcp_error(env, robot, mjk.CtrlMode.TORQUE) <= 0.003


def test_run_returns_the_largest_joint_error_and_settles_at_the_goal(env) -> None:
    robot = panda_arm(env, mjk.CtrlMode.POSITION)
    start = robot.jnt_pos_msr.copy()
    goal = start + np.array([0.3, -0.2, 0.2, 0.3, -0.3, 0.2, 0.4])
    traj = JointTrajectory([0.0, 1.0], [start, goal], np.zeros((2, 7)), np.zeros((2, 7)))
    follower = TrajectoryFollower(robot)
    error = follower.run(traj)
    assert 0.0 < error < 0.01
    # Held after the end until every joint is within settle_tolerance (1 mrad), at most 3 s.
    assert follower.final_error == pytest.approx(np.abs(robot.jnt_pos_msr - goal).max())
    assert follower.final_error <= 0.001
    assert 1.0 - 2 * env.timestep() <= env.time() <= 4.0
    with pytest.raises(mjk.SpecError, match=r"settle_tolerance must be a finite number > 0"):
        TrajectoryFollower(robot, settle_tolerance=0.0)
    with pytest.raises(mjk.SpecError, match=r"settle must be a finite number"):
        follower.run(traj, settle=math.nan)


@pytest.mark.parametrize("name", ["rizon_like", "ur10"])
def test_a_planned_trajectory_ends_at_rest_and_the_arm_stays_on_the_goal(name) -> None:
    """The timed trajectory's last knot has zero velocity and acceleration and sampling past
    its end holds the goal at rest, so the follower, holding on, adds no braking offset: the
    arm ends and stays within 2 mrad of the goal. (With the braking acceleration held, the
    Rizon-like arm drifted to 3.5 mrad from the goal in the half second after the end.)"""
    from ompl import util as ou

    from mjkdl.plan import MotionPlanner

    with untested_arm(name) as env:
        robot = untested_robot(env, name)
        goals = {
            "rizon_like": [1.2, -0.4, 0.5, 1.6, -0.7, 1.5, 1.0],
            "ur10": [1.0, -1.0, 1.0, -1.0, -1.2, 0.5],
        }
        goal = np.array(goals[name])
        ou.RNG.setSeed(1)
        n = robot.n_joints
        planner = MotionPlanner(robot, velocity_limits=[2.0] * n, acceleration_limits=[6.0] * n)
        traj = planner.plan(goal)
        assert traj.velocities[-1].tolist() == [0.0] * robot.n_joints
        assert traj.accelerations[-1].tolist() == [0.0] * robot.n_joints
        q, qd, qdd = traj.sample(traj.duration + 1.0)
        assert np.array_equal(q, goal) and not qd.any() and not qdd.any()
        follower = TrajectoryFollower(robot)
        follower.run(traj)
        assert follower.final_error <= 0.002
        for _ in range(250):  # half a second more, holding the goal
            robot.update()
            follower.command()
            robot.step()
        robot.update()
        assert np.abs(robot.jnt_pos_msr - goal).max() <= 0.002


def test_bad_use_is_refused_by_name(env) -> None:
    robot = panda_arm(env, mjk.CtrlMode.VELOCITY)
    q = robot.jnt_pos_msr
    traj = JointTrajectory([0.0, 1.0], [q, q], np.zeros((2, 7)), np.zeros((2, 7)))
    follower = TrajectoryFollower(robot)
    with pytest.raises(
        mjk.SpecError, match=r"needs the robot in POSITION or TORQUE mode, not VELOCITY"
    ):
        follower.start(traj)
    robot.ctrl_mode = mjk.CtrlMode.POSITION
    with pytest.raises(RuntimeError, match=r"call start\(trajectory\) first"):
        follower.command()
    short = JointTrajectory([0.0, 1.0], [q[:6], q[:6]], np.zeros((2, 6)), np.zeros((2, 6)))
    with pytest.raises(mjk.SpecError, match=r"the trajectory has 6 joints, the robot 7 \(joint1, "):
        follower.start(short)
    far = JointTrajectory(
        [0.0, 1.0], [q + np.array([0, 0, 0.2, 0, 0, 0, 0]), q], np.zeros((2, 7)), np.zeros((2, 7))
    )
    with pytest.raises(mjk.SpecError, match=r"starts 0.2 rad from the robot at joint 'joint3'"):
        follower.start(far)
    with pytest.raises(mjk.SpecTypeError, match=r"expected a JointTrajectory"):
        follower.start(q)
    with pytest.raises(mjk.SpecError, match=r"bandwidth must be a finite number > 0"):
        TrajectoryFollower(robot, bandwidth=0)


# ---------------------------------------------------------------------- watching


@pytest.mark.parametrize("watch", ["contact", "tracking"])
def test_a_watching_follower_stops_on_an_unexpected_block_and_the_planner_goes_on(watch) -> None:
    """A box appears on the planned path after planning: the follower stops the arm on the
    contact (or the lag it causes), says where, and a new plan from there reaches the goal."""
    from conftest import DOWN, PANDA_TCP, SHELF_TOP, shelf_objects
    from ompl import util as ou

    from mjkdl.plan import MotionPlanner

    ou.RNG.setSeed(3)
    above_a = pin.SE3(np.array(DOWN), np.array([0.45, 0.35, SHELF_TOP + 0.15]))
    above_b = pin.SE3(np.array(DOWN), np.array([0.45, -0.35, SHELF_TOP + 0.15]))
    menagerie("franka_emika_panda")
    with mjk.Env.build(panda_spec(objects=shelf_objects())) as env:
        robot = env.create_robot("link0", "hand", tool=mjk.ToolFrameSpec(tcp_pos=PANDA_TCP))
        robot.ctrl_mode = mjk.CtrlMode.POSITION
        q_a = robot.ik(above_a, np.array(PANDA_HOME)).q
        robot.set_joint_pos(q_a)
        robot.update()
        planner = MotionPlanner(robot)
        q_b = robot.ik(above_b, q_a).q
        traj = planner.plan(q_b)
        # The TCP's place a third of the way: a box appears there.
        block = robot.fk_frame(traj.sample(traj.duration / 3)[0]).translation
        env.add_object(
            mjk.SceneObject(
                name="block", shape=mjk.Shape.BOX, size=[0.03] * 3, pos=block.tolist(), fixed=True
            )
        )
        bounds = {"contact": {"max_contact_force": 20.0}, "tracking": {"max_tracking_error": 0.02}}
        follower = TrajectoryFollower(robot, **bounds[watch])
        follower.run(traj)
        stop = follower.stop
        assert stop is not None and stop.reason == watch
        assert 0.0 < stop.time < traj.duration / 3 + 0.1
        assert np.abs(stop.q - robot.jnt_pos_msr).max() < 0.01  # it stays where it stopped
        if watch == "contact":
            assert "'block'" in stop.message and "max_contact_force 20" in stop.message
        else:
            assert re.search(r"joint 'joint\d' lagged 0.0\d+ rad", stop.message)
        # On from there: the planner sees the block (and leaves the contact first).
        again = planner.plan(q_b, start_jiggle=0.15, timeout=5.0, velocity_scaling=0.5)
        assert np.abs(again.positions[0] - robot.jnt_pos_msr).max() < 1e-9
        # Pressed against the block, the arm lags as it leaves it: followed unwatched, and
        # the follower says so.
        with pytest.warns(UserWarning, match=r"joint 'joint\d' lagged 0\.\d+ rad behind"):
            error = TrajectoryFollower(robot).run(again)
        assert error < 0.3
        assert np.abs(robot.jnt_pos_msr - q_b).max() < 0.01


def test_watching_bounds_are_checked(env) -> None:
    robot = panda_arm(env, mjk.CtrlMode.POSITION)
    with pytest.raises(mjk.SpecError, match=r"max_tracking_error must be a finite number > 0"):
        TrajectoryFollower(robot, max_tracking_error=0.0)
    with pytest.raises(mjk.SpecError, match=r"max_contact_force must be a finite number > 0"):
        TrajectoryFollower(robot, max_contact_force=-1.0)
    q = robot.jnt_pos_msr
    traj = JointTrajectory([0.0, 1.0], [q, q], np.zeros((2, 7)), np.zeros((2, 7)))
    follower = TrajectoryFollower(robot, max_contact_force=5.0, allowed_contacts=[("hand", "cub")])
    with pytest.raises(mjk.UnknownNameError, match=r"no body named 'cub' in allowed_contacts\[0\]"):
        follower.start(traj)


def test_torque_aware_timing_keeps_a_weak_arm_on_track_and_the_follower_reports_when_not() -> None:
    """The Rizon-like arm's actuators limited to a few N·m (6 N·m at the base): timed under
    velocity and acceleration limits alone, the motion asks for more, the servos saturate
    and the arm lags by 0.78 rad; the follower says so. Given the same torque limits
    (`RobotLimits.effort`), the timing keeps them and the arm lags 18 mrad at most."""
    from mjkdl.plan import MotionPlanner, RobotLimits

    goal = np.array([1.2, -0.4, 0.5, 1.6, -0.7, 1.5, 1.0])
    effort = np.array([6.0, 24.0, 6.0, 14.0, 2.0, 2.0, 2.0])
    fast = {"velocity_limits": [3.0] * 7, "acceleration_limits": [20.0] * 7}
    errors = []
    for torque_aware in (False, True):
        with untested_arm("rizon_like") as env:
            robot = untested_robot(env, "rizon_like")
            env.model.actuator_forcelimited[:] = 1
            env.model.actuator_forcerange[:] = np.column_stack([-effort, effort])
            limits = RobotLimits(effort=dict(zip(robot.joint_names, effort.tolist(), strict=True)))
            planner = MotionPlanner(robot, limits=limits if torque_aware else None, **fast)
            assert ("torque: RobotLimits" in planner.limits_source) == torque_aware
            traj = planner.plan(goal)
            follower = TrajectoryFollower(robot)
            if torque_aware:
                quiet = TrajectoryFollower(robot, report_tracking_error=0.05)
                with warnings.catch_warnings():
                    warnings.simplefilter("error")
                    quiet.run(traj)
                errors.append(quiet.max_error)
                assert quiet.final_error <= 0.002
                continue
            with pytest.warns(
                UserWarning,
                match=r"joint 'joint\d' lagged 0\.\d+ rad behind the trajectory at t=0\.\d+ s "
                r"\(report_tracking_error 0\.01\); the arm ended 0\.\d+ rad from the goal",
            ):
                follower.run(traj)
            errors.append(follower.max_error)
            assert follower.max_error_joint.startswith("joint")
    assert errors[0] > 0.3
    assert errors[1] < 0.03


def test_run_stops_settling_when_the_arm_is_at_rest_short_of_the_goal() -> None:
    """The Rizon-like arm's wrist joint held by 1 N·m of dry friction, its actuator limited
    to 0.5 N·m: it cannot follow, and `run` returns once the arm is at rest instead of
    waiting out the 3 s of settling; `final_error` says how short it stopped."""
    with untested_arm("rizon_like") as env:
        robot = untested_robot(env, "rizon_like")
        model = env.model
        model.dof_frictionloss[model.joint("joint5").dofadr[0]] = 1.0
        wrist = model.actuator("a5").id
        model.actuator_forcelimited[wrist] = 1
        model.actuator_forcerange[wrist] = [-0.5, 0.5]
        start = robot.jnt_pos_msr.copy()
        goal = start + np.array([0.0, 0.0, 0.0, 0.0, 0.3, 0.0, 0.0])
        zeros = np.zeros((2, 7))
        traj = JointTrajectory([0.0, 1.0], [start, goal], zeros, zeros)
        follower = TrajectoryFollower(robot, report_tracking_error=None)
        began = env.time()
        follower.run(traj)
        assert follower.final_error > 0.01
        assert env.time() - began < 1.0 + 0.5  # not the whole 3 s of settling
