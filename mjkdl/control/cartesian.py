"""Cartesian velocity control: a TCP twist becomes joint velocities through one small QP.

Every call solves, for the joint velocities qd of the arm,

    minimise   |J qd - v|² + λ(σ) |qd|² + w |N (qd - k (q_ref - q))|²
    subject to lb <= qd <= ub       (position, velocity and acceleration limits, for period dt)
               n_iᵀ (J_a,i - J_b,i) qd <= k_c (d_i - d_min) + n_iᵀ (u_b,i - u_a,i)
                                                             (each close geom pair)

with J the robot's world-aligned TCP Jacobian, v the twist rotated from the control frame into
the world, λ a damping that grows as the smallest singular value of J falls (Levenberg-Marquardt
style), N the projector onto the null space of J (the posture task cannot disturb the twist)
and the last rows velocity dampers between geoms that should stay apart (u: the points'
measured velocity from joints that are not the robot's). DAQP solves it
(see docs/control.md for the measurements behind that choice).
"""

from __future__ import annotations

import enum
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import daqp
import mujoco
import numpy as np
from numpy.typing import ArrayLike
from scipy.linalg.lapack import dsyev as _dsyev

from ..errors import SpecError, SpecTypeError, unknown_name
from ..names import find_id, model_id
from ..robot import Robot
from ..spec import CtrlMode
from ..validate import real, real_array

# DAQP treats bounds at or beyond this magnitude as absent.
_INF = 1e30
# Model velocity limits at or above this (rad/s or m/s) stand for "none".
_NO_LIMIT = 1e6
# Largest damping or singular_damping: beyond it the twist is barely tracked (scaled by
# σ²/(σ² + λ) < 1e-3 for σ <= 1), and near 1e100 DAQP can no longer factor the cost.
_MAX_DAMPING = 1e3


class SolveStatus(enum.Enum):
    """Outcome of the last `CartesianVelocityController.solve`."""

    OPTIMAL = "optimal"
    INFEASIBLE = "infeasible"  # the constraints cannot all hold: zero velocity was returned
    FAILED = "failed"  # the solver stopped without a solution (or the state held NaN): zero


@dataclass(frozen=True)
class CartesianSettings:
    """The terms and bounds a `CartesianVelocityController` solves with, as resolved at
    construction (per-joint arrays in chain order, copies): what a re-implementation of the
    same QP (the batched backend's) needs to solve the same problem."""

    joint_lower: np.ndarray
    """Lower joint position limits."""
    joint_upper: np.ndarray
    """Upper joint position limits."""
    max_joint_velocity: np.ndarray
    """Per-joint velocity bounds (the model's where given, else the constructor's)."""
    max_joint_acceleration: float
    """Joint acceleration bound (inf: none)."""
    limit_gain: float
    """Share of the gap to a position limit one period may close."""
    limit_horizon: float
    """Shortest period the position-limit bounds assume, s."""
    posture: np.ndarray
    """Null-space posture target."""
    posture_gain: float
    """Gain of the posture task, 1/s."""
    damping: float
    """Weight of |qd|² in the cost."""
    singular_damping: float
    """Damping added as the smallest singular value of J falls below the threshold."""
    singular_threshold: float
    """Smallest singular value of J below which damping grows."""


