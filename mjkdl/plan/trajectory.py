"""Time-parametrised joint trajectories: time-optimal timing (TOPP-RA) of a geometric path.

A `JointTrajectory` holds knots (time, position, velocity, acceleration) and samples between
them: positions and velocities on cubic Hermite polynomials, accelerations linearly. toppra's
accelerations jump at its grid points; a polynomial through them would ring past the limits
(a quintic by up to 20% in tests), linear interpolation never leaves the knots' range.

A `TimeParametrizer` times a path of joint waypoints under per-joint velocity and acceleration
limits with TOPP-RA, toppra's algorithm solved in closed form for box limits (the same path
velocities as toppra's, 3-5x faster; tests compare the two): a cubic spline through the
waypoints is followed as fast as the limits allow, at rest at both ends (the last knot's
velocity and acceleration zero: a follower holding the goal holds no braking acceleration).
"""

from __future__ import annotations

import bisect
import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import SpecError

# Knot spacing of a timed trajectory (s): quintic interpolation between knots this close
# reproduces the timed trajectory to well under a micro-radian.
KNOT_PERIOD = 0.01
# Path-parameter spacing (rad of joint-space distance) of the timing grid, within 30..100 points.
GRID_STEP = 0.05
# A timing under velocity and acceleration limits is checked for the torque limits at every
# this-many grid points, against this share of them (room for the points between): a path
# that comes closer is timed again with the torque rows, exactly.
TORQUE_STRIDE = 4
TORQUE_SHARE = 0.9


@dataclass(frozen=True)
class JointTrajectory:
    """Joint positions, velocities and accelerations at increasing `times` (from 0).

    Arrays: `times` (k,), `positions`, `velocities`, `accelerations` (k, n). `sample(t)`
    interpolates between the knots (cubic Hermite positions and velocities, linear
    accelerations); before 0 and after `duration` it holds the end positions at rest (zero
    velocity and acceleration), so a follower sampling past the end holds the goal.
    """

    times: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray
    _coeffs: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        times = _array(self.times, "times", 1)
        k = len(times)
        if k < 2:
            raise SpecError(f"JointTrajectory.times needs at least 2 knots, got {k}")
        if times[0] != 0.0 or np.any(np.diff(times) <= 0):
            raise SpecError("JointTrajectory.times must start at 0 and increase strictly")
        arrays = {}
        for name in ("positions", "velocities", "accelerations"):
            arr = _array(getattr(self, name), name, 2)
            if arr.shape[0] != k:
                raise SpecError(
                    f"JointTrajectory.{name} needs one row per time ({k}), got {arr.shape[0]}"
                )
            arrays[name] = arr
        n = arrays["positions"].shape[1]
        if arrays["velocities"].shape[1] != n or arrays["accelerations"].shape[1] != n:
            raise SpecError("JointTrajectory: positions, velocities, accelerations differ in width")
        for name, arr in (("times", times), *arrays.items()):
            arr.flags.writeable = False
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "_coeffs", _cubic(times, *arrays.values()))
        object.__setattr__(self, "_list", times.tolist())

    @property
    def duration(self) -> float:
        """Seconds from the first knot to the last."""
        return float(self.times[-1])

    @property
    def n_joints(self) -> int:
        """Number of joints (columns)."""
        return int(self.positions.shape[1])

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity and acceleration at time `t` (seconds from the start)."""
        q, qd, qdd = np.empty(self.n_joints), np.empty(self.n_joints), np.empty(self.n_joints)
        self.sample_into(t, q, qd, qdd)
        return q, qd, qdd

    def sample_into(self, t: float, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> None:
        """`sample(t)` written into the given arrays (a control loop allocates nothing)."""
        times: list[float] = self._list  # type: ignore[attr-defined]
        last = len(times) - 1
        if not t >= 0.0 or t > times[last]:  # NaN too: before the start or past the end, at rest
            np.copyto(q, self.positions[0] if not t > 0.0 else self.positions[last])
            qd[:] = 0.0
            qdd[:] = 0.0
            return
        if t == times[last]:
            np.copyto(q, self.positions[last])
            np.copyto(qd, self.velocities[last])
            np.copyto(qdd, self.accelerations[last])
            return
        i = bisect.bisect_right(times, t) - 1
        h = times[i + 1] - times[i]
        s = (t - times[i]) / h
        c = self._coeffs[i]  # (6, n): cubic coefficients in s, then the two accelerations
        s2 = s * s
        np.dot((1.0, s, s2, s2 * s, 0.0, 0.0), c, out=q)
        np.dot((0.0, 1.0 / h, 2.0 * s / h, 3.0 * s2 / h, 0.0, 0.0), c, out=qd)
        np.dot((0.0, 0.0, 0.0, 0.0, 1.0 - s, s), c, out=qdd)

    def positions_at(self, times: np.ndarray) -> np.ndarray:
        """Positions at many `times` at once (len(times)×n), as `sample` gives them."""
        t = np.clip(np.asarray(times, dtype=float), 0.0, self.duration)
        i = np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self.times) - 2)
        s = ((t - self.times[i]) / (self.times[i + 1] - self.times[i]))[:, None]
        c = self._coeffs[i]
        return c[:, 0] + s * (c[:, 1] + s * (c[:, 2] + s * c[:, 3]))


def _array(value: object, name: str, ndim: int) -> np.ndarray:
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise SpecError(f"JointTrajectory.{name} must hold numbers, got {value!r}") from None
    if arr.ndim != ndim:
        raise SpecError(f"JointTrajectory.{name} must be {ndim}-D, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise SpecError(f"JointTrajectory.{name} must be finite")
    return arr


def _cubic(times: np.ndarray, p: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Per segment: c0..c3 of the cubic (in s = (t - t_i) / h) meeting position and velocity
    at both knots, then the accelerations at its two knots."""
    h = np.diff(times)[:, None]
    p0, p1, v0, v1 = p[:-1], p[1:], v[:-1] * h, v[1:] * h
    dp = p1 - p0
    c2 = 3.0 * dp - 2.0 * v0 - v1
    c3 = -2.0 * dp + v0 + v1
    return np.stack([p0, v0, c2, c3, a[:-1], a[1:]], axis=1)


