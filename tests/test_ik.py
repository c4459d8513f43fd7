"""IKSolver on the Kinova Gen3 from MuJoCo Menagerie: accuracy, limits, failure, input checks."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from conftest import menagerie

from mjkdl.errors import SpecError
from mjkdl.ik import IKResult, IKSolver

HOME = np.array([0.0, 0.2618, 3.1416, -2.2689, 0.0, 0.9599, 1.5708])
TOL_POS, TOL_ROT = 1e-6, 1e-5


@pytest.fixture(scope="module")
def gen3() -> tuple[pin.Model, int, np.ndarray, np.ndarray]:
    """Gen3 model, the pinch_site frame id, and its joint limits (±inf when unlimited)."""
    path = menagerie("kinova_gen3")  # skips, counted in the run's summary, when missing
    model = pin.buildModelFromMJCF(str(path))
    if not model.existFrame("pinch_site"):
        parent = model.getFrameId("bracelet_link")
        frame = model.frames[parent]
        placement = pin.SE3(np.diag([1.0, -1.0, -1.0]), np.array([0.0, 0.0, -0.061525]))
        model.addFrame(
            pin.Frame(
                "pinch_site",
                frame.parentJoint,
                parent,
                frame.placement * placement,
                pin.FrameType.OP_FRAME,
            )
        )
    lower = model.lowerPositionLimit.copy()
    upper = model.upperPositionLimit.copy()
    lower[lower < -1e10] = -np.inf
    upper[upper > 1e10] = np.inf
    return model, model.getFrameId("pinch_site"), lower, upper


def _sample(lower: np.ndarray, upper: np.ndarray, n: int, seed: int) -> np.ndarray:
    lo = np.where(np.isfinite(lower), lower, -np.pi)
    hi = np.where(np.isfinite(upper), upper, np.pi)
    return np.random.default_rng(seed).uniform(lo, hi, size=(n, lower.size))


def _fk(model: pin.Model, frame_id: int, q: np.ndarray) -> pin.SE3:
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return data.oMf[frame_id].copy()


def _pose_errors(model: pin.Model, frame_id: int, q: np.ndarray, target: pin.SE3):
    pose = _fk(model, frame_id, q)
    pos = np.linalg.norm(pose.translation - target.translation)
    rot = np.linalg.norm(pin.log3(pose.rotation.T @ target.rotation))
    return pos, rot


def _within(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> bool:
    return bool(np.all(q >= lower) and np.all(q <= upper))


def test_random_reachable_targets(gen3):
    model, fid, lower, upper = gen3
    solver = IKSolver(model, fid, lower, upper, tol_pos=TOL_POS, tol_rot=TOL_ROT)
    qs = _sample(lower, upper, 200, seed=1)
    successes = 0
    for q_true in qs:
        target = _fk(model, fid, q_true)
        res = solver.solve(target, HOME)
        assert isinstance(res, IKResult)
        assert _within(res.q, lower, upper), res.q
        pos, rot = _pose_errors(model, fid, res.q, target)
        assert res.position_error == pytest.approx(pos, abs=1e-12)
        assert res.rotation_error == pytest.approx(rot, abs=1e-9)
        if res.success:
            assert pos <= TOL_POS and rot <= TOL_ROT
            successes += 1
    assert successes / len(qs) >= 0.995


def test_unreachable_target_fails_within_limits(gen3):
    model, fid, lower, upper = gen3
    solver = IKSolver(model, fid, lower, upper, max_restarts=5)
    target = pin.SE3(np.eye(3), np.array([3.0, 0.0, 0.5]))
    res = solver.solve(target, HOME)
    assert res.success is False
    assert res.restarts == 5
    assert _within(res.q, lower, upper)
    assert res.position_error > TOL_POS
    assert res.position_error > 1.5  # the arm reaches about 1.2 m from its base
    pos, rot = _pose_errors(model, fid, res.q, target)
    assert res.position_error == pytest.approx(pos, abs=1e-12)
    assert res.rotation_error == pytest.approx(rot, abs=1e-9)
    assert res.iterations > 0


@pytest.mark.parametrize(("joint", "band"), [(1, (0.5, 0.6)), (0, (1.0, 1.2)), (5, (-0.3, -0.2))])
def test_tightened_limit_is_respected(gen3, joint, band):
    model, fid, lower, upper = gen3
    lower, upper = lower.copy(), upper.copy()
    lower[joint], upper[joint] = band
    q_true = _sample(lower, upper, 1, seed=7 + joint)[0]
    target = _fk(model, fid, q_true)
    q0 = HOME.copy()
    assert not band[0] <= q0[joint] <= band[1]  # the seed starts outside the band
    res = IKSolver(model, fid, lower, upper).solve(target, q0)
    assert res.success
    assert band[0] <= res.q[joint] <= band[1]
    assert _within(res.q, lower, upper)


def test_locked_joint_stays_put(gen3):
    model, fid, lower, upper = gen3
    lower, upper = lower.copy(), upper.copy()
    q_true = _sample(lower, upper, 1, seed=3)[0]
    lower[3] = upper[3] = q_true[3]
    res = IKSolver(model, fid, lower, upper).solve(_fk(model, fid, q_true), HOME)
    assert res.success
    assert res.q[3] == q_true[3]


def test_frame_inside_the_chain(gen3):
    model, _, lower, upper = gen3
    fid = model.getFrameId("forearm_link")  # carried by joints 1-4 only
    solver = IKSolver(model, fid, lower, upper)
    for q_true in _sample(lower, upper, 10, seed=11):
        res = solver.solve(_fk(model, fid, q_true), HOME)
        assert res.success
        assert _pose_errors(model, fid, res.q, _fk(model, fid, q_true))[0] <= TOL_POS
        if res.restarts == 0:  # joints 5-7 do not move the frame, so they keep the seed's value
            np.testing.assert_allclose(res.q[4:], HOME[4:], rtol=0, atol=1e-12)


def test_bad_input_names_the_argument(gen3):
    model, fid, lower, upper = gen3
    solver = IKSolver(model, fid, lower, upper)
    target = _fk(model, fid, HOME)
    with pytest.raises(ValueError, match="q0"):
        solver.solve(target, HOME[:6])
    bad = HOME.copy()
    bad[2] = np.nan
    with pytest.raises(ValueError, match="q0"):
        solver.solve(target, bad)
    with pytest.raises(SpecError, match="q0"):
        solver.solve(target, ["a"] * 7)
    with pytest.raises(ValueError, match="target"):
        solver.solve(target.homogeneous, HOME)
    with pytest.raises(ValueError, match="lower"):
        IKSolver(model, fid, lower[:3], upper)
    with pytest.raises(ValueError, match="frame_id"):
        IKSolver(model, model.nframes, lower, upper)


def test_deterministic(gen3):
    model, fid, lower, upper = gen3
    qs = _sample(lower, upper, 20, seed=5)
    targets = [_fk(model, fid, q) for q in qs]
    targets.append(pin.SE3(np.eye(3), np.array([3.0, 0.0, 0.5])))  # exercises the restarts
    first = IKSolver(model, fid, lower, upper, max_restarts=3, seed=42)
    second = IKSolver(model, fid, lower, upper, max_restarts=3, seed=42)
    for target in targets:
        a = first.solve(target, HOME)
        b = first.solve(target, HOME)
        c = second.solve(target, HOME)
        np.testing.assert_array_equal(a.q, b.q)
        np.testing.assert_array_equal(a.q, c.q)
        assert a.iterations == b.iterations == c.iterations
        assert a.restarts == b.restarts == c.restarts


def test_prismatic_and_revolute_chain():
    model = pin.Model()
    parent = 0
    joints = [pin.JointModelPX(), pin.JointModelPY(), pin.JointModelPZ()]
    joints += [pin.JointModelRZ(), pin.JointModelRY(), pin.JointModelRX()]
    for i, joint in enumerate(joints):
        offset = pin.SE3(np.eye(3), np.array([0.0, 0.0, 0.1 if i else 0.0]))
        parent = model.addJoint(parent, joint, offset, f"j{i}")
    fid = model.addFrame(
        pin.Frame("tcp", parent, 0, pin.SE3(np.eye(3), np.array([0.05, 0.0, 0.2])), pin.OP_FRAME)
    )
    lower = np.array([-0.5, -0.5, 0.0, -np.inf, -1.0, -np.inf])
    upper = np.array([0.5, 0.5, 0.4, np.inf, 1.0, np.inf])
    solver = IKSolver(model, fid, lower, upper)
    for q_true in _sample(lower, upper, 20, seed=2):
        target = _fk(model, fid, q_true)
        res = solver.solve(target, np.zeros(6))
        assert res.success
        assert _within(res.q, lower, upper)
        pos, rot = _pose_errors(model, fid, res.q, target)
        assert pos <= TOL_POS and rot <= TOL_ROT


def test_seed_past_a_limit_is_clipped_into_the_limits(gen3):
    """MuJoCo's soft limits let a measured q pass a limit; IK must not answer from there."""
    model, fid, lower, upper = gen3
    q0 = HOME.copy()
    q0[1] = upper[1] + 0.2  # joint 2 past its upper limit; the target is where q0 puts the TCP
    res = IKSolver(model, fid, lower, upper, max_restarts=3).solve(_fk(model, fid, q0), q0)
    assert _within(res.q, lower, upper)
    pos, _ = _pose_errors(model, fid, res.q, _fk(model, fid, q0))
    assert res.position_error == pytest.approx(pos, abs=1e-12)


