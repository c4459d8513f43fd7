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
    velocity_bounds: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]  # q -> (lower, upper)

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


def _panda_velocity_bounds() -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
    acc = np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0]) - _EPS
    # libfranka 0.9.2 keeps a margin of 3 lost packets' worth of acceleration.
    upper = np.array([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61]) - _EPS - 3.0 * DT * acc
    lower = -upper
    return lambda q: (lower, upper)


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


def _fr3_velocity_bounds(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a, b, cu, cl, cap = _FR3.T
    upper = np.minimum(cap, np.maximum(0.0, -a + np.sqrt(np.maximum(0.0, b * (cu - q))))) - _EPS
    lower = np.maximum(-cap, np.minimum(0.0, a - np.sqrt(np.maximum(0.0, b * (cl + q))))) + _EPS
    return lower, upper


LIMITS: dict[str, ArmLimits] = {
    "panda": ArmLimits(
        "panda",
        max_acceleration=np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0]) - _EPS,
        max_jerk=np.array([7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0]) - _EPS,
        max_torque_rate=np.full(7, 1000.0 - _EPS),
        velocity_bounds=_panda_velocity_bounds(),
    ),
    "fr3": ArmLimits(
        "fr3",
        max_acceleration=np.full(7, 10.0 - _EPS),
        max_jerk=np.full(7, 5000.0 - _EPS),
        max_torque_rate=np.full(7, 1000.0 - _EPS),
        velocity_bounds=_fr3_velocity_bounds,
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
    owned by the limiter, overwritten by the next call).
    """

    def __init__(self, limits: ArmLimits) -> None:
        self.limits = limits
        self._acc_max = limits.max_acceleration
        self._jerk_max = limits.max_jerk
        self._ratio = limits.max_jerk / limits.max_acceleration
        self.q = np.zeros(7)  # last commanded position
        self.dq = np.zeros(7)  # last commanded velocity
        self.ddq = np.zeros(7)  # last commanded acceleration
        self.tau = np.zeros(7)  # last commanded torque
        self._out = np.zeros(7)
        self._start = 0  # ticks left at START_SHARE of the limits

    def reset(
        self, q: np.ndarray, dq: np.ndarray | None = None, tau: np.ndarray | None = None
    ) -> None:
        """Start from position `q`, velocity `dq` (zero), no acceleration, torque `tau` (zero)."""
        self.q[:] = q
        self.dq[:] = 0.0 if dq is None else dq
        self.ddq[:] = 0.0
        self.tau[:] = 0.0 if tau is None else tau
        self._start = START_TICKS

    def velocity(self, dq_cmd: np.ndarray, share: float = 1.0) -> np.ndarray:
        """The joint velocities to send for the wanted `dq_cmd` (also advances `q`), at
        `share` of the acceleration and jerk limits."""
        _check_finite(dq_cmd, "velocity")
        # The bounds where this tick ends (FR3's shrink with q): libfranka evaluates them
        # at the last position, which lets a fast joint overrun a shrinking bound by ~1e-3.
        lower, upper = self.limits.velocity_bounds(self.q + self.dq * (2.0 * DT))
        jerk_max, acc_max = self._jerk_max * share, self._acc_max * share
        if self._start:
            self._start -= 1
            jerk_max, acc_max = jerk_max * START_SHARE, acc_max * START_SHARE
        jerk = ((dq_cmd - self.dq) / DT - self.ddq) / DT
        acc = self.ddq + np.clip(jerk, -jerk_max, jerk_max) * DT
        # The acceleration is bounded so that the velocity can still reach its limit at the
        # jerk limit: a_max(v) = (j_max / a_max) * (v_limit - v).
        acc_hi = np.minimum(self._ratio * (upper - self.dq), acc_max)
        acc_lo = np.maximum(self._ratio * (lower - self.dq), -acc_max)
        np.clip(acc, acc_lo, acc_hi, out=acc)
        self.ddq[:] = acc
        self.dq += acc * DT
        self.q += self.dq * DT
        self._out[:] = self.dq
        return self._out

    def position(self, q_cmd: np.ndarray) -> np.ndarray:
        """The joint positions to send this tick on the way to the target `q_cmd`.

        A position target is approached, not jumped to: the wanted velocity is what stops
        at the target (sqrt(2 a e) at half the acceleration limit, `APPROACH_GAIN` e close
        to it), and it goes through the velocity chain above at `APPROACH_SHARE` of the
        limits, so whatever the targets do,
        the positions sent keep every limit. (libfranka's limitRate on the position itself
        assumes a smooth signal: on a jump it overshoots and rings.)"""
        _check_finite(q_cmd, "position")
        err = q_cmd - self.q
        dist = np.abs(err)
        lower, upper = self.limits.velocity_bounds(self.q)
        cap = APPROACH_SHARE * np.where(err > 0.0, upper, -lower)
        speed = np.minimum(APPROACH_GAIN * dist, np.sqrt(APPROACH_SHARE * self._acc_max * dist))
        self.velocity(np.copysign(np.minimum(speed, np.maximum(cap, 0.0)), err), APPROACH_SHARE)
        self._out[:] = self.q
        return self._out

    def torque(self, tau_cmd: np.ndarray) -> np.ndarray:
        """The torques to send for the wanted `tau_cmd` (at most the torque rate per tick)."""
        _check_finite(tau_cmd, "torque")
        step = self.limits.max_torque_rate * DT
        self.tau += np.clip(tau_cmd - self.tau, -step, step)
        self._out[:] = self.tau
        return self._out


def _check_finite(value: np.ndarray, what: str) -> None:
    if not np.isfinite(value).all():
        raise SpecError(f"the {what} command holds NaN or Inf: {value}; send finite values")