class TimeParametrizer:
    """Times joint paths under per-joint velocity and acceleration limits (n values each).

    Calling it with waypoints (k×n) gives the fastest `JointTrajectory` through them, at rest
    at both ends: a natural cubic spline through the waypoints, parametrised by their
    cumulative joint-space distance, is timed by TOPP-RA (`_reachability`: toppra's algorithm
    and constraint discretisation, solved in closed form for box limits), and the result is
    sampled every `KNOT_PERIOD`. With `torque_limits` and `inverse_dynamics(q, qd, qdd)`,
    the joint torques are kept too (toppra's joint torque constraint): a timing that asks
    for more torque at a grid point is computed again with the torque rows.
    """

    def __init__(
        self,
        velocity_limits: np.ndarray,
        acceleration_limits: np.ndarray,
        torque_limits: np.ndarray | None = None,
        inverse_dynamics: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray] | None = None,
    ) -> None:
        self._v = np.asarray(velocity_limits, dtype=float)
        self._a = np.asarray(acceleration_limits, dtype=float)
        if (torque_limits is None) != (inverse_dynamics is None):
            raise SpecError("TimeParametrizer: torque_limits need inverse_dynamics, and back")
        self._torque = None if torque_limits is None else np.asarray(torque_limits, dtype=float)
        self._dynamics = inverse_dynamics

    def _over_torque(
        self, grid: np.ndarray, q: np.ndarray, d1: np.ndarray, d2: np.ndarray, x: np.ndarray
    ) -> bool:
        """Whether the timing `x` (ṡ² on `grid`) asks any joint for more than `TORQUE_SHARE`
        of its torque limit at every `TORQUE_STRIDE`th grid point or the last (with the path
        acceleration of the stage starting there): a twelfth of the torque rows' inverse
        dynamics; most paths never come near the limits and are not timed again."""
        assert self._torque is not None and self._dynamics is not None
        u = np.diff(x) / (2.0 * np.diff(grid))
        u = np.append(u, u[-1])
        speed = np.sqrt(x)
        for k in [*range(0, len(grid) - 1, TORQUE_STRIDE), len(grid) - 1]:
            tau = self._dynamics(q[k], d1[k] * speed[k], d1[k] * u[k] + d2[k] * x[k])
            if np.any(np.abs(tau) > TORQUE_SHARE * self._torque):
                return True
        return False

    def _torque_rows(
        self, q: np.ndarray, d1: np.ndarray, d2: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The joint torques along the path as rows a u + b x + g (toppra's joint torque
        constraint): τ = M q' s̈ + (M q'' + C(q, q') q') ṡ² + g(q), each term by inverse
        dynamics; bounded by ±`torque_limits` (infinite: unbounded)."""
        assert self._torque is not None and self._dynamics is not None
        dynamics, zero = self._dynamics, np.zeros(q.shape[1])
        g = np.array([dynamics(x, zero, zero) for x in q])
        a = np.array([dynamics(x, zero, v) for x, v in zip(q, d1, strict=True)]) - g
        b = np.array([dynamics(x, v, w) for x, v, w in zip(q, d1, d2, strict=True)]) - g
        return a, b, -self._torque - g, self._torque - g

    def grid(self, waypoints: np.ndarray) -> tuple[Any, np.ndarray, np.ndarray] | None:
        """The spline through `waypoints` (repeats dropped), its grid and the waypoints'
        path parameters; None for a path of one point."""
        points = np.asarray(waypoints, dtype=float)
        steps = np.linalg.norm(np.diff(points, axis=0), axis=1)
        points = points[np.concatenate([[True], steps > 1e-9])]  # repeats stall the spline
        if len(points) < 2:
            return None
        from scipy.interpolate import CubicSpline

        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
        # Natural, not clamped: a clamped spline's zero tangent at the ends leaves the last
        # grid interval to be crossed from rest to rest (an infinite time) for 2 % of random
        # paths; natural ends never did in 1,500, and time paths 3 % faster.
        path = CubicSpline(s, points, bc_type="natural")
        # A fixed density of grid points (through the waypoints): toppra's own grid proposal
        # costs ~10 ms and gives durations within a few percent.
        count = int(np.clip(s[-1] / GRID_STEP, 30, 100))
        return path, np.unique(np.concatenate([np.linspace(0.0, s[-1], count), s])), points

    def __call__(self, waypoints: np.ndarray) -> JointTrajectory:
        gridded = self.grid(waypoints)
        if gridded is None:
            points = np.asarray(waypoints, dtype=float)
            zero = np.zeros((2, points.shape[1]))
            return JointTrajectory(
                np.array([0.0, KNOT_PERIOD]), np.repeat(points[:1], 2, 0), zero, zero
            )
        path, grid, points = gridded
        q, d1, d2 = path(grid), path(grid, 1), path(grid, 2)
        constraints = [
            (d1, d2, np.broadcast_to(-self._a, d1.shape), np.broadcast_to(self._a, d1.shape))
        ]
        x = _reachability(grid, d1, self._v, constraints)
        if self._torque is not None and self._over_torque(grid, q, d1, d2, x):
            constraints.append(self._torque_rows(q, d1, d2))
            x = _reachability(grid, d1, self._v, constraints)
        sd = np.sqrt(x)
        if not np.isfinite(sd).all():
            raise SpecError("no timing for the path (limits too tight?)")
        times, positions, velocities, accelerations = _const_accel(path, grid, sd)
        # At rest at the end: toppra's last knot carries the braking acceleration, which a
        # follower holding the goal would turn into a steady offset.
        velocities[0] = velocities[-1] = accelerations[-1] = 0.0
        positions[0], positions[-1] = points[0], points[-1]
        return JointTrajectory(times, positions, velocities, accelerations)


def _reachability(
    grid: np.ndarray,
    d1: np.ndarray,
    vmax: np.ndarray,
    constraints: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]],
) -> np.ndarray:
    """Squared path velocities x = ṡ² on `grid` of the time-optimal motion along a path with
    derivative `d1` = q'(s) there, at rest at both ends, |q̇| <= vmax and each constraint
    low <= a u + b x <= high (u = s̈; the joint accelerations: a = q', b = q'', ±amax; the
    joint torques through the dynamics: a = M q', b = the velocity product terms, the
    bounds ± the torque limit less gravity): TOPP-RA (Pham & Pham 2018) as toppra runs it
    (the "interpolation" discretisation: each stage at both of its grid points). toppra
    solves each stage's 2-variable LP with a general solver from Python; here each row
    bounds u within [m x + lower, m x + upper] (or x alone), the stage's feasible x is an
    interval from 0, and its top follows by eliminating u (Fourier-Motzkin) for all stages
    at once, leaving one affine minimum per stage in the backward pass."""
    delta = np.diff(grid)[:, None]  # (N, 1)
    a_parts, b_parts, lo_parts, hi_parts = [], [], [], []
    for a, b, floor, ceiling in constraints:
        a_parts += [a[:-1], a[1:] + 2.0 * delta * b[1:]]
        b_parts += [b[:-1], b[1:]]
        lo_parts += [floor[:-1], floor[1:]]
        hi_parts += [ceiling[:-1], ceiling[1:]]
    a_rows, b_rows = np.concatenate(a_parts, axis=1), np.concatenate(b_parts, axis=1)
    lo_rows, hi_rows = np.concatenate(lo_parts, axis=1), np.concatenate(hi_parts, axis=1)
    tiny = 1e-12
    moves = np.abs(a_rows) > tiny
    up = a_rows > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = np.where(moves, -b_rows / a_rows, 0.0)
        lower = np.where(moves, np.where(up, lo_rows, hi_rows) / a_rows, -np.inf)
        upper = np.where(moves, np.where(up, hi_rows, lo_rows) / a_rows, np.inf)
        # Rows without u bound x directly (from above; low <= 0 <= high at rest).
        direct = np.where(
            ~moves & (b_rows > tiny),
            hi_rows / b_rows,
            np.where(~moves & (b_rows < -tiny), lo_rows / b_rows, np.inf),
        )
        # Every lower bound on u below every upper one: (m_k - m_l) x <= upper_l - lower_k.
        coef = slope[:, :, None] - slope[:, None, :]
        room = upper[:, None, :] - lower[:, :, None]
        pairs = np.where(
            coef > tiny, room / coef, np.where(room < 0, 0.0, np.inf)
        )  # parallel bounds that cross: only rest
        # x_{i+1} = x + 2 delta u >= 0 below each upper bound.
        coef0 = -1.0 / (2.0 * delta) - slope
        zero = np.where(coef0 > tiny, upper / coef0, np.inf)
        # Each lower bound below x + 2 delta u <= h (the next controllable set's top):
        # x <= (h - 2 delta lower) / (1 + 2 delta m).
        scale = 1.0 + 2.0 * delta * slope
        p = np.where(scale > tiny, 1.0 / scale, 0.0)
        r = np.where(scale > tiny, -2.0 * delta * lower / scale, np.inf)
        speed = np.where(np.abs(d1) > tiny, (vmax / np.abs(d1)) ** 2, np.inf).min(axis=1)
    top = np.minimum(
        np.minimum(direct.min(axis=1), pairs.min(axis=(1, 2))),
        np.minimum(zero.min(axis=1), speed[:-1]),
    )
    count = len(delta)
    # Backward: the controllable sets [0, high[i]]; at rest at the end.
    high = [0.0] * (count + 1)
    p_list, r_list, top_list = p.tolist(), r.tolist(), top.tolist()
    h = 0.0
    for i in range(count - 1, -1, -1):
        h = min(top_list[i], *[pk * h + rk for pk, rk in zip(p_list[i], r_list[i], strict=True)])
        high[i] = max(h, 0.0)
    # Forward: from rest, the largest u keeping x_{i+1} controllable.
    x = [0.0] * (count + 1)
    two_delta = (2.0 * delta[:, 0]).tolist()
    slope_list, upper_list = slope.tolist(), upper.tolist()
    xi = 0.0
    for i in range(count):
        u = min([m * xi + w for m, w in zip(slope_list[i], upper_list[i], strict=True)])
        xi = min(max(xi + two_delta[i] * u, 0.0), high[i + 1])
        x[i + 1] = xi
    return np.array(x)


def _const_accel(
    path: Any, grid: np.ndarray, sd: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Knots every `KNOT_PERIOD` of the path followed at path velocities `sd` on `grid`,
    the path acceleration constant between grid points (toppra's ParametrizeConstAccel,
    evaluated for all knots at once instead of one by one)."""
    x = sd * sd
    ds = np.diff(grid)
    u = 0.5 * np.diff(x) / ds
    t_grid = np.concatenate([[0.0], np.cumsum(2.0 * ds / (sd[:-1] + sd[1:]))])
    duration = float(t_grid[-1])
    times = np.linspace(0.0, duration, max(2, math.ceil(duration / KNOT_PERIOD) + 1))
    i = np.clip(np.searchsorted(t_grid, times, side="right") - 1, 0, len(u) - 1)
    dt = times - t_grid[i]
    s = np.minimum(grid[i] + dt * (sd[i] + 0.5 * dt * u[i]), grid[-1])
    v = sd[i] + dt * u[i]
    d1, d2 = path(s, 1), path(s, 2)
    return times, path(s), d1 * v[:, None], d2 * (v * v)[:, None] + d1 * u[i][:, None]