def test_target_must_be_finite(gen3):
    model, fid, lower, upper = gen3
    target = _fk(model, fid, HOME)
    target.translation = np.array([np.nan, 0.0, 0.5])
    with pytest.raises(ValueError, match="target must be finite"):
        IKSolver(model, fid, lower, upper).solve(target, HOME)


def test_arm_inside_a_larger_model(gen3):
    """`joints`: solve for a run of joints, the others held where `q_rest` puts them."""
    model, fid, lower, upper = gen3
    arm = list(range(2, 8))  # joints 2-7; joint 1 stays at q_rest's value
    solver = IKSolver(model, fid, lower[1:], upper[1:], joints=arm)
    q_rest = HOME.copy()
    q_rest[0] = 0.4
    q_true = q_rest.copy()
    q_true[1:] = _sample(lower[1:], upper[1:], 1, seed=4)[0]
    res = solver.solve(_fk(model, fid, q_true), HOME[1:], q_rest)
    assert res.success and res.q.shape == (6,)
    full = q_rest.copy()
    full[1:] = res.q
    assert _pose_errors(model, fid, full, _fk(model, fid, q_true))[0] <= TOL_POS
    with pytest.raises(ValueError, match="q_rest"):
        solver.solve(_fk(model, fid, q_true), HOME[1:])
    with pytest.raises(ValueError, match="model's order"):
        IKSolver(model, fid, lower[:2], upper[:2], joints=[3, 1])


