"""Operational-space control: a TCP pose target becomes joint torques (robosuite's OSC_POSE).

Each call, at the measured state, with J the world-aligned TCP Jacobian, M the joint-space
inertia and h the bias (Coriolis, centrifugal, gravity: MuJoCo's `qfrc_bias`):

    a  = kp ∘ e - kd ∘ J q̇          e = [p_d - p, log3(R_d Rᵀ)], kd = 2 ζ √kp
    F  = Λ a                        Λ = (J M⁻¹ Jᵀ)⁻¹, or its position and orientation blocks
                                    inverted separately (`decoupled`, robosuite's default)
    τ  = Jᵀ F + Nᵀ M (kp_null (q_0 - q) - 2 √kp_null q̇) + h,   N = I - M⁻¹ Jᵀ Λ J

so the TCP behaves like a critically damped spring of stiffness kp per unit of task-space
inertia, and the posture q_0 is pulled toward in the null space of the task, unseen by it.

With p the posture acceleration, Nᵀ M p = M p - Jᵀ Λ J p, so τ = Jᵀ Λ (a - J p) + M p + h: one
Pinocchio pass (CRBA, which also places the joints and fills their Jacobians), one RNEA for h,
two LAPACK Cholesky solves (M, then the damped J M⁻¹ Jᵀ), all in preallocated buffers.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pinocchio as pin
from scipy.linalg import lapack

from ..errors import MjkdlError, SimulationError, SpecError, SpecTypeError
from ..robot import Robot
from ..spec import CtrlMode
from ..validate import flag
from .cartesian import _number, _vector

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_WORLD = pin.Convention.WORLD
_crba = pin.crba
_frame_placement = pin.updateFramePlacement
_frame_jacobian = pin.getFrameJacobian
_log3 = pin.log3
_posv = lapack.dposv  # Cholesky solve of a symmetric positive definite system, in place
_subtract, _multiply, _dot, _vdot = np.subtract, np.multiply, np.dot, np.vdot
_add, _sum = np.add, np.add.reduce
_isfinite, _hypot = math.isfinite, math.hypot  # on Python floats: half a NumPy dot

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
        # Rows: the pose error e, J q̇ and J (q_0 - q). Both right-hand sides of the task
        # force, b = kp e - kd J q̇ - J p with p = kp_null (q_0 - q) - kd_null q̇, are
        # weighted sums of these rows (`_gains`); decoupled keeps J p apart (second row).
        self._rows = np.zeros((3, 6))
        self._error = self._rows[0]
        zero, kd0, kp0 = np.zeros(6), np.full(6, self._kd_null), np.full(6, self._kp_null)
        if self._decoupled:  # kp e - kd J q̇ and -J p
            gains = [[self._kp, -self._kd, zero], [zero, kd0, -kp0]]
        else:
            gains = [[self._kp, kd0 - self._kd, -kp0]]
        self._gains = np.array(gains)
        self._weighted = np.zeros_like(self._gains)
        self._rhs = np.zeros((len(gains), 6))
        self._lam_inv = np.zeros((6, 6))  # J M⁻¹ Jᵀ, then damped
        self._blocks = np.zeros((6, 6))  # its two diagonal 3×3 blocks, damped (decoupled)
        self._rot = np.zeros((3, 3))
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
        and the other bias forces included. A new array each call."""
        if target.__class__ is not pin.SE3:
            raise SpecTypeError(f"target must be a pinocchio.SE3, got {target!r}")
        if self._robot.model is not self._model:
            self._bind()  # the scene was rebuilt: the model may have changed
        model, data, frame = self._model, self._data, self._frame
        # One pass for M (the Python binding fills both triangles) and, in the WORLD
        # convention, the joint placements and Jacobians the frame's pose and J read.
        M, J = self._M, self._J
        M[...] = _crba(model, data, self._q_all, _WORLD)[self._m_block]
        pose = _frame_placement(model, data, frame)
        J[...] = _frame_jacobian(model, data, frame, _LWA)[self._j_block]
        rows = self._rows
        _subtract(target.translation, pose.translation, out=self._error_pos)
        _dot(target.rotation, pose.rotation.T, out=self._rot)
        self._error_rot[...] = _log3(self._rot)
        state = self._state  # q̇, q_0 - q
        state[0] = self._qd
        _subtract(self._posture, self._q, out=self._offset)
        _dot(state, J.T, out=self._velocity_rows)
        _multiply(self._gains, rows, out=self._weighted)
        rhs = _sum(self._weighted, axis=1, out=self._rhs)
        tau = _dot(M, _dot(self._null_gains, state, out=self._p), out=self._tau)  # M p
        # Λ⁻¹ = J M⁻¹ Jᵀ: M's Cholesky factor overwrites M, M⁻¹ Jᵀ overwrites a copy of Jᵀ
        # (M is symmetric, so its C-ordered buffer is also its Fortran-ordered transpose).
        jm = self._jm
        jm[...] = J
        if _posv(M.T, jm.T, overwrite_a=1, overwrite_b=1)[2]:
            raise self._not_positive_definite("the arm's mass matrix M", "links without mass?")
        lam_inv = _dot(jm, J.T, out=self._lam_inv)
        if self._decoupled:
            # Position and orientation blocks inverted apart for the task force; the
            # null-space term keeps the whole Λ.
            blocks = self._blocks
            blocks[:3, :3] = lam_inv[:3, :3]
            blocks[3:, 3:] = lam_inv[3:, 3:]
            diag = self._blocks_diag
            diag[:3] += _vdot(jm[:3], J[:3]) * (_DAMPING / 3)  # traces of the blocks
            diag[3:] += _vdot(jm[3:], J[3:]) * (_DAMPING / 3)
            if _posv(blocks.T, rhs[0], overwrite_a=1, overwrite_b=1)[2]:
                raise self._not_positive_definite("J M⁻¹ Jᵀ", "a TCP no joint moves?")
        self._lam_inv_diag += _vdot(jm, J) * (_DAMPING / 6)  # tr(J M⁻¹ Jᵀ)
        if _posv(lam_inv.T, rhs[-1], overwrite_a=1, overwrite_b=1)[2]:
            raise self._not_positive_definite("J M⁻¹ Jᵀ", "a TCP no joint moves?")
        force = _sum(rhs, axis=0, out=self._force) if self._decoupled else rhs[0]
        # τ = Jᵀ F + Nᵀ M p + h = Jᵀ Λ (a - J p) + M p + h  (J M⁻¹ M p = J p).
        tau += _dot(force, J, out=self._jf)
        tau = _add(tau, self._robot.nonlinear_effects())  # MuJoCo's qfrc_bias (gravcomp out)
        if not _isfinite(_hypot(*tau.tolist())):  # a target or a state that is not finite
            raise self._not_finite(target)
        return tau

    def _not_finite(self, target: pin.SE3) -> MjkdlError:
        """The error for torques that are not finite: the target's, else the state's."""
        if not (np.isfinite(target.translation).all() and np.isfinite(target.rotation).all()):
            return SpecError(f"target must be finite, got {target}")
        robot = self._robot
        return SimulationError(
            f"OperationalSpaceController: the torques at the measured state are not finite "
            f"(q = {robot.jnt_pos_msr.tolist()}, q̇ = {robot.jnt_vel_msr.tolist()}); has the "
            "simulation diverged?",
            robot.last_update_time,
            {},
        )

    def _not_positive_definite(self, what: str, hint: str) -> SpecError:
        return SpecError(
            f"OperationalSpaceController: {what} is not positive definite at the measured "
            f"q = {self._robot.jnt_pos_msr.tolist()} ({hint})"
        )

    def _bind(self) -> None:
        """Index arrays and buffers for `robot`'s current Pinocchio model."""
        robot = self._robot
        model = robot.model
        self._model = model
        self._data = model.createData()
        self._frame = robot.tcp_frame_id
        n = robot.n_joints
        arm = robot.arm_v
        # The arm's block of M and columns of J: slices, or an open mesh (a copy each call)
        # when the arm is not contiguous in v.
        self._m_block = (arm, arm) if isinstance(arm, slice) else np.ix_(arm, arm)
        self._j_block = (slice(None), arm)
        # Live read-only views of the robot's state, valid until the scene is rebuilt.
        self._q_all, self._q, self._qd = robot.q, robot.jnt_pos_msr, robot.jnt_vel_msr
        self._M, self._J, self._jm = np.zeros((n, n)), np.zeros((6, n)), np.zeros((6, n))
        self._state = np.zeros((2, n))
        self._offset = self._state[1]
        self._null_gains = np.array([-self._kd_null, self._kp_null])  # p from the state rows
        self._p, self._tau, self._jf = np.zeros(n), np.zeros(n), np.zeros(n)
        self._error_pos, self._error_rot = self._error[:3], self._error[3:]
        self._velocity_rows = self._rows[1:]
        self._lam_inv_diag = self._lam_inv.reshape(-1)[::7]
        self._blocks_diag = self._blocks.reshape(-1)[::7]
        self._force = np.zeros(6)

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
