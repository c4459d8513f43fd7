"""Execution of a `JointTrajectory` on a robot, with feed-forward so the arm does not lag.

POSITION mode: a servo's joint torque is K (u - q) - D q̇ (stiffness K, damping D from the
actuator), so a setpoint u = q_d alone trails a moving target by D/K (0.1 s on Menagerie's
Panda). The follower writes

    u = q_d + (D / K) q̇_d + (τ_d - g(q)) / K

with τ_d the inverse dynamics of the desired motion (plus the joints' own damping): the servo
then applies τ_d + K e + D ė, and the robot's gravity feed-forward supplies g(q).
TORQUE mode: computed torque, τ = M(q) (q̈_d + Kp e + Kd ė) + h(q, q̇) + damping q̇, the gains
those of a critically damped `bandwidth` in every joint.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import mujoco
import numpy as np

from ..control.cartesian import _number
from ..errors import SpecError, SpecTypeError
from ..robot import Robot
from ..spec import CtrlMode
from .trajectory import JointTrajectory


class TrajectoryFollower:
    """Plays `JointTrajectory`s on `robot`, in POSITION or TORQUE mode.

    `bandwidth` (Hz): the computed-torque loop's stiffness in TORQUE mode. `start_tolerance`
    (rad): how far the robot may be from a trajectory's first point when it starts.
    Per step: `robot.update()`, `follower.command()`, `robot.step()` — or `run(trajectory)`.
    """

    def __init__(
        self, robot: Robot, *, bandwidth: float = 10.0, start_tolerance: float = 0.05
    ) -> None:
        if not isinstance(robot, Robot):
            raise SpecTypeError(f"TrajectoryFollower: robot must be a Robot, got {robot!r}")
        self._robot = robot
        self._n = robot.n_joints
        omega = 2.0 * math.pi * _number(bandwidth, "bandwidth", positive=True)
        self._kp, self._kd = omega * omega, 2.0 * omega
        self._tolerance = _number(start_tolerance, "start_tolerance")
        self._trajectory: JointTrajectory | None = None
        self._t0 = 0.0
        self._q, self._qd, self._qdd = np.zeros(self._n), np.zeros(self._n), np.zeros(self._n)
        self._u = np.zeros(self._n)
        self.max_error = 0.0  # largest joint error (rad) seen since `start`

    @property
    def trajectory(self) -> JointTrajectory | None:
        """The trajectory being played (None before `start`)."""
        return self._trajectory

    @property
    def finished(self) -> bool:
        """Whether the scene's clock has passed the end of the trajectory."""
        if self._trajectory is None:
            return True
        return self._robot.scene.time() - self._t0 >= self._trajectory.duration

    def start(self, trajectory: JointTrajectory) -> None:
        """Play `trajectory` from the scene's time now; the robot must be at its start."""
        if not isinstance(trajectory, JointTrajectory):
            raise SpecTypeError(
                f"TrajectoryFollower.start: expected a JointTrajectory, got {trajectory!r}"
            )
        robot = self._robot
        if trajectory.n_joints != self._n:
            raise SpecError(
                f"the trajectory has {trajectory.n_joints} joints, the robot {self._n} "
                f"({', '.join(robot.joint_names)})"
            )
        mode = robot.ctrl_mode
        if mode is CtrlMode.VELOCITY:
            raise SpecError(
                "TrajectoryFollower needs the robot in POSITION or TORQUE mode, not VELOCITY "
                "(set robot.ctrl_mode)"
            )
        robot.update()  # the mode's actuator gains are in the model from here on
        off = np.abs(robot.jnt_pos_msr - trajectory.positions[0])
        if off.max() > self._tolerance:
            i = int(off.argmax())
            raise SpecError(
                f"the trajectory starts {off[i]:.3g} rad from the robot at joint "
                f"{robot.joint_names[i]!r} (start_tolerance {self._tolerance:g}): plan from "
                "the robot's joint positions"
            )
        if mode is CtrlMode.POSITION:
            self._stiffness, self._damping = _servo_gains(robot)
        self._joint_damping = _joint_damping(robot)
        self._trajectory = trajectory
        self._t0 = robot.scene.time()
        self.max_error = 0.0

    def command(self) -> None:
        """Write the commands for the scene's time now (after `robot.update()`)."""
        trajectory = self._trajectory
        if trajectory is None:
            raise RuntimeError("TrajectoryFollower.command: call start(trajectory) first")
        robot = self._robot
        q, qd, qdd = self._q, self._qd, self._qdd
        trajectory.sample_into(robot.scene.time() - self._t0, q, qd, qdd)
        q_msr = robot.jnt_pos_msr
        self.max_error = max(self.max_error, float(np.abs(q - q_msr).max()))
        if robot.ctrl_mode is CtrlMode.TORQUE:
            accel = qdd + self._kp * (q - q_msr) + self._kd * (qd - robot.jnt_vel_msr)
            tau = robot.mass_matrix() @ accel + robot.nonlinear_effects()
            tau += self._joint_damping * robot.jnt_vel_msr
            if robot.gravity_compensation:
                tau -= robot.gravity_torques()
            robot.jnt_trq_cmd = tau
            return
        if robot.ctrl_mode is not CtrlMode.POSITION:
            raise SpecError(
                f"TrajectoryFollower: the robot is in {robot.ctrl_mode.name} mode; it was "
                "started in POSITION or TORQUE"
            )
        tau = robot.inverse_dynamics(q, qd, qdd) + self._joint_damping * qd
        if robot.gravity_feedforward:
            tau -= robot.gravity_torques()
        u = self._u
        np.multiply(self._damping, qd, out=u)
        u += tau
        u /= self._stiffness
        u += q
        robot.jnt_pos_cmd = u

    def run(
        self, trajectory: JointTrajectory, after_step: Callable[[], None] | None = None
    ) -> float:
        """Play `trajectory` to its end (update, command, step); the largest joint error."""
        self.start(trajectory)
        robot = self._robot
        while not self.finished:
            robot.update()
            self.command()
            robot.step()
            if after_step is not None:
                after_step()
        robot.update()
        return self.max_error


def _actuators(robot: Robot) -> list[int]:
    """The MuJoCo actuator driving each of the robot's joints."""
    model = robot.scene.model
    by_joint = {
        int(model.actuator_trnid[a, 0]): a
        for a in range(model.nu)
        if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
    }
    out = []
    for name in robot.joint_names:
        joint = int(model.joint(name).id)
        if joint not in by_joint:
            raise SpecError(f"POSITION mode: joint {name!r} has no actuator")
        out.append(by_joint[joint])
    return out


def _servo_gains(robot: Robot) -> tuple[np.ndarray, np.ndarray]:
    """Joint stiffness K and damping D of the robot's position servos as configured now:
    the joint torque is gear·(gain·u + b1·gear·q + b2·gear·q̇)."""
    model = robot.scene.model
    ids = _actuators(robot)
    gear = model.actuator_gear[ids, 0]
    stiffness = -model.actuator_biasprm[ids, 1] * gear * gear
    damping = -model.actuator_biasprm[ids, 2] * gear * gear
    return stiffness, damping


def _joint_damping(robot: Robot) -> np.ndarray:
    """MuJoCo's passive joint damping of the arm (its torque is -damping·q̇)."""
    model = robot.scene.model
    return np.array([model.dof_damping[model.joint(j).dofadr[0]] for j in robot.joint_names])