# ---------------------------------------------------------------- small hand-built chains


def _chain(joints) -> tuple[pin.Model, int]:
    """A serial chain of `joints` with coincident origins; frame "tcp" at the last one."""
    model = pin.Model()
    parent = 0
    for i, joint in enumerate(joints):
        parent = model.addJoint(parent, joint, pin.SE3.Identity(), f"j{i}")
    fid = model.addFrame(pin.Frame("tcp", parent, 0, pin.SE3.Identity(), pin.OP_FRAME))
    return model, fid


@pytest.fixture(scope="module")
def free6() -> tuple[pin.Model, int]:
    """x, y, z slides then z, y, x hinges: the tcp's position is (q0, q1, q2) exactly."""
    return _chain(
        [
            pin.JointModelPX(),
            pin.JointModelPY(),
            pin.JointModelPZ(),
            pin.JointModelRZ(),
            pin.JointModelRY(),
            pin.JointModelRX(),
        ]
    )


FREE = (np.full(6, -np.inf), np.full(6, np.inf))


def _offset(pose: pin.SE3, dp, w) -> pin.SE3:
    """`pose` moved by `dp` (world) and turned by the world rotation vector `w` about its origin."""
    return pin.SE3(pin.exp3(np.asarray(w, dtype=float)) @ pose.rotation, pose.translation + dp)