class CartesianVelocityController:
    """Joint velocities that make a robot's TCP move with a commanded twist.

    The twist `[vx, vy, vz, wx, wy, wz]` is the TCP's linear velocity (of the TCP point) and
    angular velocity, both along the axes of `control_frame` (a site or body name; "" is the
    world). The frame is read afresh on every call, so it may move (a site on a turning
    torso). `solve` uses the robot's state as of its last `update()`.

    Limits, all hard constraints of the QP:

    * joint positions are never crossed: the velocity bounds shrink as a limit nears, so one
      period at the bound closes `limit_gain` of the remaining gap (the period taken as at
      least `limit_horizon`, so servos that lag their command do not overshoot);
    * joint velocities: the model's (`robot.model.velocityLimit`) where positive and below
      1e6 (Pinocchio marks "none" with inf or the largest double), else `max_joint_velocity`;
    * joint accelerations: the velocity changes by at most `max_joint_acceleration * dt`
      between solutions (None: unlimited), so a servo is never handed a step;
    * `avoid=[(body_a, body_b), ...]`: every collision geom of body_a's subtree stays at least
      `min_distance` from those of body_b's; once a pair is closer than `influence_distance`
      its approach speed is capped at `collision_gain * (d - min_distance)`.

    The other terms: `damping` (λ, the weight of |qd|²) plus up to `singular_damping`
    once the smallest singular value of J falls below `singular_threshold` (both at most 1e3);
    a posture task in the null space of J pulling toward `posture` (default: the pose now;
    within the joints' position limits) at `posture_gain` (1/s). A single
    `max_joint_velocity` applies to every joint. `influence_distance` defaults to
    `min_distance + 0.1`; `dt`, the period the bounds are computed for, defaults to the
    scene's timestep. docs/control.md has the formulation.

    When the constraints cannot all hold (an infeasible QP) or DAQP fails, `solve` returns
    zero velocity, sets `last_status` and warns once; it never raises for that.
    """

    def __init__(
        self,
        robot: Robot,
        control_frame: str = "",
        avoid: Sequence[tuple[str, str]] = (),
        min_distance: float = 0.05,
        *,
        influence_distance: float | None = None,
        collision_gain: float = 2.0,
        max_joint_velocity: float | Sequence[float] = 1.0,
        max_joint_acceleration: float | None = 10.0,
        limit_gain: float = 0.5,
        limit_horizon: float = 0.05,
        posture: Sequence[float] | None = None,
        posture_gain: float = 1.0,
        damping: float = 1e-5,
        singular_damping: float = 0.05,
        singular_threshold: float = 0.05,
        dt: float | None = None,
    ) -> None:
        if not isinstance(robot, Robot):
            raise SpecTypeError(
                f"CartesianVelocityController: robot must be a Robot, got {robot!r}"
            )
        self._robot = robot
        n = robot.n_joints
        self._n = n
        if not isinstance(control_frame, str):
            raise SpecTypeError(f"control_frame must be a site or body name, got {control_frame!r}")
        self._frame_name = control_frame
        self._min_distance = _number(min_distance, "min_distance")
        self._influence = (
            self._min_distance + 0.1
            if influence_distance is None
            else _number(influence_distance, "influence_distance")
        )
        if self._influence <= self._min_distance:
            raise SpecError(
                f"influence_distance ({self._influence}) must exceed min_distance "
                f"({self._min_distance})"
            )
        self._collision_gain = _number(collision_gain, "collision_gain")
        self._limit_gain = _number(limit_gain, "limit_gain", positive=True)
        if self._limit_gain > 1.0:
            raise SpecError(f"limit_gain must be in (0, 1], got {limit_gain!r}")
        self._limit_horizon = _number(limit_horizon, "limit_horizon")
        self._posture_gain = _number(posture_gain, "posture_gain")
        self._damping = _at_most(_number(damping, "damping"), _MAX_DAMPING, "damping")
        self._singular_damping = _at_most(
            _number(singular_damping, "singular_damping"), _MAX_DAMPING, "singular_damping"
        )
        self._singular_threshold = _number(singular_threshold, "singular_threshold", positive=True)
        self._dt = None if dt is None else _number(dt, "dt", positive=True)
        self._vmax = self._velocity_limits(max_joint_velocity)
        self._amax = (
            math.inf
            if max_joint_acceleration is None
            else _number(max_joint_acceleration, "max_joint_acceleration", positive=True)
        )
        limits = robot.joint_limits
        self._lower, self._upper = limits[:, 0].copy(), limits[:, 1].copy()
        self._limits = np.vstack([self._upper, self._lower])
        self._posture = (
            np.clip(robot.jnt_pos_msr, self._lower, self._upper)  # soft limits may overshoot
            if posture is None
            else self._checked_posture(posture)
        )
        self._neg_vmax = -self._vmax
        self._pairs = _pair_names(avoid)
        self._model: mujoco.MjModel | None = None
        self._bind()
        # Work arrays, reused every call.
        self._n_null = max(0, n - 6)
        self._v = np.zeros(6)
        self._d = np.zeros(n)
        self._qp_post = np.zeros(n)
        self._H = np.zeros((n, n))
        self._scaled = np.zeros((n, n))
        self._f = np.zeros(n)
        rows = self._rows
        self._A = np.zeros((rows, n))
        self._b = np.empty((2, n + rows))  # DAQP's upper and lower bounds, boxes first
        self._b[0], self._b[1] = _INF, -_INF
        self._bu, self._bl = self._b[0], self._b[1]
        self._zero = np.zeros(n)
        self._last = np.zeros(n)  # the previous solution, where the acceleration bounds start
        self._last_time = math.inf  # scene time of the previous solve; inf: none yet
        self._signs = np.array([[1.0], [-1.0]])
        self._reach = np.zeros((2, 1))
        self._window = np.zeros((2, n))
        self._clash = np.zeros(n, dtype=bool)
        self._solver = daqp.Model()
        self._ready = False
        self._cold = False  # whether the next solve starts from an empty active set
        self._no_active = np.zeros(n + rows, dtype=np.int32)  # DAQP's sense flags: none active
        self.last_status = SolveStatus.OPTIMAL
        self._warned = False

    @property
    def settings(self) -> CartesianSettings:
        """The terms and bounds of this controller's QP (copies)."""
        return CartesianSettings(
            joint_lower=self._lower.copy(),
            joint_upper=self._upper.copy(),
            max_joint_velocity=self._vmax.copy(),
            max_joint_acceleration=self._amax,
            limit_gain=self._limit_gain,
            limit_horizon=self._limit_horizon,
            posture=self._posture.copy(),
            posture_gain=self._posture_gain,
            damping=self._damping,
            singular_damping=self._singular_damping,
            singular_threshold=self._singular_threshold,
        )

    # ------------------------------------------------------------------ setup

    def _velocity_limits(self, fallback: float | Sequence[float]) -> np.ndarray:
        """Per joint: the model's velocity limit where finite and positive, else `fallback`."""
        n = self._n
        if isinstance(fallback, (list, tuple)) or (
            isinstance(fallback, np.ndarray) and fallback.ndim
        ):
            default = _vector(fallback, n, "max_joint_velocity")
        else:  # one number (Python's or NumPy's) for every joint
            default = np.full(n, _number(fallback, "max_joint_velocity", positive=True))
        if np.any(default <= 0):
            raise SpecError(f"max_joint_velocity must be positive, got {fallback!r}")
        # The arm's entries, found by joint name: the model may hold more joints (a moving
        # base, the tool's fingers) than the arm.
        pin_model = self._robot.model
        limits = np.asarray(pin_model.velocityLimit, dtype=float)
        model = np.full(n, np.nan)
        for i, name in enumerate(self._robot.joint_names):
            joint = pin_model.getJointId(name)
            if joint < pin_model.njoints:
                model[i] = limits[pin_model.joints[joint].idx_v]
        # Pinocchio marks "no limit" with inf or the largest double.
        usable = (model > 0) & (model < _NO_LIMIT)
        return np.where(usable, model, default)

    def _bind(self) -> None:
        """Resolve names against the scene's current model (again after a rebuild)."""
        scene = self._robot.scene
        model = scene.model
        self._model = model
        self._data = scene.data
        self._frame = _frame_rotation(model, self._data, self._frame_name)
        dofs = [int(model.joint(name).dofadr[0]) for name in self._robot.joint_names]
        self._dofs = np.array(dofs)
        pairs: list[tuple[int, int]] = []
        for a, b in self._pairs:
            geoms_a, geoms_b = _collision_geoms(model, a, b), _collision_geoms(model, b, a)
            if set(geoms_a) & set(geoms_b):
                raise SpecError(
                    f"avoid: {a!r} and {b!r} share geoms (one is in the other's subtree)"
                )
            pairs += [(ga, gb) for ga in geoms_a for gb in geoms_b]
        self._rows = len(pairs)
        self._pair_list = pairs
        ga, gb = np.array(pairs, dtype=int).reshape(-1, 2).T
        self._geom_a, self._geom_b = ga, gb
        # Bounding spheres skip the exact distance for pairs that are clearly far apart
        # (a plane has no bounding sphere: never skipped).
        plane = int(mujoco.mjtGeom.mjGEOM_PLANE)
        rbound = np.where(model.geom_type == plane, np.inf, model.geom_rbound)
        self._sphere_reach = rbound[ga] + rbound[gb] + self._influence
        # One Jacobian per moving body (at its origin); bodies welded to the world have none
        # and use the last, all-zero slot.
        bodies_a, bodies_b = model.geom_bodyid[ga], model.geom_bodyid[gb]
        moving = sorted({int(x) for x in (*bodies_a, *bodies_b) if model.body_weldid[x] != 0})
        slot = {body: i for i, body in enumerate(moving)}
        self._moving = moving
        self._slot_a = np.array([slot.get(int(x), len(moving)) for x in bodies_a], dtype=int)
        self._slot_b = np.array([slot.get(int(x), len(moving)) for x in bodies_b], dtype=int)
        self._body_a, self._body_b = bodies_a, bodies_b
        # Sides whose bodies are all welded to the world (a table) add nothing to a row.
        self._sides = [
            (sign, slots, bodies, points)
            for sign, slots, bodies, points in (
                (1.0, self._slot_a, bodies_a, slice(0, 3)),
                (-1.0, self._slot_b, bodies_b, slice(3, 6)),
            )
            if np.any(slots < len(moving))
        ]
        self._jacp = np.zeros((len(moving) + 1, 3, model.nv))
        self._jacr = np.zeros((len(moving) + 1, 3, model.nv))
        self._fromto = np.zeros((self._rows, 6))
        self._fromto_rows = list(self._fromto)  # contiguous row views for mj_geomDistance
        self._dist = np.zeros(self._rows)

    def _current(self) -> None:
        """Rebind when the scene was rebuilt (`add_object`/`remove_object`)."""
        if self._robot.scene.model is not self._model:
            self._bind()
            self._ready = False

    # ------------------------------------------------------------------ public

    @property
    def robot(self) -> Robot:
        """The robot this controller drives."""
        return self._robot

    @property
    def control_frame(self) -> str:
        """Site or body whose axes the twist is expressed along ("" = world)."""
        return self._frame_name

    def frame_rotation(self) -> np.ndarray:
        """World rotation of the control frame now (3×3 copy; identity for the world)."""
        self._current()
        if self._frame is None:
            return np.eye(3)
        return self._frame.reshape(3, 3).copy()

    @property
    def velocity_limits(self) -> np.ndarray:
        """Per-joint velocity limits the solution respects (rad/s or m/s)."""
        return self._vmax.copy()

    @property
    def posture(self) -> np.ndarray:
        """Joint positions the null-space posture task pulls toward."""
        return self._posture.copy()

    @posture.setter
    def posture(self, value: Sequence[float]) -> None:
        self._posture = self._checked_posture(value)

    def _checked_posture(self, value: object) -> np.ndarray:
        """`value` as n joint positions, each within its joint's position limits."""
        posture = _vector(value, self._n, "posture")
        outside = np.flatnonzero((posture < self._lower) | (posture > self._upper))
        if len(outside):
            i = int(outside[0])
            raise SpecError(
                f"posture[{i}] (joint {self._robot.joint_names[i]!r}) must lie in "
                f"[{self._lower[i]:g}, {self._upper[i]:g}], got {posture[i]:g}"
            )
        return posture

    def reset(self) -> None:
        """Forget the previous solution: the next one starts from the measured velocities.

        Call it after an episode reset (`Env.reset`, `set_joint_pos`): the acceleration bounds
        start from the previous solution, which belongs to the old episode. A scene clock
        that went backwards is taken for a reset too, but a reset to the same time is not.
        """
        self._last_time = math.inf
        self._ready = False

    def resume(self, previous: ArrayLike) -> None:
        """Continue from a saved state: `previous`, the joint velocities of the solution
        before it, is where the acceleration bounds start, and the next solve starts from an
        empty active set as the first one does. The same robot state and `previous` then give
        the same solution bit for bit whatever was solved before (DAQP's warm start from the
        last active set changes the last bits of a solution)."""
        if not (isinstance(previous, np.ndarray) and previous.dtype == np.float64):
            previous = real_array(previous, "previous")
        if previous.shape != (self._n,) or not math.isfinite(previous.dot(previous)):
            raise SpecError(
                f"resume(previous) needs {self._n} finite joint velocities, got {previous!r}"
            )
        np.copyto(self._last, previous)
        self._last_time = -math.inf  # the clock's reset detection would overwrite `previous`
        self._cold = True

    def solve(self, twist: ArrayLike, dt: float | None = None) -> np.ndarray:
        """Joint velocities for `twist` (6: linear then angular, along the control frame).

        `dt` is the period over which the result will be applied (default: the controller's,
        else the scene's timestep); the position-limit bounds are computed for it.
        """
        v = self._twist(twist)
        step = self._period(dt)
        robot = self._robot
        self._current()
        # In POSITION mode the command is the controller's state: it is what the integration
        # advances and what must stay inside the limits; the servo follows it with some lag.
        if robot.ctrl_mode is CtrlMode.POSITION:
            q = robot.jnt_pos_cmd
            J = robot.jacobian(q)
        else:
            q = robot.jnt_pos_msr
            J = robot.jacobian()
        if not math.isfinite(q.dot(q)):
            return self._give_up(SolveStatus.FAILED, "the robot's state is not finite")
        self._world_twist(v)
        self._cost(J, q)
        self._bounds(q, step)
        self._accelerations(step)
        if self._rows:
            self._collision_rows()
        x, exitflag = self._qp()
        if exitflag < 0 or not math.isfinite(x.dot(x)):
            status = SolveStatus.INFEASIBLE if exitflag == -1 else SolveStatus.FAILED
            return self._give_up(status, f"DAQP exit flag {exitflag}")
        self.last_status = SolveStatus.OPTIMAL
        np.copyto(self._last, x)
        return x

    def command(self, twist: ArrayLike, dt: float | None = None) -> np.ndarray:
        """Solve for `twist` and write the robot's command; return the joint velocities.

        VELOCITY mode writes them to `jnt_vel_cmd`; POSITION mode adds `qd * dt` to
        `jnt_pos_cmd` (kept inside the joint limits). `dt` defaults to the scene's timestep:
        one call per physics step; a slower loop passes its period.
        """
        step = self._period(dt)
        mode = self._robot.ctrl_mode
        if mode is CtrlMode.TORQUE:
            raise SpecError(
                "CartesianVelocityController.command needs the robot in VELOCITY or POSITION "
                "mode, not TORQUE (use solve() for the joint velocities)"
            )
        qd = self.solve(twist, step)
        robot = self._robot
        if mode is CtrlMode.VELOCITY:
            robot.jnt_vel_cmd = qd
        else:
            target = robot.jnt_pos_cmd + qd * step
            np.clip(target, self._lower, self._upper, out=target)
            robot.jnt_pos_cmd = target
        return qd

    # ------------------------------------------------------------------ the QP

    def _twist(self, twist: object) -> np.ndarray:
        """`twist` checked to be 6 finite numbers, as float64 (no copy when it already is)."""
        if isinstance(twist, np.ndarray) and twist.dtype == np.float64:
            arr = twist
        else:
            arr = real_array(twist, "twist")
        if arr.shape != (6,):
            raise SpecError(f"twist needs 6 values [vx, vy, vz, wx, wy, wz], got shape {arr.shape}")
        # One dot product is finite exactly when every entry is (barring overflow, which the
        # exact check then clears).
        if not math.isfinite(arr.dot(arr)) and not np.isfinite(arr).all():
            raise SpecError(f"twist must be finite, got {twist!r}")
        return arr

    def _period(self, dt: float | None) -> float:
        if dt is None:
            return self._dt if self._dt is not None else self._robot.scene.timestep()
        return _number(dt, "dt", positive=True)

    def _world_twist(self, twist: np.ndarray) -> None:
        """The twist with both halves rotated from the control frame into the world."""
        v = self._v
        if self._frame is None:
            np.copyto(v, twist)
            return
        R = self._frame.reshape(3, 3)
        np.matmul(R, twist[:3], out=v[:3])
        np.matmul(R, twist[3:], out=v[3:])

    def _cost(self, J: np.ndarray, q: np.ndarray) -> None:
        """H and f of the tracking, damping and null-space posture terms."""
        JtJ = self._H
        np.matmul(J.T, J, out=JtJ)
        # Eigenvalues of JᵀJ in ascending order are the squared singular values of J, after
        # one zero per null-space dimension; the eigenvectors split the two spaces.
        eig, vec, info = _dsyev(JtJ)
        if info != 0:
            raise np.linalg.LinAlgError(f"dsyev failed ({info})")
        n_null = self._n_null
        # Levenberg-Marquardt style: more damping the closer J is to losing rank.
        lam = self._damping
        sigma = math.sqrt(max(float(eig[n_null]), 0.0))
        if sigma < self._singular_threshold:
            ratio = sigma / self._singular_threshold
            lam += self._singular_damping * (1.0 - ratio * ratio)
        d = self._d
        np.add(eig, lam, out=d)
        f = self._f
        np.matmul(self._v, J, out=f)
        if n_null:
            # Posture in the null space of J: the projector N = V_n V_nᵀ is orthogonal to the
            # rows of J, so the posture term cannot change the TCP's twist.
            d[:n_null] += 1.0
            null = vec[:, :n_null]
            post = self._qp_post
            np.subtract(self._posture, q, out=post)
            post *= self._posture_gain
            f += null @ (post @ null)
        np.negative(f, out=f)
        scaled = self._scaled
        np.multiply(vec, d, out=scaled)  # V diag(d)
        np.matmul(scaled, vec.T, out=self._H)

    def _bounds(self, q: np.ndarray, dt: float) -> None:
        """Joint velocity bounds: the velocity limits, tightened near position limits."""
        n = self._n
        box = self._b[:, :n]  # rows: upper, lower
        np.subtract(self._limits, q, out=box)
        box *= self._limit_gain / max(dt, self._limit_horizon)
        np.minimum(box, self._vmax, out=box)
        np.maximum(box, self._neg_vmax, out=box)

    def _accelerations(self, dt: float) -> None:
        """Narrow the bounds to what `max_joint_acceleration` allows from the last solution.

        Where that window misses the position/velocity bounds (a limit needs a harder stop),
        those bounds win: the velocity is pinned to their end nearest to the last one.
        """
        time = self._robot.scene.time()
        if time < self._last_time:
            np.copyto(self._last, self._robot.jnt_vel_msr)  # first call, or after a reset
        self._last_time = time
        if self._amax == math.inf:
            return
        n = self._n
        ub, lb, last = self._bu[:n], self._bl[:n], self._last
        window = self._window  # rows: last + a dt, last - a dt
        np.multiply(self._signs, self._amax * dt, out=self._reach)
        np.add(last, self._reach, out=window)
        np.minimum(ub, window[0], out=ub)
        np.maximum(lb, window[1], out=lb)
        clash = self._clash
        np.greater(lb, ub, out=clash)  # the window missed [lb, ub] on one side
        if clash.any():
            pinned = np.where(lb > last, lb, ub)  # the bound that was missed
            np.copyto(ub, pinned, where=clash)
            np.copyto(lb, pinned, where=clash)

    def _collision_rows(self) -> None:
        """One velocity-damper row per geom pair closer than the influence distance.

        d' = nᵀ (v_b - v_a) >= -k (d - d_min), with n the unit vector from the nearest point
        on geom a to the one on geom b. The points move by the robot's joints (J_a qd, J_b qd:
        the decision variables) and by everything else that moves them — another robot, a
        turning torso, the fingers — at its measured speed (u_a, u_b), so the row reads
        nᵀ (J_a - J_b) qd <= k (d - d_min) + nᵀ (u_b - u_a).
        """
        model, data, n = self._model, self._data, self._n
        A, bu, dist, ft = self._A, self._bu, self._dist, self._fromto
        A.fill(0.0)
        bu[n:] = _INF
        gap = data.geom_xpos[self._geom_a] - data.geom_xpos[self._geom_b]
        near = np.flatnonzero(np.sqrt(np.einsum("ij,ij->i", gap, gap)) < self._sphere_reach)
        if not len(near):
            return
        dist.fill(np.inf)
        pairs, rows, influence = self._pair_list, self._fromto_rows, self._influence
        for i in near.tolist():
            ga, gb = pairs[i]
            dist[i] = mujoco.mj_geomDistance(model, data, ga, gb, influence, rows[i])
        act = np.flatnonzero(dist < influence)
        if not len(act):
            return
        jacp, jacr = self._jacp, self._jacr
        for k, body in enumerate(self._moving):
            mujoco.mj_jac(model, data, jacp[k], jacr[k], data.xpos[body], body)
        jp, jr = jacp[:, :, self._dofs], jacr[:, :, self._dofs]
        # Body velocities from every joint but the robot's own: what the QP cannot change.
        qvel, own = data.qvel, data.qvel[self._dofs]
        lin = jacp @ qvel - jp @ own
        ang = jacr @ qvel - jr @ own
        d, pa, pb = dist[act], ft[act, :3], ft[act, 3:]
        normal = pb - pa
        length = np.sqrt(np.einsum("ij,ij->i", normal, normal))
        touching = length < 1e-9
        if touching.any():  # no direction from the points: use the centres'
            normal[touching] = -gap[act][touching]
            length[touching] = np.linalg.norm(normal[touching], axis=1)
            length[length == 0.0] = 1.0
        normal /= length[:, None]
        inside = (d < 0) & ~touching
        if inside.any():
            normal[inside] *= -1.0  # penetrating: the nearest points cross over
        row = np.zeros((len(act), n))
        bound = self._collision_gain * (d - self._min_distance)
        for sign, slots, bodies, points in self._sides:
            slot, body, point = slots[act], bodies[act], ft[act, points]
            # A point p of a body moves with v + ω × (p - x): nᵀ J_p = nᵀ J_v + ((p - x) × n)ᵀ J_ω.
            lever = _cross(point - data.xpos[body], normal)
            row += sign * np.matmul(normal[:, None, :], jp[slot])[:, 0]
            row += sign * np.matmul(lever[:, None, :], jr[slot])[:, 0]
            bound -= sign * (
                np.einsum("ij,ij->i", normal, lin[slot]) + np.einsum("ij,ij->i", lever, ang[slot])
            )
        A[act] = row
        bu[n + act] = bound

    def _qp(self) -> tuple[np.ndarray, int]:
        """DAQP's solution and exit flag; a setup or update that failed (a cost DAQP cannot
        factor) gives its own negative flag, and solving would raise or return NaN."""
        if not self._ready:
            exitflag, _ = self._solver.setup(self._H, self._f, self._A, self._bu, self._bl)
            if exitflag < 0:
                return self._zero, int(exitflag)
            self._ready = True
        else:
            A = self._A if self._rows else None  # DAQP rejects an update with no rows
            sense = self._no_active if self._cold else None  # None: warm start
            exitflag = self._solver.update(
                H=self._H, f=self._f, A=A, bupper=self._bu, blower=self._bl, sense=sense
            )
            if exitflag < 0:
                return self._zero, int(exitflag)
        self._cold = False
        x, _, exitflag, _ = self._solver.solve()
        return x, int(exitflag)

    def _give_up(self, status: SolveStatus, why: str) -> np.ndarray:
        self.last_status = status
        self._ready = False  # start the next solve from scratch, not from this one's state
        self._last.fill(0.0)
        if not self._warned:
            self._warned = True
            warnings.warn(
                f"CartesianVelocityController: no solution ({status.value}: {why}); "
                "commanding zero joint velocity (reported in last_status, warned once)",
                RuntimeWarning,
                stacklevel=3,
            )
        return self._zero.copy()


