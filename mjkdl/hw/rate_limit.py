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

import math
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
_INV_DT = 1.0 / DT


@dataclass(frozen=True)
class ArmLimits:
    """One arm's published limits, already reduced by libfranka's safety margins."""

    name: str
    max_acceleration: np.ndarray  # rad/s^2 per joint
    max_jerk: np.ndarray  # rad/s^3 per joint
    max_torque_rate: np.ndarray  # Nm/s per joint
    max_velocity: np.ndarray  # rad/s per joint: the bound everywhere, or the cap of `shrink`
    # FR3: per joint (a, b, c_upper, c_lower, v_cap) of the bounds that shrink near the
    # position limits (`_joint_velocity_bounds`); None: ±max_velocity everywhere (Panda)
    shrink: tuple[tuple[float, float, float, float, float], ...] | None = None

    def velocity_bounds(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The joint velocity bounds (lower, upper) at `q`, rad/s."""
        if self.shrink is None:
            return -self.max_velocity, self.max_velocity.copy()
        q = np.asarray(q, dtype=float)
        pairs = [_joint_velocity_bounds(float(q[j]), self.shrink[j]) for j in range(7)]
        return np.array([lo for lo, _ in pairs]), np.array([hi for _, hi in pairs])

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


def _joint_velocity_bounds(
    q: float, shrink: tuple[float, float, float, float, float]
) -> tuple[float, float]:
    """FR3 (libfranka >= 0.15): one joint's velocity bounds (lower, upper) at position `q`,
    upper = clip(-a + sqrt(b (c_upper - q)), 0, v_cap) - eps and the mirrored lower."""
    a, b, c_upper, c_lower, cap = shrink
    # (comparisons, not max/min: Python numbers in, no call, the same IEEE results as NumPy's)
    t = (c_upper - q) * b
    if t < 0.0:
        t = 0.0
    t = math.sqrt(t) - a
    if t < 0.0:
        t = 0.0
    if t > cap:
        t = cap
    upper = t - _EPS
    t = (c_lower + q) * b
    if t < 0.0:
        t = 0.0
    t = a - math.sqrt(t)
    if t > 0.0:
        t = 0.0
    if t < -cap:
        t = -cap
    return t + _EPS, upper


# FR3 (libfranka >= 0.15): (a, b, c_upper, c_lower, v_cap) per joint from rate_limiting.h.
_FR3 = (
    (0.30, 12.0, 2.75010, 2.750100, 2.62),
    (0.20, 5.17, 1.79180, 1.791800, 2.62),
    (0.20, 7.00, 2.90650, 2.906500, 2.62),
    (0.30, 8.00, -0.1458, 3.048100, 2.62),
    (0.35, 34.0, 2.81010, 2.810100, 5.26),
    (0.35, 11.0, 4.52050, -0.54092, 4.18),
    (0.35, 34.0, 3.01960, 3.019600, 5.26),
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


_PANDA_ACC = np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0]) - _EPS

LIMITS: dict[str, ArmLimits] = {
    "panda": ArmLimits(
        "panda",
        max_acceleration=_PANDA_ACC,
        max_jerk=np.array([7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0]) - _EPS,
        max_torque_rate=np.full(7, 1000.0 - _EPS),
        # libfranka 0.9.2 keeps a margin of 3 lost packets' worth of acceleration.
        max_velocity=np.array([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61])
        - _EPS
        - 3.0 * DT * _PANDA_ACC,
    ),
    "fr3": ArmLimits(
        "fr3",
        max_acceleration=np.full(7, 10.0 - _EPS),
        max_jerk=np.full(7, 5000.0 - _EPS),
        max_torque_rate=np.full(7, 1000.0 - _EPS),
        max_velocity=np.array([row[4] for row in _FR3]),
        shrink=_FR3,
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
    owned by the limiter, overwritten by the next call), and `positions` runs many ticks of
    position targets at once. The chain runs joint by joint on Python numbers (seven joints
    are too few for NumPy's per-call cost); a tick allocates nothing: the numbers come from
    the interpreter's free list, the arrays are made here (`bind` puts `q`, `dq`, `ddq`
    elsewhere, a task env's userdata).
    """

    def __init__(self, limits: ArmLimits) -> None:
        self.limits = limits
        # per joint, as Python numbers: (jerk, acceleration, jerk / acceleration, the approach's
        # acceleration, the constant velocity bounds, the FR3 shrink or None)
        shrink = limits.shrink or (None,) * 7
        self._joints = tuple(
            (
                float(limits.max_jerk[j]),
                float(limits.max_acceleration[j]),
                float(limits.max_jerk[j] / limits.max_acceleration[j]),
                float(APPROACH_SHARE * limits.max_acceleration[j]),
                float(-limits.max_velocity[j]),
                float(limits.max_velocity[j]),
                shrink[j],
            )
            for j in range(7)
        )
        self._step = limits.max_torque_rate * DT
        self._neg_step = -self._step
        self.tau = np.zeros(7)  # last commanded torque
        self._out = np.zeros(7)
        self._out_view = number_view(self._out)
        self._cmd = np.zeros(7)
        self._cmd_view = number_view(self._cmd)
        self.start_ticks = 0  # ticks left at START_SHARE of the limits
        self.bind(np.zeros(7), np.zeros(7), np.zeros(7))
        # scratch
        self._acc = np.zeros(7)
        self._flags = np.zeros(7, dtype=bool)
        self._flags_view = number_view(self._flags)

    def bind(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> None:
        """Keep the last commanded position, velocity and acceleration in these 7-vectors
        (float64, contiguous), from their values."""
        self.q, self.dq, self.ddq = q, dq, ddq
        self._views = (number_view(q), number_view(dq), number_view(ddq))

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
        np.copyto(self._cmd, dq_cmd)  # (a memoryview of the caller's array would allocate)
        self._ticks(self._cmd_view, 1, False, share, self._out_view, None)
        return self._out

    def position(self, q_cmd: np.ndarray) -> np.ndarray:
        """The joint positions to send this tick on the way to the target `q_cmd`.

        A position target is approached, not jumped to: the wanted velocity is what stops
        at the target (sqrt(2 a e) at half the acceleration limit, `APPROACH_GAIN` e close
        to it), and it goes through the velocity chain of `velocity` at `APPROACH_SHARE` of
        the limits, so whatever the targets do, the positions sent keep every limit.
        (libfranka's limitRate on the position itself assumes a smooth signal: on a jump it
        overshoots and rings.)"""
        self._check_finite(q_cmd, "position")
        np.copyto(self._cmd, q_cmd)
        self._ticks(self._cmd_view, 1, True, APPROACH_SHARE, None, self._out_view)
        return self._out

    def positions(self, q_cmd: np.ndarray, q_out: np.ndarray, dq_out: np.ndarray) -> None:
        """`position` for each row of `q_cmd` (n ticks' targets, n x 7), tick after tick: the
        positions sent into the rows of `q_out`, their velocities into `dq_out` (each n x 7,
        C-contiguous float64)."""
        n = len(q_cmd)
        arrays = (q_cmd, q_out, dq_out)
        if any(a.shape != (n, 7) or not a.flags.c_contiguous for a in arrays):
            raise SpecError(
                "positions: q_cmd, q_out and dq_out must be C-contiguous n x 7 arrays, got "
                f"shapes {q_cmd.shape}, {q_out.shape}, {dq_out.shape}"
            )
        if not math.isfinite(float(np.sum(q_cmd))) and not np.isfinite(q_cmd).all():
            raise SpecError(f"the position commands hold NaN or Inf: {q_cmd}; send finite values")
        self._ticks(
            number_view(q_cmd.reshape(-1)),
            n,
            True,
            APPROACH_SHARE,
            number_view(dq_out.reshape(-1)),
            number_view(q_out.reshape(-1)),
        )

    def _ticks(
        self, cmd: Any, n: int, approach: bool, share: float, dq_out: Any, q_out: Any
    ) -> None:
        """`n` ticks of the chain, joint after joint: each tick's command `cmd[7 k + j]`
        (a position target with `approach`, else a velocity), its velocity and position
        written into `dq_out` and `q_out` at the same index (either may be None).

        Every operation is the one NumPy would do on the 7-vectors, in the same order, so the
        result is the same to the bit; `while` loops, not `for`: an iterator is allocated."""
        qv, dqv, ddqv = self._views
        start = self.start_ticks
        half_share = 0.5 * APPROACH_SHARE
        started = share * START_SHARE
        j = 0
        while j < 7:
            jerk, acc_max, ratio, approach_acc, lower, upper, shrink = self._joints[j]
            q, dq, ddq = qv[j], dqv[j], ddqv[j]
            # the jerk and acceleration bounds (and their negatives) at the start, then after
            first = (jerk * started, acc_max * started, -(jerk * started), -(acc_max * started))
            then = (jerk * share, acc_max * share, -(jerk * share), -(acc_max * share))
            k, i = 0, j
            while k < n:
                wanted = cmd[i]
                if approach:  # the velocity that stops at the target, within the bounds at q
                    if shrink is not None:
                        lower, upper = _joint_velocity_bounds(q, shrink)
                    err = wanted - q
                    dist = abs(err)
                    # the bound in the direction of travel, at APPROACH_SHARE (at err = 0 the
                    # speed is 0 whatever the cap)
                    cap = 2.0 * upper * half_share if err > 0.0 else -2.0 * lower * half_share
                    if cap < 0.0:
                        cap = 0.0
                    wanted = math.sqrt(dist * approach_acc)
                    dist = dist * APPROACH_GAIN
                    if dist < wanted:
                        wanted = dist
                    if cap < wanted:
                        wanted = cap
                    wanted = math.copysign(wanted, err)
                # The bounds where this tick ends (FR3's shrink with q): libfranka evaluates
                # them at the last position, which lets a fast joint overrun a shrinking
                # bound by ~1e-3.
                if shrink is not None:
                    lower, upper = _joint_velocity_bounds(dq * (2.0 * DT) + q, shrink)
                jerk_max, a_max, jerk_min, a_min = first if k < start else then
                acc = ((wanted - dq) * _INV_DT - ddq) * _INV_DT  # the jerk first
                if acc < jerk_min:
                    acc = jerk_min
                if acc > jerk_max:
                    acc = jerk_max
                acc = acc * DT + ddq  # then the acceleration it gives
                # The acceleration is bounded so that the velocity can still reach its limit
                # at the jerk limit: a_max(v) = (j_max / a_max) * (v_limit - v).
                hi = (upper - dq) * ratio
                if hi > a_max:
                    hi = a_max
                lo = (lower - dq) * ratio
                if lo < a_min:
                    lo = a_min
                if acc < lo:
                    acc = lo
                if acc > hi:  # (lo <= hi: clip)
                    acc = hi
                ddq = acc
                dq = dq + acc * DT
                q = q + dq * DT
                if dq_out is not None:
                    dq_out[i] = dq
                if q_out is not None:
                    q_out[i] = q
                k += 1
                i += 7
            qv[j], dqv[j], ddqv[j] = q, dq, ddq
            j += 1
        self.start_ticks = start - n if start > n else 0

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