@pytest.mark.parametrize(
    ("tols", "where", "dp", "w"),
    [
        ({}, (0.6, 0.0, 0.8), (0.0, 0.9e-6, 0.0), (0.0, 0.9e-5, 0.0)),
        ({"tol_pos": 2e-5, "tol_rot": 1e-5}, (0.6, 0.0, 0.8), (1.5e-5, 0.0, 0.0), (0, 0, 0)),
        ({}, (0.0, 0.0, 3.0), (0.0, 0.0, 0.0), (0.9e-5, 0.0, 0.0)),
        ({"tol_rot": 1.0}, (0.0, 0.0, 100.0), (0.0, 0.0, 0.0), (0.9, 0.0, 0.0)),
    ],
)
def test_seed_within_tolerance_is_returned_at_iteration_zero(free6, tols, where, dp, w):
    """Any pose within tol_pos/tol_rot is accepted as is, wherever the target and tolerances."""
    model, fid = free6
    q0 = np.array([*where, 0.3, -0.2, 0.1])
    target = _offset(_fk(model, fid, q0), dp, w)
    res = IKSolver(model, fid, *FREE, **tols).solve(target, q0)
    assert res.success is True
    assert res.iterations == 0 and res.restarts == 0
    np.testing.assert_array_equal(res.q, q0)
    assert res.position_error == pytest.approx(np.linalg.norm(dp), rel=1e-6, abs=1e-15)
    assert res.rotation_error == pytest.approx(np.linalg.norm(w), rel=1e-6, abs=1e-15)


def test_seed_just_outside_the_default_tolerance_is_refined(free6):
    """The default tolerances are 1e-6 m and 1e-5 rad: a 2e-5 rad error is not accepted."""
    model, fid = free6
    q0 = np.array([0.6, 0.0, 0.8, 0.3, -0.2, 0.1])
    target = _offset(_fk(model, fid, q0), np.zeros(3), (0.0, 2e-5, 0.0))
    res = IKSolver(model, fid, *FREE).solve(target, q0)
    assert res.success and res.iterations >= 1
    pos, rot = _pose_errors(model, fid, res.q, target)
    assert pos <= 1e-6 and rot <= 1e-5


def test_tolerance_bounds_are_inclusive(free6):
    """A pose whose error equals the tolerance to the bit is accepted."""
    model, fid = free6
    q0 = np.array([0.6, 0.1, 0.8, 0.0, 0.0, 0.0])
    pose = _fk(model, fid, q0)
    target = pin.SE3(pose.rotation, pose.translation + np.array([3e-6, 0.0, 0.0]))
    dp = pose.translation - target.translation
    assert dp[1] == dp[2] == 0.0
    res = IKSolver(model, fid, *FREE, tol_pos=abs(dp[0])).solve(target, q0)
    assert res.success and res.iterations == 0
    target = pin.SE3(pin.exp3(np.array([0.0, 0.0, 3e-5])), pose.translation)
    w = pin.log6(pose * target.inverse()).vector[3:]
    assert w[0] == w[1] == 0.0
    res = IKSolver(model, fid, *FREE, tol_rot=abs(w[2])).solve(target, q0)
    assert res.success and res.iterations == 0


