"""JointTrajectory sampling and TOPP-RA timing under limits (toppra the reference)."""

from __future__ import annotations

import numpy as np
import pytest

import mjkdl as mjk
from mjkdl.plan import JointTrajectory, TimeParametrizer

V = np.array([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61])
A = np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0])


def test_sample_reproduces_a_cubic_and_holds_the_ends() -> None:
    times = np.array([0.0, 0.3, 0.5, 1.0])
    cubic = lambda t: np.stack([t**3 - t, 2 * t**2], axis=-1)  # noqa: E731
    speed = lambda t: np.stack([3 * t**2 - 1, 4 * t], axis=-1)  # noqa: E731
    accel = lambda t: np.stack([6 * t, 4 + 0 * t], axis=-1)  # noqa: E731
    traj = JointTrajectory(times, cubic(times), speed(times), accel(times))
    assert traj.duration == 1.0 and traj.n_joints == 2
    for t in (0.0, 0.1, 0.3, 0.42, 0.77, 1.0):
        q, qd, qdd = traj.sample(t)
        assert np.allclose(q, cubic(np.array(t)), atol=1e-12)
        assert np.allclose(qd, speed(np.array(t)), atol=1e-12)
        assert np.allclose(qdd, accel(np.array(t)), atol=1e-12)  # linear in t: exact
    many = traj.positions_at(np.array([-1.0, 0.1, 0.42, 1.0, 2.0]))
    assert np.allclose(many, [traj.sample(t)[0] for t in (0.0, 0.1, 0.42, 1.0, 1.0)], atol=1e-14)
    assert np.array_equal(traj.sample(-1.0)[0], traj.positions[0])
    # Past the end (and before the start) the trajectory holds its end at rest.
    q, qd, qdd = traj.sample(5.0)
    assert np.array_equal(q, traj.positions[-1])
    assert qd.tolist() == [0.0, 0.0] and qdd.tolist() == [0.0, 0.0]
    assert traj.sample(-1.0)[2].tolist() == [0.0, 0.0]
    assert traj.sample(1.0)[1].tolist() == [2.0, 4.0]  # the last knot itself as given
    with pytest.raises(ValueError, match="read-only"):
        traj.positions[0, 0] = 1.0


@pytest.mark.parametrize(
    ("times", "positions", "message"),
    [
        ([0.0], [[0.0]], r"times needs at least 2 knots, got 1"),
        ([0.0, 0.0], [[0.0], [1.0]], r"times must start at 0 and increase strictly"),
        ([0.1, 0.2], [[0.0], [1.0]], r"times must start at 0"),
        ([0.0, 1.0], [[0.0]], r"positions needs one row per time \(2\), got 1"),
        ([0.0, 1.0], [0.0, 1.0], r"positions must be 2-D, got shape \(2,\)"),
        ([0.0, np.nan], [[0.0], [1.0]], r"times must be finite"),
        ([0.0, 1.0], [["a"], [1.0]], r"positions must hold numbers"),
    ],
)
def test_bad_knots_are_refused_by_field(times, positions, message) -> None:
    width = np.shape(positions)[-1] if np.ndim(positions) == 2 else 1
    zeros = np.zeros((len(times), width))
    with pytest.raises(mjk.SpecError, match=message):
        JointTrajectory(times, positions, zeros, zeros)


