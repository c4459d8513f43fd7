"""The rate limiter against libfranka's published limits and limitRate's arithmetic."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjkdl.errors import MjkdlError
from mjkdl.hw.rate_limit import (
    APPROACH_SHARE,
    DT,
    LIMITS,
    START_SHARE,
    START_TICKS,
    RateLimiter,
    limits_for,
)


def _run(limiter: RateLimiter, target: np.ndarray, ticks: int) -> np.ndarray:
    return np.array([limiter.position(target).copy() for _ in range(ticks)])


@pytest.mark.parametrize("model", ["panda", "fr3"])
def test_a_position_jump_becomes_a_motion_within_every_limit(model: str) -> None:
    limits = LIMITS[model]
    limiter = RateLimiter(limits)
    q0 = np.array([0.0, 0.0, 0.0, -1.57, 0.0, 1.57, 0.785])
    limiter.reset(q0)
    target = q0 + np.array([1.0, -0.5, 0.8, 0.6, -1.0, 0.5, 1.2])
    q = np.vstack([q0, q0, q0, _run(limiter, target, 4000)])  # from rest
    v = np.diff(q, axis=0) / DT
    a = np.diff(v, axis=0) / DT
    j = np.diff(a, axis=0) / DT
    lower, upper = limits.velocity_bounds(q0)
    tol = 1e-6
    assert (v <= upper.max() + tol).all() and (v >= lower.min() - tol).all()
    assert (np.abs(a) <= limits.max_acceleration + 1e-3).all()
    assert (np.abs(j) <= limits.max_jerk + 1.0).all()  # 1 rad/s^3 of round-off in 3 diffs
    np.testing.assert_allclose(q[-1], target, atol=1e-9)  # and it gets there, at rest
    np.testing.assert_allclose(v[-1], 0.0, atol=1e-9)


def test_the_first_tick_is_limitRate_s_jerk_step() -> None:
    # From rest, a far velocity: the jerk is clipped to j_max, so a = j_max dt, v = a dt
    # (libfranka's limitRate); the first ticks of a motion at START_SHARE of the limits (the
    # float32 q_d a motion starts from).
    limits = LIMITS["panda"]
    limiter = RateLimiter(limits)
    limiter.reset(np.zeros(7))
    v = limiter.velocity(np.full(7, 2.0))
    jerk = limits.max_jerk * START_SHARE
    np.testing.assert_allclose(limiter.ddq, jerk * DT)
    np.testing.assert_allclose(v, jerk * DT * DT)
    np.testing.assert_allclose(limiter.q, jerk * DT**3)
    for _ in range(START_TICKS - 1):
        limiter.velocity(np.full(7, 2.0))
    np.testing.assert_allclose(limiter.ddq, limits.max_acceleration * START_SHARE)
    limiter.velocity(np.full(7, 2.0))  # past the start: the full acceleration
    np.testing.assert_allclose(limiter.ddq, limits.max_acceleration)
    assert limits.max_jerk[0] == 7500.0 - 1e-3  # libfranka 0.9.2's kMaxJointJerk, less kLimitEps
    # A position target goes at APPROACH_SHARE of the limits, at most.
    limiter.reset(np.zeros(7))
    for _ in range(3000):
        limiter.position(np.full(7, 2.0))
        assert (np.abs(limiter.ddq) <= APPROACH_SHARE * limits.max_acceleration + 1e-9).all()
        # (the jerk-limited chain reaches the cap with a few mrad/s of overshoot)
        assert (limiter.dq <= APPROACH_SHARE * limits.velocity_bounds(limiter.q)[1] + 5e-3).all()


def test_fr3_velocity_limits_shrink_near_the_position_limits() -> None:
    bounds = LIMITS["fr3"].velocity_bounds
    lower, upper = bounds(np.zeros(7))
    # At q = 0 every joint is far from its limits: the caps 2.62 / 5.26 / 4.18 rad/s less 1e-3.
    np.testing.assert_allclose(upper, [2.619, 2.619, 2.619, 0.0 - 1e-3, 5.259, 4.179, 5.259])
    q = np.zeros(7)
    q[0] = 2.7
    assert bounds(q)[1][0] == pytest.approx(-0.30 + math.sqrt(12.0 * (2.75010 - 2.7)) - 1e-3)
    q[5] = 1.0  # joint 6's lower bound: -0.35 + sqrt(11 (q - 0.54092)) away from 0
    assert bounds(q)[0][5] == pytest.approx(0.35 - math.sqrt(11.0 * (1.0 - 0.54092)) + 1e-3)
    # Panda: constant, 2.175 rad/s less 1e-3 and three lost packets' acceleration.
    np.testing.assert_allclose(
        LIMITS["panda"].velocity_bounds(q)[1][0], 2.175 - 1e-3 - 3e-3 * (15.0 - 1e-3)
    )
    assert lower[3] < 0.0 < upper[0]


def test_velocity_commands_are_held_to_the_velocity_limits() -> None:
    limits = LIMITS["fr3"]
    limiter = RateLimiter(limits)
    limiter.reset(np.array([0.0, 0.0, 0.0, -1.57, 0.0, 1.57, 0.0]))  # inside every limit
    for _ in range(400):
        _lower, upper = limits.velocity_bounds(limiter.q)  # at the state each tick starts from
        v = limiter.velocity(np.full(7, 100.0))
        # Never past the robot's own limit (upper + kLimitEps): where the bound shrinks with
        # q the jerk-limited braking lags it by less than the margin, as libfranka's does.
        assert (v <= upper + 1e-3).all()
    assert v[0] == pytest.approx(2.619, abs=1e-6)  # and at it once accelerated (0.26 s)
    # Joint 2 nears its position limit: it follows its shrinking bound, below the cap.
    assert v[1] < 2.5 and v[1] == pytest.approx(limits.velocity_bounds(limiter.q)[1][1], abs=2e-3)


def test_torques_change_at_most_1000_nm_per_second() -> None:
    limiter = RateLimiter(LIMITS["panda"])
    limiter.reset(np.zeros(7))
    first = limiter.torque(np.full(7, 10.0)).copy()
    np.testing.assert_allclose(first, 0.999999)  # (1000 - 1e-3) Nm/s for 1 ms
    for _ in range(20):
        tau = limiter.torque(np.full(7, 10.0))
    np.testing.assert_allclose(tau, 10.0)


def test_bad_commands_and_models_are_refused_by_name() -> None:
    limiter = RateLimiter(LIMITS["panda"])
    with pytest.raises(MjkdlError, match="position command holds NaN"):
        limiter.position(np.array([0, 0, 0, np.nan, 0, 0, 0.0]))
    with pytest.raises(MjkdlError, match="torque command holds NaN or Inf"):
        limiter.torque(np.full(7, np.inf))
    with pytest.raises(ValueError, match="model must be one of 'panda', 'fr3', got 'ur5'"):
        limits_for("ur5")


def test_the_limits_are_described_in_one_line() -> None:
    text = LIMITS["fr3"].describe()
    assert "fr3 limits" in text and "jerk [5000" in text and "torque rate 1000 Nm/s" in text


@pytest.mark.parametrize("model", ["panda", "fr3"])
def test_many_ticks_at_once_are_the_ticks_one_by_one_to_the_bit(model: str) -> None:
    # `positions` (a task env's control period) against `position` tick by tick (the
    # connection's loop): the same numbers, start ticks included, and the same state after.
    rng = np.random.default_rng(3)
    q0 = np.array([0.0, 0.3, 0.0, -1.57, 0.0, 1.57, 0.785])
    one, many = RateLimiter(LIMITS[model]), RateLimiter(LIMITS[model])
    one.reset(q0)
    many.reset(q0)
    for _ in range(4):  # from the start, then further periods that change direction
        targets = q0 + np.linspace(0.0, 1.0, 100)[:, None] * rng.uniform(-1.0, 1.0, 7)
        q_out, dq_out = np.zeros((100, 7)), np.zeros((100, 7))
        many.positions(targets, q_out, dq_out)
        for k in range(100):
            np.testing.assert_array_equal(one.position(targets[k]), q_out[k])
            np.testing.assert_array_equal(one.dq, dq_out[k])
        for name in ("q", "dq", "ddq"):
            np.testing.assert_array_equal(getattr(one, name), getattr(many, name))
        assert one.start_ticks == many.start_ticks == 0


def test_many_ticks_refuse_bad_arrays_by_name() -> None:
    limiter = RateLimiter(LIMITS["panda"])
    limiter.reset(np.zeros(7))
    out = np.zeros((3, 7))
    bad = np.zeros((3, 7))
    bad[1, 2] = np.nan
    with pytest.raises(MjkdlError, match="the position commands hold NaN or Inf"):
        limiter.positions(bad, out, out.copy())
    with pytest.raises(ValueError, match=r"C-contiguous n x 7 arrays, got shapes \(3, 6\)"):
        limiter.positions(np.zeros((3, 6)), out, out.copy())
    with pytest.raises(ValueError, match="C-contiguous"):
        limiter.positions(np.zeros((3, 7)), np.zeros((7, 3)).T, out)
    np.testing.assert_array_equal(limiter.q, 0.0)  # nothing ran