def test_an_attempt_without_progress_stops_after_six_iterations(gen3):
    """Frame 0 (the world) never moves: each attempt gives up after 6 steps without a new best."""
    model, _, lower, upper = gen3
    target = pin.SE3(np.eye(3), np.array([0.1, 0.0, 0.0]))
    res = IKSolver(model, 0, lower, upper, max_restarts=2).solve(target, HOME)
    assert res.success is False
    assert res.restarts == 2
    assert res.iterations == 3 * 6
    np.testing.assert_array_equal(res.q, HOME)  # all attempts tie: the first one is kept
    assert res.position_error == pytest.approx(0.1, abs=1e-15)
    assert res.rotation_error == 0.0


def test_a_failed_box_qp_ends_the_attempt_where_it_stands(gen3, monkeypatch):
    """mju_boxQP reports failure (< 0, a Hessian it cannot factor): no step is taken and the
    attempt ends; the next seed is tried."""
    model, fid, lower, upper = gen3
    target = _fk(model, fid, HOME)
    target.translation += [0.001, 0, 0]  # 1 mm from the seed: the seed is the best start
    calls = []
    monkeypatch.setattr(mujoco, "mju_boxQP", lambda *args: calls.append(1) or -1)
    res = IKSolver(model, fid, lower, upper, max_restarts=2).solve(target, HOME)
    assert (res.success, res.restarts, res.iterations, len(calls)) == (False, 2, 0, 3)
    np.testing.assert_array_equal(res.q, HOME)  # no attempt moved
    assert res.position_error == pytest.approx(0.001, rel=1e-9)


def test_each_attempt_is_bounded_by_max_iters():
    """Three slides, a target 1 km away: every step improves, all 1 + 20 attempts run 50."""
    model, fid = _chain([pin.JointModelPX(), pin.JointModelPY(), pin.JointModelPZ()])
    target = pin.SE3(np.eye(3), np.array([1000.0, 0.0, 0.0]))
    res = IKSolver(model, fid, np.full(3, -np.inf), np.full(3, np.inf)).solve(target, np.zeros(3))
    assert res.success is False
    assert res.restarts == 20
    assert res.iterations == 21 * 50
    assert 900.0 < res.position_error < 1000.0


def test_default_seed_is_zero(gen3):
    model, fid, lower, upper = gen3
    target = pin.SE3(np.eye(3), np.array([3.0, 0.0, 0.5]))
    default = IKSolver(model, fid, lower, upper, max_restarts=2).solve(target, HOME)
    zero = IKSolver(model, fid, lower, upper, max_restarts=2, seed=0).solve(target, HOME)
    one = IKSolver(model, fid, lower, upper, max_restarts=2, seed=1).solve(target, HOME)
    np.testing.assert_array_equal(default.q, zero.q)
    assert default.iterations == zero.iterations
    assert not np.array_equal(default.q, one.q)


@pytest.mark.parametrize(
    ("joints", "frame"),
    [
        (None, "forearm_link"),  # joints 5-7 do not carry the frame
        ([1, 2, 3, 4, 5, 6], "pinch_site"),  # a run that does not end q
        ([1, 2, 4, 5, 6, 7], "pinch_site"),  # not contiguous in q
    ],
)
def test_one_step_is_the_damped_gauss_newton_step(gen3, joints, frame):
    """max_iters=1: q + (J'J + λI)⁻¹J'(-e), λ = 3e-3|e|² + 1e-9, with Pinocchio's world Jacobian."""
    model, _, lower, upper = gen3
    fid = model.getFrameId(frame)
    cols = list(range(7)) if joints is None else [j - 1 for j in joints]
    q_rest = HOME.copy()
    q_rest[2] = 2.9
    q_goal = q_rest.copy()
    q_goal[cols] += 0.05
    target = _fk(model, fid, q_goal)
    solver = IKSolver(
        model, fid, lower[cols], upper[cols], max_iters=1, max_restarts=0, joints=joints
    )
    res = solver.solve(target, q_rest[cols], q_rest)
    data = model.createData()
    jac = pin.computeFrameJacobian(model, data, q_rest, fid, pin.WORLD)[:, cols]
    e = pin.log6(_fk(model, fid, q_rest) * target.inverse()).vector
    lam = 3e-3 * e.dot(e) + 1e-9
    step = -np.linalg.solve(jac.T @ jac + lam * np.eye(len(cols)), jac.T @ e)
    assert res.iterations == 1 and res.restarts == 0 and res.success is False
    np.testing.assert_allclose(res.q, q_rest[cols] + step, rtol=0, atol=1e-10)
    full = q_rest.copy()
    full[cols] = res.q
    pos, rot = _pose_errors(model, fid, full, target)
    assert res.position_error == pytest.approx(pos, abs=1e-12)
    assert res.rotation_error == pytest.approx(rot, abs=1e-9)


