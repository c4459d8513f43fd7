"""IKSolver on the Kinova Gen3 from MuJoCo Menagerie: accuracy, limits, failure, input checks."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from mjkdl.errors import SpecError
from mjkdl.ik import IKResult, IKSolver

HOME = np.array([0.0, 0.2618, 3.1416, -2.2689, 0.0, 0.9599, 1.5708])
TOL_POS, TOL_ROT = 1e-6, 1e-5


def _gen3_path() -> Path:
    root = os.environ.get("MENAGERIE_ROOT")
    base = Path(root) if root else Path(__file__).resolve().parents[2] / "shared" / "menagerie"
    return base / "kinova_gen3" / "gen3.xml"


@pytest.fixture(scope="module")
def gen3() -> tuple[pin.Model, int, np.ndarray, np.ndarray]:
    """Gen3 model, the pinch_site frame id, and its joint limits (±inf when unlimited)."""
    path = _gen3_path()
    if not path.is_file():
        pytest.skip(f"Kinova Gen3 MJCF not found at {path} (set MENAGERIE_ROOT)")
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
