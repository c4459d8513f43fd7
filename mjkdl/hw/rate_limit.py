"""Commands limited to a Franka arm's published velocity, acceleration and jerk limits.

The same algorithm as libfranka's `limitRate` (include/franka/rate_limiting.h): each 1 ms tick
the commanded jerk is clipped, integrated into an acceleration clipped so that the velocity can
still stop at its limit, and integrated into the velocity (and position) that leaves the
client. Joint positions and velocities go through the jerk/acceleration/velocity chain, torques
through the torque-rate limit. The limits are the ones libfranka publishes for each arm: the
Panda's (libfranka 0.9.2, constant per joint) and the FR3's (libfranka 0.15+, a joint's velocity
limit shrinks near its position limits).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import SpecError

DT = 1e-3  # the control interface's tick (s)
_EPS = 1e-3  # libfranka's kLimitEps: every limit is kept this far inside the robot's own
APPROACH_GAIN = 20.0  # 1/s: the last stretch to a position target, a 50 ms time constant
# A position target is approached at up to this share of the velocity, acceleration and jerk
# limits: at the limits themselves the robot's joint impedance controller overshoots the
# velocity (joint_velocity_violation) and its torques read as a collision (joint_reflex).
APPROACH_SHARE = 0.5
# The state reports q_d in float32 (libfranka >= 0.18), up to 1.2e-7 rad off the robot's own
# double: a motion that starts from it is off by that step, which the robot's differences turn
# into up to 240 rad/s^3 of jerk and 0.12 rad/s^2 of acceleration over its first three ticks.
# Those ticks keep this share of the jerk and acceleration limits.
START_SHARE = 0.9
START_TICKS = 5


@dataclass(frozen=True)
class ArmLimits:
    """One arm's published limits, already reduced by libfranka's safety margins."""

    name: str
    max_acceleration: np.ndarray  # rad/s^2 per joint
    max_jerk: np.ndarray  # rad/s^3 per joint
    max_torque_rate: np.ndarray  # Nm/s per joint
    # (q, lower, upper): the velocity bounds at q written into lower and upper
    bounds_into: Callable[[np.ndarray, np.ndarray, np.ndarray], None]

    def velocity_bounds(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The joint velocity bounds (lower, upper) at `q`, rad/s."""
        lower, upper = np.zeros(7), np.zeros(7)
        self.bounds_into(np.asarray(q, dtype=float), lower, upper)
        return lower, upper

    def describe(self) -> str:
        """One paragraph naming the limits (printed once by the first connection)."""
        _lo, hi = self.velocity_bounds(np.zeros(7))

        def fmt(a: np.ndarray) -> str:
            return "[" + ", ".join(f"{x:.4g}" for x in a) + "]"

        where = " at q = 0 (they shrink near the position limits)" if self.name == "fr3" else ""
        return (
            f"mjkdl.hw: commands are rate-limited to the {self.name} limits before they leave "
            f"(libfranka's limit_rate): velocity {fmt(hi)} rad/s{where}, acceleration "
            f"{fmt(self.max_acceleration)} rad/s^2, jerk {fmt(self.max_jerk)} rad/s^3, "
            f"torque rate {self.max_torque_rate[0]:.4g} Nm/s"
        )


def _panda_bounds_into() -> Callable[[np.ndarray, np.ndarray, np.ndarray], None]:
    acc = np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0]) - _EPS
    # libfranka 0.9.2 keeps a margin of 3 lost packets' worth of acceleration.
    upper = np.array([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61]) - _EPS - 3.0 * DT * acc
    lower = -upper

    def bounds(q: np.ndarray, lower_out: np.ndarray, upper_out: np.ndarray) -> None:
        np.copyto(lower_out, lower)
        np.copyto(upper_out, upper)

    return bounds


# FR3 (libfranka >= 0.15): v_max(q) = clip(-a + sqrt(b * (c - q)), 0, v_cap) per joint, and the
# mirrored expression for the lower bound; (a, b, c_upper, c_lower, v_cap) from rate_limiting.h.
_FR3 = np.array(
    [
        [0.30, 12.0, 2.75010, 2.750100, 2.62],
        [0.20, 5.17, 1.79180, 1.791800, 2.62],
        [0.20, 7.00, 2.90650, 2.906500, 2.62],
        [0.30, 8.00, -0.1458, 3.048100, 2.62],
        [0.35, 34.0, 2.81010, 2.810100, 5.26],
        [0.35, 11.0, 4.52050, -0.54092, 4.18],
        [0.35, 34.0, 3.01960, 3.019600, 5.26],
    ]
)


_FR3_A, _FR3_B, _FR3_CU, _FR3_CL, _FR3_CAP = (np.ascontiguousarray(c) for c in _FR3.T)
_FR3_NCAP = -_FR3_CAP
_FR3_SCRATCH = np.zeros(7)


def _full(value: float) -> np.ndarray:
    return np.full(7, value)


# Constants as arrays: a NumPy ufunc given a Python number allocates to wrap it.
_ZERO7, _ONE7, _EPS7, _DT7, _INV_DT7, _2DT7 = (
    _full(v) for v in (0.0, 1.0, _EPS, DT, 1.0 / DT, 2.0 * DT)
)


