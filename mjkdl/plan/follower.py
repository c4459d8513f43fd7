"""Execution of a `JointTrajectory` on a robot, with feed-forward so the arm does not lag.

POSITION mode: a servo's joint torque is K (u - q) - D q̇ (stiffness K, damping D from the
actuator), so a setpoint u = q_d alone trails a moving target by D/K (0.1 s on Menagerie's
Panda). The follower writes

    u = q_d + (D / K) q̇_d + (τ_d - g(q)) / K

with τ_d the inverse dynamics of the desired motion (plus the joints' own damping): the servo
then applies τ_d + K e + D ė, and the robot's gravity feed-forward supplies g(q).
TORQUE mode: computed torque, τ = M(q) (q̈_d + Kp e + Kd ė) + h(q, q̇) + damping q̇, the gains
those of a critically damped `bandwidth` in every joint.

Settling: `run` goes on holding the goal after the trajectory's end until every joint is
within `settle_tolerance` of it (or the arm is at rest, or `settle` seconds have passed), so
the arm stops on the goal rather than wherever the servos' lag left it; `final_error` says
how far it ended.

Reporting: the largest joint error while playing is kept (`max_error`, with the joint and
time: `max_error_joint`, `max_error_time`), and `run` warns when it passes
`report_tracking_error` (10 mrad by default): a trajectory the arm cannot follow (limits
beyond what its actuators deliver, soft servos) does not go unnoticed.

Watching: with `max_tracking_error` (rad) or `max_contact_force` (N) set, the follower stops
the arm (holds it where it is measured) when a joint lags the trajectory by more, or when a
contact of the arm's bodies with anything (other than `allowed_contacts`) pushes harder;
`stop` says when, where and why, and a `MotionPlanner` can plan on from there.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from ..control.cartesian import _number, _pair_names
from ..errors import SpecError, SpecTypeError
from ..names import model_id
from ..robot import Robot
from ..spec import CtrlMode
from .trajectory import JointTrajectory

# `run` holds the goal after the trajectory's end until every joint is this close (rad), for
# at most SETTLE seconds.
SETTLE_TOLERANCE = 0.001
SETTLE = 3.0
# ... or until no joint moves faster than this (rad/s): at rest short of the goal.
SETTLE_SPEED = 1e-3
# `run` warns when a joint lags the trajectory by more than this (rad).
REPORT = 0.01


@dataclass(frozen=True)
class FollowerStop:
    """Why and where a watching follower stopped the arm: `time` (s into the trajectory),
    the measured joint positions `q`, `reason` ("tracking" or "contact") and a message."""

    time: float
    q: np.ndarray
    reason: str
    message: str


class TrajectoryFollower:
    """Plays `JointTrajectory`s on `robot`, in POSITION or TORQUE mode.

    `bandwidth` (Hz): the computed-torque loop's stiffness in TORQUE mode. `start_tolerance`
    (rad): how far the robot may be from a trajectory's first point when it starts.
    `max_tracking_error` (rad, any joint), `max_contact_force` (N, normal force of one
    contact): stop the arm beyond them (None: not watched); `allowed_contacts`: pairs of
    body names whose contacts are expected (fingers and a grasped cube).
    `settle_tolerance` (rad): how close to the goal `run` waits for the arm to come.
    `report_tracking_error` (rad; None: quiet): `run` warns when a joint lagged more.
    Per step: `robot.update()`, `follower.command()`, `robot.step()` — or `run(trajectory)`.
    """

    def __init__(
        self,
        robot: Robot,
        *,
        bandwidth: float = 10.0,
        start_tolerance: float = 0.05,
        max_tracking_error: float | None = None,
        max_contact_force: float | None = None,
        allowed_contacts: Sequence[tuple[str, str]] = (),
        settle_tolerance: float = SETTLE_TOLERANCE,
        report_tracking_error: float | None = REPORT,
    ) -> None:
        if not isinstance(robot, Robot):
            raise SpecTypeError(f"TrajectoryFollower: robot must be a Robot, got {robot!r}")
        self._settle_tolerance = _number(settle_tolerance, "settle_tolerance", positive=True)
        self._report = (
            None
            if report_tracking_error is None
            else _number(report_tracking_error, "report_tracking_error", positive=True)
        )
        self._robot = robot
        self._n = robot.n_joints
        self._max_error = (
            None
            if max_tracking_error is None
            else _number(max_tracking_error, "max_tracking_error", positive=True)
        )
        self._max_force = (
            None
            if max_contact_force is None
            else _number(max_contact_force, "max_contact_force", positive=True)
        )
        self._allowed_names = _pair_names(allowed_contacts, "allowed_contacts")
        self._force = np.zeros(6)
        self._error = np.zeros(self._n)
        self.stop: FollowerStop | None = None
        omega = 2.0 * math.pi * _number(bandwidth, "bandwidth", positive=True)
        self._kp, self._kd = omega * omega, 2.0 * omega
        self._tolerance = _number(start_tolerance, "start_tolerance")
        self._trajectory: JointTrajectory | None = None
        self._t0 = 0.0
        self._q, self._qd, self._qdd = np.zeros(self._n), np.zeros(self._n), np.zeros(self._n)
        self._u = np.zeros(self._n)
        self.max_error = 0.0  # largest joint error (rad) seen since `start`
        self.max_error_joint = ""  # where and when (s into the trajectory) it was
        self.max_error_time = 0.0
        self.final_error = math.nan  # largest joint distance (rad) from the goal after `run`

    @property
    def trajectory(self) -> JointTrajectory | None:
        """The trajectory being played (None before `start`)."""
        return self._trajectory

    @property
    def finished(self) -> bool:
        """Whether the scene's clock has passed the end of the trajectory."""
        if self._trajectory is None or self.stop is not None:
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
        if self._max_force is not None:
            self._watch_bodies(robot)
        self._trajectory = trajectory
        self._t0 = robot.scene.time()
        self.max_error = 0.0
        self.max_error_joint = ""
        self.max_error_time = 0.0
        self.stop = None

    def _watch_bodies(self, robot: Robot) -> None:
        """Which bodies the arm moves and which body pairs may touch (per scene model)."""
        model = robot.scene.model
        root = int(model.joint(robot.joint_names[0]).bodyid[0])
        arm = np.zeros(model.nbody, dtype=bool)
        arm[root] = True
        for b in range(root + 1, model.nbody):
            arm[b] = arm[model.body_parentid[b]]
        self._arm = arm
        allowed = np.zeros((model.nbody, model.nbody), dtype=bool)
        for i, (first, second) in enumerate(self._allowed_names):
            where = f"allowed_contacts[{i}]"
            ia = model_id(model, mujoco.mjtObj.mjOBJ_BODY, "body", first, where)
            ib = model_id(model, mujoco.mjtObj.mjOBJ_BODY, "body", second, where)
            allowed[ia, ib] = allowed[ib, ia] = True
        self._allowed = allowed

    def command(self) -> None:
        """Write the commands for the scene's time now (after `robot.update()`)."""
        trajectory = self._trajectory
        if trajectory is None:
            raise RuntimeError("TrajectoryFollower.command: call start(trajectory) first")
        robot = self._robot
        q, qd, qdd = self._q, self._qd, self._qdd
        q_msr = robot.jnt_pos_msr
        if self.stop is None:
            t = robot.scene.time() - self._t0
            trajectory.sample_into(t, q, qd, qdd)
            error = self._error
            np.subtract(q, q_msr, out=error)
            np.abs(error, out=error)
            i = int(error.argmax())
            if error[i] > self.max_error:
                self.max_error = float(error[i])
                self.max_error_joint = robot.joint_names[i]
                self.max_error_time = t
            self._watch(q_msr)
        if self.stop is not None:  # hold the arm where it stopped
            np.copyto(q, self.stop.q)
            qd[:] = 0.0
            qdd[:] = 0.0
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

    def _watch(self, q_msr: np.ndarray) -> None:
        """Stop when the tracking error (`_error`, this step's) or a contact force passes
        its bound."""
        robot = self._robot
        t = robot.scene.time() - self._t0
        if self._max_error is not None:
            error = self._error
            i = int(error.argmax())
            if error[i] > self._max_error:
                self.stop = FollowerStop(
                    t,
                    q_msr.copy(),
                    "tracking",
                    f"joint {robot.joint_names[i]!r} lagged {error[i]:.4f} rad behind the "
                    f"trajectory at t={t:.3f} s (max_tracking_error {self._max_error:g})",
                )
                return
        if self._max_force is None:
            return
        model, data = robot.scene.model, robot.scene.data
        arm, allowed, force = self._arm, self._allowed, self._force
        for k in range(data.ncon):
            contact = data.contact[k]
            b1, b2 = model.geom_bodyid[contact.geom1], model.geom_bodyid[contact.geom2]
            if not (arm[b1] or arm[b2]) or allowed[b1, b2]:
                continue
            mujoco.mj_contactForce(model, data, k, force)
            if force[0] > self._max_force:
                self.stop = FollowerStop(
                    t,
                    q_msr.copy(),
                    "contact",
                    f"bodies {model.body(b1).name!r} and {model.body(b2).name!r} touched with "
                    f"{force[0]:.1f} N at t={t:.3f} s (max_contact_force {self._max_force:g})",
                )
                return

    def run(
        self,
        trajectory: JointTrajectory,
        after_step: Callable[[], None] | None = None,
        *,
        settle: float = SETTLE,
    ) -> float:
        """Play `trajectory` to its end, or until the follower stops the arm (update,
        command, step), then hold the goal until every joint is within `settle_tolerance`
        of it or `settle` seconds have passed; the largest joint error while playing
        (`final_error`: the distance from the goal at the end)."""
        settle = _number(settle, "settle")
        self.start(trajectory)
        robot = self._robot
        while not self.finished:
            robot.update()
            self.command()
            robot.step()
            if after_step is not None:
                after_step()
        goal = trajectory.positions[-1]
        until = robot.scene.time() + settle
        robot.update()
        while self.stop is None and robot.scene.time() < until:
            if np.abs(robot.jnt_pos_msr - goal).max() <= self._settle_tolerance:
                break
            if np.abs(robot.jnt_vel_msr).max() < SETTLE_SPEED:
                break  # at rest off the goal (held by friction, a load): waiting gains nothing
            self.command()
            robot.step()
            if after_step is not None:
                after_step()
            robot.update()
        self.final_error = float(np.abs(robot.jnt_pos_msr - goal).max())
        if self._report is not None and self.stop is None and self.max_error > self._report:
            warnings.warn(
                f"TrajectoryFollower: joint {self.max_error_joint!r} lagged "
                f"{self.max_error:.4f} rad behind the trajectory at t={self.max_error_time:.3f} "
                f"s (report_tracking_error {self._report:g}); the arm ended "
                f"{self.final_error:.4f} rad from the goal. Slower timing (velocity_scaling, "
                "acceleration_scaling), torque limits or stiffer servos track closer",
                stacklevel=2,
            )
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