class JerkLimitedParametrizer:
    """Times joint paths under velocity, acceleration and jerk limits with Ruckig.

    Ruckig's open-source version times state-to-state motions only, so the path is followed
    segment by segment, at rest at every waypoint: each segment is one Ruckig motion with
    phase synchronisation, which keeps it on the straight joint-space segment the planner
    checked. Slower than toppra's timing (it stops at every waypoint), but jerk-limited and
    exactly on the checked polyline; the result is sampled every `KNOT_PERIOD`.
    """

    def __init__(
        self, velocity_limits: np.ndarray, acceleration_limits: np.ndarray, jerk_limits: np.ndarray
    ) -> None:
        try:
            import ruckig  # noqa: F401
        except ImportError:
            raise SpecError(
                "jerk-limited timing needs ruckig: pip install ruckig (1.1 MB)"
            ) from None
        self._v = np.asarray(velocity_limits, dtype=float)
        self._a = np.asarray(acceleration_limits, dtype=float)
        self._j = np.asarray(jerk_limits, dtype=float)

    def __call__(self, waypoints: np.ndarray) -> JointTrajectory:
        from ruckig import InputParameter, Result, Ruckig, Synchronization, Trajectory

        points = np.asarray(waypoints, dtype=float)
        steps = np.abs(np.diff(points, axis=0)).max(axis=1)
        points = points[np.concatenate([[True], steps > 1e-9])]
        n = points.shape[1]
        if len(points) < 2:
            zero = np.zeros((2, n))
            return JointTrajectory(
                np.array([0.0, KNOT_PERIOD]), np.repeat(points[:1], 2, 0), zero, zero
            )
        otg = Ruckig(n)
        segments = []
        for a, b in itertools.pairwise(points):
            inp = InputParameter(n)
            inp.current_position, inp.target_position = a.tolist(), b.tolist()
            inp.max_velocity = self._v.tolist()
            inp.max_acceleration = self._a.tolist()
            inp.max_jerk = self._j.tolist()
            inp.synchronization = Synchronization.Phase
            trajectory = Trajectory(n)
            if otg.calculate(inp, trajectory) != Result.Working:
                raise SpecError("ruckig found no timing for a segment (limits too tight?)")
            segments.append(trajectory)
        ends = np.concatenate([[0.0], np.cumsum([s.duration for s in segments])])
        times = np.linspace(0.0, ends[-1], max(2, math.ceil(ends[-1] / KNOT_PERIOD) + 1))
        out = np.empty((3, len(times), n))
        index = np.clip(np.searchsorted(ends, times, side="right") - 1, 0, len(segments) - 1)
        for k, (t, i) in enumerate(zip(times.tolist(), index.tolist(), strict=True)):
            q, qd, qdd = segments[i].at_time(min(t - ends[i], segments[i].duration))
            out[0, k], out[1, k], out[2, k] = q, qd, qdd
        out[1, [0, -1]] = 0.0
        out[2, -1] = 0.0
        out[0, 0], out[0, -1] = points[0], points[-1]
        return JointTrajectory(times, out[0], out[1], out[2])