def number_view(array: np.ndarray) -> Any:
    """A memoryview of `array`: indexing it gives Python numbers (floats from the interpreter's
    free list, bools), where indexing the array makes a new NumPy scalar each time."""
    return memoryview(array)  # type: ignore[arg-type]  # NumPy's stubs lack __buffer__


def all_finite(values: np.ndarray, flags: np.ndarray, view: Any) -> bool:
    """Whether the 7 `values` are finite, through the caller's bool array `flags` and its
    memoryview `view` (a NumPy reduction, or `.data`, would allocate)."""
    np.isfinite(values, out=flags)
    return bool(view[0] and view[1] and view[2] and view[3] and view[4] and view[5] and view[6])


def _fr3_bounds_into(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> None:
    # upper = min(cap, max(0, -a + sqrt(max(0, b (c_upper - q))))) - eps, lower mirrored;
    # in place: the control loop allocates nothing per tick
    t = _FR3_SCRATCH
    np.subtract(_FR3_CU, q, out=t)
    np.multiply(t, _FR3_B, out=t)
    np.maximum(t, _ZERO7, out=t)
    np.sqrt(t, out=t)
    np.subtract(t, _FR3_A, out=t)
    np.maximum(t, _ZERO7, out=t)
    np.minimum(t, _FR3_CAP, out=upper)
    np.subtract(upper, _EPS7, out=upper)
    np.add(_FR3_CL, q, out=t)
    np.multiply(t, _FR3_B, out=t)
    np.maximum(t, _ZERO7, out=t)
    np.sqrt(t, out=t)
    np.subtract(_FR3_A, t, out=t)
    np.minimum(t, _ZERO7, out=t)
    np.maximum(t, _FR3_NCAP, out=lower)
    np.add(lower, _EPS7, out=lower)


LIMITS: dict[str, ArmLimits] = {
    "panda": ArmLimits(
        "panda",
        max_acceleration=np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0]) - _EPS,
        max_jerk=np.array([7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0]) - _EPS,
        max_torque_rate=np.full(7, 1000.0 - _EPS),
        bounds_into=_panda_bounds_into(),
    ),
    "fr3": ArmLimits(
        "fr3",
        max_acceleration=np.full(7, 10.0 - _EPS),
        max_jerk=np.full(7, 5000.0 - _EPS),
        max_torque_rate=np.full(7, 1000.0 - _EPS),
        bounds_into=_fr3_bounds_into,
    ),
}


def limits_for(model: str) -> ArmLimits:
    """The limits of `model` ("panda" or "fr3")."""
    if model not in LIMITS:
        raise SpecError(f"model must be one of {', '.join(map(repr, LIMITS))}, got {model!r}")
    return LIMITS[model]