@pytest.mark.parametrize(
    ("lo", "hi", "goal"), [(2.0, 3.0, -1.0), (-3.0, -2.0, 1.0), (-np.inf, -2.0, 1.0)]
)
def test_restarts_start_inside_the_limits(lo, hi, goal):
    """One slide, a goal outside its range but within tol_pos of some seeds outside it."""
    model, fid = _chain([pin.JointModelPX()])
    solver = IKSolver(model, fid, np.array([lo]), np.array([hi]), tol_pos=0.5)
    res = solver.solve(pin.SE3(np.eye(3), np.array([goal, 0.0, 0.0])), np.array([0.0]))
    assert res.success is False and res.restarts == 20
    assert lo <= res.q[0] <= hi
    near = hi if goal > hi else lo
    assert res.q[0] == near
    assert res.position_error == pytest.approx(abs(goal - near), abs=1e-12)


def test_stuck_at_a_bound_the_attempt_runs_until_it_stalls():
    """From 2.5 the first step hits the bound 3 and stays: 1 improving step, then 6 stalled."""
    model, fid = _chain([pin.JointModelPX()])
    solver = IKSolver(model, fid, np.array([2.0]), np.array([3.0]), max_restarts=0)
    res = solver.solve(pin.SE3(np.eye(3), np.array([5.0, 0.0, 0.0])), np.array([2.5]))
    assert res.success is False
    assert res.iterations == 7
    assert res.q[0] == 3.0
    assert res.position_error == 2.0


def test_fully_locked_chain_stays_at_the_lock():
    """lower == upper everywhere: the answer is the lock to the bit even when pushed past it."""
    model, fid = _chain([pin.JointModelPX()])
    lock = np.array([1.0])
    solver = IKSolver(model, fid, lock, lock, max_restarts=1)
    res = solver.solve(pin.SE3(np.eye(3), np.array([2.0, 0.0, 0.0])), np.array([0.0]))
    assert res.success is False
    assert res.q[0] == 1.0
    assert res.position_error == 1.0


def test_seed_below_a_lower_limit_is_clipped_first(gen3):
    """The target is where the clipped seed puts the TCP: solved there without a step."""
    model, fid, lower, upper = gen3
    q0 = HOME.copy()
    q0[1] = lower[1] - 0.2
    clipped = np.clip(q0, lower, upper)
    res = IKSolver(model, fid, lower, upper).solve(_fk(model, fid, clipped), q0)
    assert res.success and res.iterations == 0
    np.testing.assert_array_equal(res.q, clipped)


@pytest.mark.filterwarnings("ignore:overflow encountered in dot")
def test_huge_finite_seed_is_clipped_not_refused(gen3):
    model, fid, lower, upper = gen3
    q0 = HOME.copy()
    q0[1] = 1e200  # finite, though q0·q0 overflows
    clipped = np.clip(q0, lower, upper)
    res = IKSolver(model, fid, lower, upper).solve(_fk(model, fid, clipped), q0)
    assert res.success and res.iterations == 0
    np.testing.assert_array_equal(res.q, clipped)