def test_toppra_timing_passes_the_waypoints_within_the_limits() -> None:
    rng = np.random.default_rng(1)
    waypoints = np.cumsum(rng.normal(0.0, 0.5, (5, 7)), axis=0)
    traj = TimeParametrizer(V, A)(waypoints)
    assert np.array_equal(traj.positions[[0, -1]], waypoints[[0, -1]])
    assert np.abs(traj.velocities[[0, -1]]).max() == 0.0  # at rest at both ends
    assert np.abs(traj.accelerations[-1]).max() == 0.0
    q, qd, qdd = traj.sample(traj.duration + 0.5)  # past the end: the goal, at rest
    assert np.array_equal(q, waypoints[-1]) and not qd.any() and not qdd.any()
    samples = [traj.sample(t) for t in np.linspace(0.0, traj.duration, 3000)]
    assert (np.abs([s[1] for s in samples]).max(axis=0) / V).max() <= 1.01
    assert (np.abs([s[2] for s in samples]).max(axis=0) / A).max() <= 1.02
    # Time-optimal: some joint runs at its velocity or acceleration limit.
    assert (np.abs([s[1] for s in samples]).max(axis=0) / V).max() > 0.95
    # The path goes through every waypoint (a spline through them, in order).
    path = np.array([s[0] for s in samples])
    for point in waypoints[1:-1]:
        assert np.linalg.norm(path - point, axis=1).min() < 0.01
    # Velocities are the positions' derivative.
    t = np.linspace(0.1, traj.duration - 0.1, 50)
    numeric = np.array([(traj.sample(x + 1e-6)[0] - traj.sample(x - 1e-6)[0]) / 2e-6 for x in t])
    assert np.abs(numeric - np.array([traj.sample(x)[1] for x in t])).max() < 1e-4


@pytest.mark.parametrize("seed", [2, 3])
def test_timing_matches_toppras_own_solver_and_const_accel_parametrizer(seed) -> None:
    # The closed-form stages give toppra's path velocities on the same grid and constraints
    # (its seidel solver, interpolation discretisation); the knots, evaluated for all times
    # at once, are toppra's ParametrizeConstAccel trajectory.
    import toppra
    import toppra.algorithm
    import toppra.constraint

    rng = np.random.default_rng(seed)
    waypoints = np.cumsum(rng.normal(0.0, 0.5, (4 + seed, 7)), axis=0)
    timing = TimeParametrizer(V, A)
    traj = timing(waypoints)
    _spline, grid, points = timing.grid(waypoints)
    assert 30 <= len(grid) <= 100 + len(points)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(waypoints, axis=0), axis=1))])
    path = toppra.SplineInterpolator(s, waypoints, bc_type="natural")
    constraints = [
        toppra.constraint.JointVelocityConstraint(np.column_stack([-V, V])),
        toppra.constraint.JointAccelerationConstraint(np.column_stack([-A, A])),
    ]
    own = toppra.algorithm.TOPPRA(
        constraints, path, gridpoints=grid, parametrizer="ParametrizeConstAccel"
    )
    theirs = own.compute_trajectory(0.0, 0.0)
    assert traj.duration == pytest.approx(theirs.duration, rel=1e-7)
    inner = traj.times[1:-1]
    assert np.abs(traj.positions[1:-1] - theirs(inner)).max() < 1e-6
    assert np.abs(traj.velocities[1:-1] - theirs(inner, 1)).max() < 1e-5
    assert np.abs(traj.accelerations[:-1] - theirs(traj.times[:-1], 2)).max() < 1e-4
    # toppra's last knot brakes; ours is at rest there.
    assert np.abs(theirs(traj.times[-1:], 2)).max() > 0.1
    assert traj.accelerations[-1].tolist() == [0.0] * 7


def test_random_paths_get_finite_timings() -> None:
    # 200 random paths with their midpoints (as the planner times them): each is timed in
    # finite time. The clamped spline before took forever (or raised) on 6 of them.
    from mjkdl.plan.planner import _subdivide

    rng = np.random.default_rng(0)
    timing = TimeParametrizer(V, A)
    durations = []
    for _ in range(200):
        waypoints = rng.uniform(-2.5, 2.5, (rng.integers(2, 6), 7)) * rng.uniform(0.05, 1.0)
        for _ in range(rng.integers(1, 4)):
            waypoints = _subdivide(waypoints)
        durations.append(timing(waypoints).duration)
    assert max(durations) < 10.0


def test_a_path_of_one_point_is_a_standstill() -> None:
    traj = TimeParametrizer(V, A)(np.zeros((3, 7)))
    assert traj.duration > 0 and not traj.velocities.any() and not traj.positions.any()