class RateLimiter:
    """Rate-limits one stream of joint commands, tick by tick, from the arm's measured state.

    `reset` starts from the arm at rest at `q` (the state a motion starts from); then each call
    of `position`, `velocity` or `torque` returns the command to send this tick (an array
    owned by the limiter, overwritten by the next call). A tick allocates nothing: every
    intermediate lives in arrays made here.
    """

    def __init__(self, limits: ArmLimits) -> None:
        self.limits = limits
        self._acc_max = limits.max_acceleration
        self._jerk_max = limits.max_jerk
        self._ratio = limits.max_jerk / limits.max_acceleration
        self._step = limits.max_torque_rate * DT
        self._neg_step = -self._step
        self._approach_acc = APPROACH_SHARE * limits.max_acceleration
        self._gain = _full(APPROACH_GAIN)
        self._half_share = _full(0.5 * APPROACH_SHARE)
        self.q = np.zeros(7)  # last commanded position
        self.dq = np.zeros(7)  # last commanded velocity
        self.ddq = np.zeros(7)  # last commanded acceleration
        self.tau = np.zeros(7)  # last commanded torque
        self._out = np.zeros(7)
        self.start_ticks = 0  # ticks left at START_SHARE of the limits
        # scratch
        self._lower, self._upper, self._at = np.zeros(7), np.zeros(7), np.zeros(7)
        self._share, self._jm, self._am, self._neg = (np.zeros(7) for _ in range(4))
        self._acc, self._hi, self._lo = np.zeros(7), np.zeros(7), np.zeros(7)
        self._flags = np.zeros(7, dtype=bool)
        self._flags_view = number_view(self._flags)
        self._err, self._dist, self._cap, self._speed = (np.zeros(7) for _ in range(4))

    def reset(
        self, q: np.ndarray, dq: np.ndarray | None = None, tau: np.ndarray | None = None
    ) -> None:
        """Start from position `q`, velocity `dq` (zero), no acceleration, torque `tau` (zero)."""
        self.q[:] = q
        self.dq[:] = 0.0 if dq is None else dq
        self.ddq[:] = 0.0
        self.tau[:] = 0.0 if tau is None else tau
        self.start_ticks = START_TICKS

    def velocity(self, dq_cmd: np.ndarray, share: float = 1.0) -> np.ndarray:
        """The joint velocities to send for the wanted `dq_cmd` (also advances `q`), at
        `share` of the acceleration and jerk limits."""
        self._check_finite(dq_cmd, "velocity")
        # The bounds where this tick ends (FR3's shrink with q): libfranka evaluates them
        # at the last position, which lets a fast joint overrun a shrinking bound by ~1e-3.
        at, lower, upper = self._at, self._lower, self._upper
        np.multiply(self.dq, _2DT7, out=at)
        np.add(at, self.q, out=at)
        self.limits.bounds_into(at, lower, upper)
        if self.start_ticks:
            self.start_ticks -= 1
            share = share * START_SHARE
        jerk_max, acc_max, neg = self._jm, self._am, self._neg
        self._share.fill(share)
        np.multiply(self._jerk_max, self._share, out=jerk_max)
        np.multiply(self._acc_max, self._share, out=acc_max)
        acc = self._acc  # the jerk first, then the acceleration it gives
        np.subtract(dq_cmd, self.dq, out=acc)
        np.multiply(acc, _INV_DT7, out=acc)
        np.subtract(acc, self.ddq, out=acc)
        np.multiply(acc, _INV_DT7, out=acc)
        np.negative(jerk_max, out=neg)
        np.maximum(acc, neg, out=acc)
        np.minimum(acc, jerk_max, out=acc)
        np.multiply(acc, _DT7, out=acc)
        np.add(acc, self.ddq, out=acc)
        # The acceleration is bounded so that the velocity can still reach its limit at the
        # jerk limit: a_max(v) = (j_max / a_max) * (v_limit - v).
        hi, lo = self._hi, self._lo
        np.subtract(upper, self.dq, out=hi)
        np.multiply(hi, self._ratio, out=hi)
        np.minimum(hi, acc_max, out=hi)
        np.subtract(lower, self.dq, out=lo)
        np.multiply(lo, self._ratio, out=lo)
        np.negative(acc_max, out=neg)
        np.maximum(lo, neg, out=lo)
        np.maximum(acc, lo, out=acc)  # (lo <= hi: clip)
        np.minimum(acc, hi, out=acc)
        np.copyto(self.ddq, acc)
        np.multiply(acc, _DT7, out=acc)
        np.add(self.dq, acc, out=self.dq)
        np.multiply(self.dq, _DT7, out=acc)
        np.add(self.q, acc, out=self.q)
        np.copyto(self._out, self.dq)
        return self._out

    def position(self, q_cmd: np.ndarray) -> np.ndarray:
        """The joint positions to send this tick on the way to the target `q_cmd`.

        A position target is approached, not jumped to: the wanted velocity is what stops
        at the target (sqrt(2 a e) at half the acceleration limit, `APPROACH_GAIN` e close
        to it), and it goes through the velocity chain above at `APPROACH_SHARE` of the
        limits, so whatever the targets do,
        the positions sent keep every limit. (libfranka's limitRate on the position itself
        assumes a smooth signal: on a jump it overshoots and rings.)"""
        self._check_finite(q_cmd, "position")
        err, dist, cap, speed = self._err, self._dist, self._cap, self._speed
        np.subtract(q_cmd, self.q, out=err)
        np.abs(err, out=dist)
        lower, upper = self._lower, self._upper
        self.limits.bounds_into(self.q, lower, upper)
        # the bound in the direction of travel, at APPROACH_SHARE: with s = sign(err),
        # (1 + s)/2 upper - (1 - s)/2 lower (s = 0: no travel, the speed is 0 anyway)
        np.sign(err, out=speed)
        np.add(_ONE7, speed, out=cap)
        np.multiply(cap, upper, out=cap)
        np.subtract(_ONE7, speed, out=speed)
        np.multiply(speed, lower, out=speed)
        np.subtract(cap, speed, out=cap)
        np.multiply(cap, self._half_share, out=cap)
        np.maximum(cap, _ZERO7, out=cap)
        np.multiply(dist, self._approach_acc, out=speed)
        np.sqrt(speed, out=speed)
        np.multiply(dist, self._gain, out=dist)
        np.minimum(speed, dist, out=speed)
        np.minimum(speed, cap, out=speed)
        np.copysign(speed, err, out=speed)
        self.velocity(speed, APPROACH_SHARE)
        np.copyto(self._out, self.q)
        return self._out

    def torque(self, tau_cmd: np.ndarray) -> np.ndarray:
        """The torques to send for the wanted `tau_cmd` (at most the torque rate per tick)."""
        self._check_finite(tau_cmd, "torque")
        step = self._acc
        np.subtract(tau_cmd, self.tau, out=step)
        np.maximum(step, self._neg_step, out=step)
        np.minimum(step, self._step, out=step)
        np.add(self.tau, step, out=self.tau)
        np.copyto(self._out, self.tau)
        return self._out

    def _check_finite(self, value: np.ndarray, what: str) -> None:
        if not all_finite(value, self._flags, self._flags_view):
            raise SpecError(f"the {what} command holds NaN or Inf: {value}; send finite values")