def test_limits_as_integers_or_a_column(gen3):
    model, fid, _, _ = gen3
    lower, upper = [-3] * 7, [3] * 7
    target = _fk(model, fid, np.full(7, 0.5))
    as_float = IKSolver(model, fid, np.full(7, -3.0), np.full(7, 3.0)).solve(target, HOME)
    as_int = IKSolver(model, fid, lower, upper).solve(target, HOME)
    as_column = IKSolver(model, fid, np.reshape(lower, (7, 1)), np.reshape(upper, (7, 1)))
    assert as_float.success
    np.testing.assert_array_equal(as_int.q, as_float.q)
    np.testing.assert_array_equal(as_column.solve(target, HOME).q, as_float.q)


def _message(call) -> str:
    with pytest.raises(SpecError) as err:
        call()
    return str(err.value)


def test_constructor_messages_name_the_argument(gen3):
    model, fid, lower, upper = gen3
    n = model.njoints

    def make(**kw):
        args = {"model": model, "frame_id": fid, "lower": lower, "upper": upper, **kw}
        return lambda: IKSolver(**args)

    one_dof = "joints must be 1-DoF joints of the model (nq == nv == 1 each)"
    assert _message(make(model="gen3")) == "model must be a pinocchio.Model, got str"
    assert _message(make(joints=[])) == one_dof
    assert _message(make(joints=[n], lower=lower[:1], upper=upper[:1])) == one_dof
    assert _message(make(joints=[2, 2], lower=lower[:2], upper=upper[:2])) == (
        "joints must be distinct and in the model's order"
    )
    assert _message(make(lower=lower[:3])) == "lower must have length 7, got shape (3,)"
    assert _message(make(upper=upper[:3])) == "upper must have length 7, got shape (3,)"
    bad = upper.copy()
    bad[2] = np.nan
    assert _message(make(upper=bad)) == "upper must not contain NaN"
    assert _message(make(lower=[None, *lower[1:]])) == "lower must not contain NaN"
    order = "lower must be <= upper for every joint, with lower < +inf"
    swapped = lower.copy()
    swapped[1] = upper[1] + 0.1
    assert _message(make(lower=swapped)) == order
    plus_inf = np.where(np.arange(7) == 0, np.inf, lower)
    assert _message(make(lower=plus_inf, upper=np.full(7, np.inf))) == order
    minus_inf = np.where(np.arange(7) == 0, -np.inf, upper)
    assert _message(make(lower=np.full(7, -np.inf), upper=minus_inf)) == order
    tols = "tol_pos and tol_rot must be positive"
    assert _message(make(tol_pos=0.0)) == tols
    assert _message(make(tol_rot=0.0)) == tols
    counts = "max_iters must be >= 1 and max_restarts >= 0"
    assert _message(make(max_iters=0)) == counts
    assert _message(make(max_restarts=-1)) == counts
    assert _message(make(frame_id=model.nframes)) == (
        f"frame_id {model.nframes} out of range [0, {model.nframes})"
    )


def test_joint_with_two_coordinates_is_refused():
    """A continuous (unbounded revolute) joint has nq == 2, nv == 1."""
    model, fid = _chain([pin.JointModelPX(), pin.JointModelRUBZ()])
    assert (
        _message(lambda: IKSolver(model, fid, [0.0], [1.0], joints=[2]))
        == "joints must be 1-DoF joints of the model (nq == nv == 1 each)"
    )


def test_solve_messages_name_the_argument(gen3):
    model, fid, lower, upper = gen3
    solver = IKSolver(model, fid, lower[1:], upper[1:], joints=list(range(2, 8)))
    target = _fk(model, fid, HOME)
    assert _message(lambda: solver.solve(target.homogeneous, HOME[1:], HOME)) == (
        "target must be a pinocchio.SE3, got ndarray"
    )
    assert _message(lambda: solver.solve(target, HOME[1:], HOME[:3])) == (
        "q_rest must be the whole model's configuration (7 values)"
    )
