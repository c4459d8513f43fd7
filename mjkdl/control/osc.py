"""Operational-space control: a TCP pose target becomes joint torques (robosuite's OSC_POSE).

Each call, at the measured state, with J the world-aligned TCP Jacobian, M the joint-space
inertia and h the bias (Coriolis, centrifugal, gravity: MuJoCo's `qfrc_bias`):

    a  = kp ∘ e - kd ∘ J q̇          e = [p_d - p, log3(R_d Rᵀ)], kd = 2 ζ √kp
    F  = Λ a                        Λ = (J M⁻¹ Jᵀ)⁻¹, or its position and orientation blocks
                                    inverted separately (`decoupled`, robosuite's default)
    τ  = Jᵀ F + Nᵀ M (kp_null (q_0 - q) - 2 √kp_null q̇) + h,   N = I - M⁻¹ Jᵀ Λ J

so the TCP behaves like a critically damped spring of stiffness kp per unit of task-space
inertia, and the posture q_0 is pulled toward in the null space of the task, unseen by it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from ..errors import SpecError, SpecTypeError
from ..robot import Robot
from ..spec import CtrlMode
from ..validate import flag
from .cartesian import _number, _vector

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_all_terms = pin.computeAllTerms
_frame_placement = pin.updateFramePlacement
_frame_jacobian = pin.getFrameJacobian
_log3 = pin.log3
_solve, _inv, _trace = np.linalg.solve, np.linalg.inv, np.trace


def _damped_inverse(A: np.ndarray) -> np.ndarray:
    """(A + δI)⁻¹ of a symmetric positive semi-definite A, δ a tiny share of its trace."""
    damped = A + np.diag(np.full(len(A), _DAMPING * _trace(A) / len(A)))
    return _inv(damped)


# J M⁻¹ Jᵀ is inverted with this fraction of its mean eigenvalue added to the diagonal, so Λ
# stays bounded at a singularity (robosuite takes a pseudo-inverse: 8x the cost here).
_DAMPING = 1e-6


class OperationalSpaceController:
    """Joint torques that pull `robot`'s TCP to a target pose (`pinocchio.SE3`, world frame).

    `kp`: stiffness, one number or six (x, y, z, rx, ry, rz; 1/s²). `damping_ratio`: one or
    six (1: critically damped). `kp_null`: the null-space posture's stiffness toward `posture`
    (default: the joint positions now). `decoupled`: invert the position and orientation blocks
    of the task-space inertia separately (robosuite's default) instead of the whole 6×6
    matrix; the coupling then goes uncompensated (on the Panda a 5 cm step turns the TCP by
    up to 2.5° instead of 0.8°).
    """

    def __init__(
        self,
        robot: Robot,
        kp: float | Sequence[float] = 150.0,
        damping_ratio: float | Sequence[float] = 1.0,
        kp_null: float = 10.0,
        posture: Sequence[float] | None = None,
        *,
        decoupled: bool = False,
    ) -> None:
        if not isinstance(robot, Robot):
            raise SpecTypeError(f"OperationalSpaceController: robot must be a Robot, got {robot!r}")
        self._robot = robot
        n = robot.n_joints
        self._kp = _six(kp, "kp")
        zeta = _six(damping_ratio, "damping_ratio")
        self._kd = 2.0 * np.sqrt(self._kp) * zeta
        self._kp_null = _number(kp_null, "kp_null")
        self._kd_null = 2.0 * math.sqrt(self._kp_null)
        self._decoupled = flag(decoupled, "decoupled")
        limits = robot.joint_limits
        if posture is None:
            self._posture = np.clip(robot.jnt_pos_msr, limits[:, 0], limits[:, 1])
        else:
            self._posture = _vector(posture, n, "posture")
        self._error = np.zeros(6)
        self._bind()

    @property
    def robot(self) -> Robot:
        """The robot this controller drives."""
        return self._robot

    @property
    def posture(self) -> np.ndarray:
        """Joint positions the null-space task pulls toward."""
        return self._posture.copy()

    @posture.setter
    def posture(self, value: Sequence[float]) -> None:
        self._posture = _vector(value, self._robot.n_joints, "posture")

    @property
    def error(self) -> np.ndarray:
        """The last call's pose error [p_d - p, log3(R_d Rᵀ)] (m, rad; world axes)."""
        return self._error.copy()

    def torques(self, target: pin.SE3) -> np.ndarray:
        """Joint torques toward `target` at the state of the last `robot.update()`; gravity
        and the other bias forces included."""
        if target.__class__ is not pin.SE3:
            raise SpecTypeError(f"target must be a pinocchio.SE3, got {target!r}")
        robot, model, data = self._robot, self._model, self._data
        self._current()
        q_all, v_all = robot.q, robot.v
        arm = self._arm
        # One pass for M (upper triangle), the Jacobians and the kinematics.
        _all_terms(model, data, q_all, v_all)
        pose = _frame_placement(model, data, self._frame)
        J = _frame_jacobian(model, data, self._frame, _LWA)[:, arm]
        q, qd = q_all[arm], v_all[arm]
        e = self._error
        np.subtract(target.translation, pose.translation, out=e[:3])
        e[3:] = _log3(target.rotation @ pose.rotation.T)
        if not math.isfinite(e.dot(e)):
            raise SpecError(f"target must be finite, got {target}")
        accel = self._kp * e - self._kd * (J @ qd)
        M = self._symmetric(data.M[self._block])
        jm = _solve(M, J.T).T  # J M⁻¹ (M is symmetric)
        inertia_inv = jm @ J.T
        inertia = _damped_inverse(inertia_inv)  # Λ = (J M⁻¹ Jᵀ)⁻¹
        if self._decoupled:
            force = np.concatenate(
                [
                    _damped_inverse(inertia_inv[:3, :3]) @ accel[:3],
                    _damped_inverse(inertia_inv[3:, 3:]) @ accel[3:],
                ]
            )
        else:
            force = inertia @ accel
        posture = M @ (self._kp_null * (self._posture - q) - self._kd_null * qd)
        # Jᵀ F + Nᵀ p with Nᵀ = I - Jᵀ Λ J M⁻¹, without forming the n×n projector.
        force -= inertia @ (jm @ posture)
        tau = J.T @ force
        tau += posture
        tau += robot.nonlinear_effects()  # MuJoCo's qfrc_bias (gravcomp accounted for)
        return tau

    def _symmetric(self, upper: np.ndarray) -> np.ndarray:
        """The symmetric matrix whose upper triangle `upper` holds (Pinocchio's CRBA)."""
        out = upper.copy()
        out[self._lower_idx] = out.T[self._lower_idx]
        return out

    def _current(self) -> None:
        """A fresh Pinocchio Data after the scene was rebuilt (the model may have changed)."""
        if self._robot.model is not self._model:
            self._bind()

    def _bind(self) -> None:
        robot = self._robot
        self._model = robot.model
        self._data = self._model.createData()
        self._frame = robot.tcp_frame_id
        self._arm = robot.arm_v
        # The arm's block of M: a slice pair, or an open mesh when the arm is not contiguous.
        arm = self._arm
        self._block = (arm, arm) if isinstance(arm, slice) else np.ix_(arm, arm)
        self._n = robot.n_joints
        self._lower_idx = np.tril_indices(self._n, -1)

    def command(self, target: pin.SE3) -> np.ndarray:
        """Write `torques(target)` to `jnt_trq_cmd` (TORQUE mode; with the robot's
        `gravity_compensation` on, less the gravity it adds itself); return the command."""
        robot = self._robot
        if robot.ctrl_mode is not CtrlMode.TORQUE:
            raise SpecError(
                f"OperationalSpaceController.command needs the robot in TORQUE mode, not "
                f"{robot.ctrl_mode.name} (set robot.ctrl_mode = CtrlMode.TORQUE)"
            )
        tau = self.torques(target)
        if robot.gravity_compensation:
            tau -= robot.gravity_torques()
        robot.jnt_trq_cmd = tau
        return tau


def _six(value: object, name: str) -> np.ndarray:
    """One non-negative number for all six task axes, or six of them."""
    if isinstance(value, (list, tuple, np.ndarray)) and np.ndim(value):
        arr = _vector(value, 6, name)
    else:
        arr = np.full(6, _number(value, name))
    if np.any(arr < 0):
        raise SpecError(f"{name} must be >= 0 on every axis, got {arr.tolist()}")
    return arr