def test_ruckig_timing_is_jerk_limited_and_stays_on_the_checked_polyline() -> None:
    from mjkdl.plan.trajectory import JerkLimitedParametrizer

    v, a, j = np.array([1.0, 2.0]), np.array([4.0, 5.0]), np.array([40.0, 60.0])
    points = np.array([[0.0, 0.0], [0.6, 0.3], [0.6, -0.5]])
    traj = JerkLimitedParametrizer(v, a, j)(points)
    assert np.abs(traj.positions[[0, -1]] - points[[0, -1]]).max() < 1e-12
    assert not traj.velocities[-1].any() and not traj.accelerations[-1].any()
    t = np.arange(0.0, traj.duration, 0.001)
    q = np.array([traj.sample(x)[0] for x in t])
    qd = np.array([traj.sample(x)[1] for x in t])
    assert np.all(np.abs(qd).max(axis=0) <= v * 1.001)
    # Jerk from the knots' accelerations (every 10 ms): within the limits.
    jerk = np.abs(np.diff(traj.accelerations, axis=0) / np.diff(traj.times)[:, None])
    assert np.all(jerk.max(axis=0) <= j * 1.001)
    assert np.all(np.abs(traj.accelerations).max(axis=0) <= a * 1.001)
    # On the polyline: every sample lies on one of its two segments.
    first = np.abs(np.cross(q - points[0], points[1] - points[0]))
    second = np.abs(q[:, 0] - 0.6)
    assert np.minimum(first, second).max() < 1e-6
    # toppra's spline through the corner leaves the polyline; it is faster too.
    from mjkdl.plan import TimeParametrizer

    assert TimeParametrizer(v, a)(points).duration < traj.duration


def test_torque_limits_are_kept_through_the_dynamics_as_toppra_keeps_them() -> None:
    """The UR10's dynamics, its URDF efforts scaled down until they bind (the base to 5 %,
    the shoulder to 60 %): timed under velocity and acceleration limits alone, the path asks
    the base for 3.5x its torque; with the torque limits, at most its torque (1 %: the
    discretisation), in the time toppra's own JointTorqueConstraint gives."""
    import toppra
    import toppra.algorithm
    import toppra.constraint
    from conftest import untested_arm, untested_robot

    with untested_arm("ur10") as env:
        robot = untested_robot(env, "ur10")
        v = np.array([2.16, 2.16, 3.15, 3.2, 3.2, 3.2])
        a = v / 0.5
        torque = robot.model.effortLimit.copy() * [0.05, 0.6, 0.5, 0.1, 0.1, 0.1]
        waypoints = np.array(
            [
                [0, -1.57, 1.57, -1.57, -1.57, 0],
                [1.0, -0.5, 0.3, -1.0, -1.2, 0.5],
                [2.0, -0.2, -0.5, -0.5, 0.2, 1.0],
            ]
        )

        def worst(traj: JointTrajectory) -> float:
            return max(
                float((np.abs(robot.inverse_dynamics(*traj.sample(t))) / torque).max())
                for t in np.linspace(0.0, traj.duration, 400)
            )

        plain = TimeParametrizer(v, a)(waypoints)
        timing = TimeParametrizer(v, a, torque, robot.inverse_dynamics)
        traj = timing(waypoints)
        assert worst(plain) > 3.0
        assert worst(traj) <= 1.01
        assert traj.duration > 1.3 * plain.duration
        _spline, grid, points = timing.grid(waypoints)
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
        interpolation = toppra.constraint.DiscretizationType.Interpolation
        constraints = [
            toppra.constraint.JointVelocityConstraint(np.column_stack([-v, v])),
            toppra.constraint.JointAccelerationConstraint(np.column_stack([-a, a])),
            toppra.constraint.JointTorqueConstraint(
                robot.inverse_dynamics,
                np.column_stack([-torque, torque]),
                np.zeros(6),
                discretization_scheme=interpolation,
            ),
        ]
        theirs = toppra.algorithm.TOPPRA(
            constraints,
            toppra.SplineInterpolator(s, points, bc_type="natural"),
            gridpoints=grid,
            parametrizer="ParametrizeConstAccel",
        ).compute_trajectory(0.0, 0.0)
        assert traj.duration == pytest.approx(theirs.duration, rel=1e-6)
        with pytest.raises(mjk.SpecError, match=r"torque_limits need inverse_dynamics"):
            TimeParametrizer(v, a, torque)