# ---------------------------------------------------------------------- helpers

_NEXT, _AFTER = [1, 2, 0], [2, 0, 1]


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross products of two (k, 3) arrays (np.cross costs ~10 us on small input)."""
    return a[:, _NEXT] * b[:, _AFTER] - a[:, _AFTER] * b[:, _NEXT]


def _number(value: object, name: str, positive: bool = False) -> float:
    """`value` as a finite float that is >= 0 (> 0 when `positive`): a real number, Python's
    or NumPy's (or a 0-d array of one), never text, a bool or a complex number."""
    if isinstance(value, np.ndarray) and value.shape == ():
        value = value[()]
    bound = "> 0" if positive else ">= 0"
    message = f"{name} must be a finite number {bound}, got {value!r}"
    try:
        x = real(value, name)
    except SpecTypeError:
        raise SpecTypeError(message) from None
    except SpecError:  # not finite
        raise SpecError(message) from None
    if x < 0 or (positive and x == 0):
        raise SpecError(message)
    return x


def _at_most(x: float, limit: float, name: str) -> float:
    if x > limit:
        raise SpecError(f"{name} must lie in [0, {limit:g}], got {x!r}")
    return x


def _vector(value: object, n: int, name: str) -> np.ndarray:
    """`value` as n finite numbers, one per joint (a copy)."""
    arr = real_array(value, name)
    if arr.shape != (n,):
        raise SpecError(f"{name} needs {n} values (one per joint), got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise SpecError(f"{name} must be finite, got {value!r}")
    return arr


def _frame_rotation(model: mujoco.MjModel, data: mujoco.MjData, name: str) -> np.ndarray | None:
    """A live view of the control frame's world rotation (9 values), None for the world."""
    if not name:
        return None
    site = find_id(model, mujoco.mjtObj.mjOBJ_SITE, name)
    if site >= 0:
        return data.site_xmat[site]
    body = find_id(model, mujoco.mjtObj.mjOBJ_BODY, name)
    if body >= 0:
        return data.xmat[body]
    known = [model.site(i).name for i in range(model.nsite)]
    known += [model.body(i).name for i in range(model.nbody)]
    raise unknown_name("site or body", name, known, where="the scene (control_frame)")


def _pair_names(avoid: object, field: str = "avoid") -> list[tuple[str, str]]:
    """`avoid` as a list of (body, body) name pairs; errors name `field`."""
    if isinstance(avoid, (str, bytes)) or not isinstance(avoid, Sequence):
        raise SpecError(f"{field} must be a sequence of (body_a, body_b) pairs, got {avoid!r}")
    pairs = []
    for i, pair in enumerate(avoid):
        if (
            not isinstance(pair, (tuple, list))
            or len(pair) != 2
            or not all(isinstance(b, str) and b for b in pair)
        ):
            raise SpecError(f"{field}[{i}] must be a pair of body names, got {pair!r}")
        pairs.append((pair[0], pair[1]))
    return pairs


def _collision_geoms(model: mujoco.MjModel, body: str, other: str) -> list[int]:
    """Geoms that take part in collisions, in the subtree of `body` (paired with `other`)."""
    where = f"the scene (avoid pair {body!r}, {other!r})"
    root = model_id(model, mujoco.mjtObj.mjOBJ_BODY, "body", body, where)
    inside = np.zeros(model.nbody, dtype=bool)
    inside[root] = True
    for b in range(root + 1, model.nbody):  # parents come before their children
        inside[b] = inside[model.body_parentid[b]]
    geoms = [
        g
        for g in range(model.ngeom)
        if inside[model.geom_bodyid[g]] and (model.geom_contype[g] or model.geom_conaffinity[g])
    ]
    if not geoms:
        raise SpecError(f"avoid: body {body!r} and its subtree have no collision geoms")
    return geoms
