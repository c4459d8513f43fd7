"""Reward and termination helpers against hand-computed numbers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import import_extra

import mjkdl as mjk
from mjkdl.task import (
    Held,
    Lifted,
    LiftReward,
    Placed,
    PlaceReward,
    Reached,
    ReachReward,
    SparseReward,
    distance,
    height,
    place_reward,
)


def obs(tcp, cube, contacts=(0.0, 0.0)) -> dict[str, np.ndarray]:
    return {
        "tcp_pos": np.array(tcp, float),
        "cube_pose": np.array([*cube, 1, 0, 0, 0], float),
        "cube_contacts": np.array(contacts, float),
    }


def test_distance_and_height() -> None:
    o = obs([0.0, 0.0, 0.0], [0.3, 0.4, 0.0])
    assert distance(o, "tcp_pos", "cube_pose") == pytest.approx(0.5, abs=1e-15)
    assert height(o, "cube_pose") == 0.0


def test_reach_reward_halves_closeness_and_success() -> None:
    r = ReachReward("tcp_pos", "cube_pose")
    assert r(obs([0, 0, 0], [0.3, 0.4, 0])) == pytest.approx(0.5 * (1 - math.tanh(2.0)))
    assert r(obs([0, 0, 0], [0.03, 0.04, 0])) == pytest.approx(0.5 * (1 - math.tanh(0.2)) + 0.5)
    assert r(obs([1, 1, 1], [1, 1, 1])) == 1.0
    wide = ReachReward("tcp_pos", "cube_pose", success_distance=0.6, scale=1.0)
    assert wide(obs([0, 0, 0], [0.3, 0.4, 0])) == pytest.approx(0.5 * (1 - math.tanh(0.5)) + 0.5)


def test_reach_reward_never_pays_a_failure_more_than_a_success() -> None:
    r = ReachReward("tcp_pos", "cube_pose", success_distance=0.05)
    before = [r(obs([0, 0, 0], [d, 0, 0])) for d in np.linspace(0.0501, 0.6, 200)]
    after = [r(obs([0, 0, 0], [d, 0, 0])) for d in np.linspace(0.0, 0.05, 50)]
    assert max(before) < min(after)
    assert all(np.diff(before) < 0) and all(np.diff(after) < 0)  # closer pays more


def test_reached_and_lifted() -> None:
    assert Reached("tcp_pos", "cube_pose", 0.05)(obs([0, 0, 0], [0.03, 0.04, 0]))
    assert not Reached("tcp_pos", "cube_pose", 0.049)(obs([0, 0, 0], [0.03, 0.04, 0]))
    assert Lifted("cube_pose", rest_z=0.02, lift=0.1)(obs([0, 0, 0], [0, 0, 0.1201]))
    assert not Lifted("cube_pose", rest_z=0.02, lift=0.1)(obs([0, 0, 0], [0, 0, 0.1199]))


def test_lift_reward_stages() -> None:
    r = LiftReward("tcp_pos", "cube_pose", "cube_contacts", rest_z=0.02, lift=0.05)
    # Far away (0.5 m, where PickCube's episodes start), at rest: 0.25 * (1 - tanh(0.5 / 0.3)),
    # a reward with a gradient (0.1 m paid 0.25 * (1 - tanh(5)) = 2.3e-5).
    far = r(obs([0, 0, 0.52], [0, 0, 0.02]))
    assert far == pytest.approx(0.25 * (1 - math.tanh(0.5 / 0.3))) and far > 0.015
    # TCP on the cube, one finger touching: reach only.
    assert r(obs([0, 0, 0.02], [0, 0, 0.02], (1, 0))) == pytest.approx(0.25)
    # Grasped at rest, then raised 2 cm of 5: 0.25 + 0.25 + 0.25 * 0.4.
    assert r(obs([0, 0, 0.02], [0, 0, 0.02], (1, 1))) == pytest.approx(0.5)
    assert r(obs([0, 0, 0.04], [0, 0, 0.04], (1, 1))) == pytest.approx(0.6)
    # Lifted and held: success pays 1; lifted without the fingers: only the reach.
    assert r(obs([0, 0, 0.07], [0, 0, 0.07], (1, 1))) == 1.0
    assert r(obs([0, 0, 0.07], [0, 0, 0.07])) == pytest.approx(0.25)


def test_shaped_lift_reward_pulls_from_afar_and_pays_the_last_centimetres() -> None:
    """PickCube's `reward_type="shaped"`: the reach stage the mean of a 0.5 m and a 5 cm
    term; the other stages and the success as the dense reward's."""
    r = LiftReward("tcp_pos", "cube_pose", "cube_contacts", 0.02, 0.05, 0.5, near_scale=0.05)
    far = r(obs([0, 0, 0.52], [0, 0, 0.02]))
    assert far == pytest.approx(0.125 * (1 - math.tanh(1.0)) + 0.125 * (1 - math.tanh(10)))
    # 2 cm off: the near term pays 0.125 * (1 - tanh(0.4)) of it.
    near = r(obs([0, 0, 0.04], [0, 0, 0.02]))
    assert near == pytest.approx(0.125 * (2 - math.tanh(0.04) - math.tanh(0.4)))
    assert r(obs([0, 0, 0.02], [0, 0, 0.02], (1, 1))) == pytest.approx(0.5)
    assert r(obs([0, 0, 0.07], [0, 0, 0.07], (1, 1))) == 1.0


def test_held_needs_the_height_and_every_contact() -> None:
    held = Held("cube_pose", "cube_contacts", rest_z=0.02, lift=0.05)
    assert held(obs([0, 0, 0], [0, 0, 0.0701], (1, 1)))
    assert not held(obs([0, 0, 0], [0, 0, 0.0699], (1, 1)))
    assert not held(obs([0, 0, 0], [0, 0, 0.2], (1, 0)))


def test_sparse_reward_is_the_success() -> None:
    sparse = SparseReward(Reached("tcp_pos", "cube_pose", 0.05))
    assert sparse(obs([0, 0, 0], [0.03, 0.04, 0])) == 1.0
    assert sparse(obs([0, 0, 0], [0.03, 0.041, 0])) == 0.0
    with pytest.raises(TypeError, match=r"SparseReward\.success must be callable, got 3"):
        SparseReward(3)


def test_unknown_observation_names_it() -> None:
    with pytest.raises(KeyError, match=r"'tcp_ps'.*close matches: tcp_pos"):
        distance(obs([0, 0, 0], [0, 0, 0]), "tcp_ps", "cube_pose")
    with pytest.raises(ValueError, match="'t' has no x, y, z"):
        height({"t": np.zeros(1)}, "t")


NAN = float("nan")


@pytest.mark.parametrize(
    ("build", "error", "message"),
    [
        (
            lambda: ReachReward("a", "b", scale=0),
            mjk.SpecError,
            "ReachReward.scale must be positive, got 0",
        ),
        (
            lambda: ReachReward("a", "b", scale=-1),
            mjk.SpecError,
            "ReachReward.scale must be positive, got -1",
        ),
        (
            lambda: ReachReward("a", "b", scale="1"),
            mjk.SpecTypeError,
            "ReachReward.scale must be a number, got '1'",
        ),
        (
            lambda: ReachReward("a", "b", scale=NAN),
            mjk.SpecError,
            "ReachReward.scale must be finite, got nan",
        ),
        (
            lambda: ReachReward("a", None, 1.0),
            mjk.SpecTypeError,
            "ReachReward.b must be a string, got None",
        ),
        (
            lambda: Reached("a", "b", tolerance=None),
            mjk.SpecTypeError,
            "Reached.tolerance must be a number, got None",
        ),
        (
            lambda: Reached("a", "b", tolerance=NAN),
            mjk.SpecError,
            "Reached.tolerance must be finite, got nan",
        ),
        (
            lambda: Reached(["a"], "b", 0.1),
            mjk.SpecTypeError,
            "Reached.a must be a string, got ['a']",
        ),
        (
            lambda: Lifted("a", rest_z=0.0, lift="0.1"),
            mjk.SpecTypeError,
            "Lifted.lift must be a number, got '0.1'",
        ),
        (
            lambda: Lifted("a", rest_z=0.0, lift=0),
            mjk.SpecError,
            "Lifted.lift must be positive, got 0",
        ),
        (
            lambda: Lifted("a", rest_z=True, lift=0.1),
            mjk.SpecTypeError,
            "Lifted.rest_z must be a number, got True",
        ),
        (
            lambda: LiftReward("t", "o", "c", rest_z=None, lift=0.1),
            mjk.SpecTypeError,
            "LiftReward.rest_z must be a number, got None",
        ),
        (
            lambda: LiftReward("t", "o", "c", rest_z=0.0, lift=0),
            mjk.SpecError,
            "LiftReward.lift must be positive, got 0",
        ),
        (
            lambda: LiftReward("t", "o", "c", 0.0, 0.1, reach_scale=0),
            mjk.SpecError,
            "LiftReward.reach_scale must be positive, got 0",
        ),
        (
            lambda: LiftReward("t", "o", "c", 0.0, 0.1, near_scale=-0.05),
            mjk.SpecError,
            "LiftReward.near_scale must be >= 0 (0: off), got -0.05",
        ),
        (
            lambda: LiftReward("t", "o", "c", 0.0, 0.1, near_scale="0.05"),
            mjk.SpecTypeError,
            "LiftReward.near_scale must be a number, got '0.05'",
        ),
        (
            lambda: PlaceReward("t", "o", "g", bool, near_scale=-0.05),
            mjk.SpecError,
            "PlaceReward.near_scale must be >= 0 (0: off), got -0.05",
        ),
        (
            lambda: LiftReward(5, "o", "c", 0.0, 0.1),
            mjk.SpecTypeError,
            "LiftReward.tcp must be a string, got 5",
        ),
        (
            lambda: Placed("o", "g", 0),
            mjk.SpecError,
            "Placed.tolerance must be positive, got 0",
        ),
        (
            lambda: Placed("o", "g", 0.02, contacts=None),
            mjk.SpecTypeError,
            "Placed.contacts must be a string, got None",
        ),
        (
            lambda: PlaceReward("t", "o", "g", bool, behind=-0.01),
            mjk.SpecError,
            "PlaceReward.behind must be >= 0 (0: off), got -0.01",
        ),
        (
            lambda: PlaceReward("t", "o", "g", bool, gate=-1),
            mjk.SpecError,
            "PlaceReward.gate must be >= 0 (0: off), got -1",
        ),
        (
            lambda: PlaceReward("t", "o", "g", bool, behind=0.035, over=-0.06),
            mjk.SpecError,
            "PlaceReward.over must be >= 0 (0: off), got -0.06",
        ),
        (
            lambda: PlaceReward("t", "o", "g", bool, over=0.06),
            mjk.SpecError,
            "PlaceReward.over needs PlaceReward.behind: the path goes over the object to the "
            "reach point behind it",
        ),
        (
            lambda: PlaceReward("t", "o", "g", bool, "c", hold="yes"),
            mjk.SpecTypeError,
            "PlaceReward.hold must be True or False, got 'yes'",
        ),
        (
            lambda: PlaceReward("t", "o", "g", bool, hold=True),
            mjk.SpecError,
            "PlaceReward.hold needs PlaceReward.contacts: the ContactSensor observation that "
            "says the object is grasped",
        ),
        (
            lambda: PlaceReward("t", "o", "g", success=3),
            mjk.SpecTypeError,
            "PlaceReward.success must be callable, got 3",
        ),
        (
            lambda: PlaceReward("t", "o", "g", Placed("o", "g", 0.02), goal_scale=-1),
            mjk.SpecError,
            "PlaceReward.goal_scale must be positive, got -1",
        ),
    ],
)
def test_helpers_check_their_fields_when_built(build, error, message) -> None:
    with pytest.raises(error) as err:
        build()
    assert str(err.value) == message


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (
            lambda o: distance(o, None, "cube_pose"),
            "an observation name must be a string, got None",
        ),
        (
            lambda o: distance(o, "tcp_pos", ["a"]),
            "an observation name must be a string, got ['a']",
        ),
        (lambda o: height(o, 3), "an observation name must be a string, got 3"),
        (
            lambda o: distance(None, "tcp_pos", "cube_pose"),
            "the observation must be a mapping of names to arrays, got None",
        ),
    ],
)
def test_distance_and_height_check_their_arguments(call, message) -> None:
    with pytest.raises(mjk.SpecTypeError) as err:
        call(obs([0, 0, 0], [0, 0, 0]))
    assert str(err.value) == message


def test_placed_needs_the_goal_and_with_contacts_the_release() -> None:
    near = {**obs([0, 0, 0], [0.3, 0.0, 0.06], (0, 0)), "goal_pose": np.array([0.3, 0.019, 0.06])}
    assert Placed("cube_pose", "goal_pose", 0.02)(near)
    assert not Placed("cube_pose", "goal_pose", 0.018)(near)
    stack = Placed("cube_pose", "goal_pose", 0.02, contacts="cube_contacts")
    assert stack(near)
    assert not stack({**near, "cube_contacts": np.array([1.0, 0.0])})  # still held


def test_place_reward_stages_and_pays_success_most() -> None:
    success = Placed("cube_pose", "goal_pose", 0.05)
    r = PlaceReward("tcp_pos", "cube_pose", "goal_pose", success, contacts="cube_contacts")
    goal = {"goal_pose": np.array([0.5, 0.0, 0.02])}
    far = {**obs([0, 0, 0.3], [0.0, 0.0, 0.02]), **goal}
    expected = 0.25 * (1 - math.tanh(math.hypot(0.28, 0) / 0.1)) + 0.5 * (1 - math.tanh(2.0))
    assert r(far) == pytest.approx(expected)
    held = {**obs([0.2, 0, 0.02], [0.2, 0.0, 0.02], (1, 1)), **goal}
    assert r(held) == pytest.approx(0.25 + 0.25 + 0.5 * (1 - math.tanh(0.3 / 0.25)))
    there = {**obs([0.47, 0, 0.02], [0.47, 0.0, 0.02]), **goal}
    assert r(there) == 1.0
    # Just outside the goal, grasped and at the cube: below 1.
    edge = {**obs([0.449, 0, 0.02], [0.449, 0.0, 0.02], (1, 1)), **goal}
    assert r(edge) < 1.0


def test_shaped_place_reward_pulls_from_afar() -> None:
    """`reward_type="shaped"` on Push, PickAndPlace and Stack: the reach term the mean of a
    0.5 m and a 5 cm one, the grasp and goal stages as the dense reward's."""
    success = Placed("cube_pose", "goal_pose", 0.05)
    r = PlaceReward("tcp_pos", "cube_pose", "goal_pose", success, "", 0.5, near_scale=0.05)
    goal = {"goal_pose": np.array([0.5, 0.0, 0.02])}
    far = {**obs([0, 0, 0.52], [0.0, 0.0, 0.02]), **goal}
    reach = 0.5 * (1 - math.tanh(1.0)) + 0.5 * (1 - math.tanh(10.0))
    assert r(far) == pytest.approx(0.25 * reach + 0.5 * (1 - math.tanh(2.0)))
    assert place_reward(0.5, 0.5, False, 0.5, 0.25, 0.05) == pytest.approx(r(far))


def test_place_reward_reaches_behind_the_object_away_from_the_goal() -> None:
    """`behind`: the reach point lies that far behind the object on the line from the goal,
    in the horizontal plane; a hand there is paid the whole reach term."""
    success = Placed("cube_pose", "goal_pose", 0.05)
    r = PlaceReward("tcp_pos", "cube_pose", "goal_pose", success, behind=0.035)
    goal = {"goal_pose": np.array([0.3, 0.4, 0.02])}  # 0.5 m away along (0.6, 0.8)
    goal_term = 0.5 * (1 - math.tanh(0.5 / 0.25))
    behind = {**obs([-0.021, -0.028, 0.02], [0.0, 0.0, 0.02]), **goal}
    assert r(behind) == pytest.approx(0.25 + goal_term, abs=1e-9)
    # The hand on the cube's centre is `behind` from the point; in front, twice that.
    on = {**behind, "tcp_pos": np.array([0.0, 0.0, 0.02])}
    front = {**behind, "tcp_pos": np.array([0.021, 0.028, 0.02])}
    assert r(on) == pytest.approx(0.25 * (1 - math.tanh(0.035 / 0.1)) + goal_term)
    assert r(front) == pytest.approx(0.25 * (1 - math.tanh(0.07 / 0.1)) + goal_term)
    # Height counts as distance: the point is at the object's height.
    above = {**behind, "tcp_pos": np.array([-0.021, -0.028, 0.07])}
    assert r(above) == pytest.approx(0.25 * (1 - math.tanh(0.05 / 0.1)) + goal_term)


def test_place_reward_with_gate_pays_the_goal_only_at_the_reach_point() -> None:
    """`gate`: the goal term only while the TCP is that near its reach point (behind the cube
    for Push), so knocking the cube about on the way costs nothing."""
    success = Placed("cube_pose", "goal_pose", 0.05)
    r = PlaceReward("tcp_pos", "cube_pose", "goal_pose", success, behind=0.035, gate=0.02)
    at = {**obs([-0.035, 0.0, 0.02], [0.0, 0.0, 0.02]), "goal_pose": np.array([0.2, 0, 0.02])}
    assert r(at) == pytest.approx(0.25 + 0.5 * (1 - math.tanh(0.2 / 0.25)))
    off = {**at, "tcp_pos": np.array([-0.035, 0.021, 0.02])}
    assert r(off) == pytest.approx(0.25 * (1 - math.tanh(0.021 / 0.1)))
    assert place_reward(0.021, 0.2, False, 0.1, 0.25, gate=0.02) == pytest.approx(r(off))


def test_place_reward_with_over_charges_the_path_over_the_object() -> None:
    """`over`: a hand on the object's near side (more than `gate` past the reach point
    towards the goal) is charged the path up to `over` above the reach point, across and
    down; behind it, the straight distance. Pressed against the near face, the hand is paid
    less than anywhere on the way over."""
    success = Placed("cube_pose", "goal_pose", 0.05)
    r = PlaceReward(
        "tcp_pos", "cube_pose", "goal_pose", success, behind=0.035, gate=0.02, over=0.06
    )
    goal = {"goal_pose": np.array([0.3, 0.0, 0.02])}

    def reach(d: float) -> float:
        return 0.25 * (1 - math.tanh(d / 0.1))

    near_face = {**obs([0.03, 0.0, 0.02], [0.0, 0.0, 0.02]), **goal}
    assert r(near_face) == pytest.approx(reach(0.065 + 0.06 + 0.06))
    over_top = {**near_face, "tcp_pos": np.array([0.0, 0.0, 0.08])}
    assert r(over_top) == pytest.approx(reach(0.035 + 0.06))
    assert r(over_top) > r(near_face)
    # High up on the near side: down to `over`, across, down.
    high = {**near_face, "tcp_pos": np.array([0.1, 0.0, 0.3])}
    assert r(high) == pytest.approx(reach(0.22 + 0.135 + 0.06))
    # Within `gate` past the point, or behind it, straight: as without `over`.
    straight = PlaceReward("tcp_pos", "cube_pose", "goal_pose", success, behind=0.035, gate=0.02)
    for x in (-0.016, -0.2):
        behind = {**near_face, "tcp_pos": np.array([x, 0.03, 0.1])}
        assert r(behind) == pytest.approx(straight(behind), abs=1e-15)
    assert r(over_top) < straight(over_top)


def test_place_reward_with_hold_pays_the_goal_only_while_grasped() -> None:
    """`hold`: the cube pushed right under its goal pays no goal term until it is grasped."""
    success = Placed("cube_pose", "goal_pose", 0.03)
    r = PlaceReward(
        "tcp_pos", "cube_pose", "goal_pose", success, contacts="cube_contacts", hold=True
    )
    under = {**obs([0.0, 0.0, 0.02], [0.0, 0.0, 0.02]), "goal_pose": np.array([0, 0, 0.12])}
    assert r(under) == pytest.approx(0.25)
    held = {**under, "cube_contacts": np.array([1.0, 1.0])}
    assert r(held) == pytest.approx(0.5 + 0.5 * (1 - math.tanh(0.1 / 0.25)))
    assert place_reward(0.0, 0.1, False, 0.1, 0.25, hold=True) == pytest.approx(0.25)
    both = place_reward(np.zeros(2), np.full(2, 0.1), np.array([False, True]), 0.1, 0.25, hold=True)
    np.testing.assert_allclose(both, [r(under), r(held)], rtol=0, atol=1e-15)


def test_place_reward_formula_takes_batches() -> None:
    """The formula a batched backend evaluates: arrays with a leading batch axis give the
    numbers the scalar reward gives one by one."""
    rng = np.random.default_rng(0)
    d_reach, d_goal = rng.uniform(0, 0.5, 64), rng.uniform(0.01, 0.5, 64)
    grasped = rng.uniform(size=64) < 0.5
    batch = place_reward(d_reach, d_goal, grasped, 0.1, 0.25)
    one = [
        place_reward(a, b, c, 0.1, 0.25) for a, b, c in zip(d_reach, d_goal, grasped, strict=True)
    ]
    assert batch.shape == (64,)
    np.testing.assert_allclose(batch, one, rtol=0, atol=1e-15)
    assert batch.max() < 1.0


def test_every_rule_evaluates_batches_as_it_evaluates_one_world() -> None:
    """`evaluate` on (N, k) torch tensors (the batched backend's call) gives, world by world,
    what the CPU env's call gives on that world's NumPy observation."""
    torch = import_extra("warp", "torch")
    from mjkdl.task.goal import GoalReward
    from mjkdl.task.rewards import batchable

    rng = np.random.default_rng(5)
    n = 256
    tcp = rng.uniform(-0.1, 0.1, (n, 3))
    cube = tcp + rng.normal(0, 0.02, (n, 3))
    cube[:, 2] = rng.uniform(0.0, 0.12, n)
    goal = cube + rng.normal(0, 0.04, (n, 3))
    worlds = {
        "tcp_pos": tcp,
        "cube_pose": np.concatenate([cube, np.tile([1.0, 0, 0, 0], (n, 1))], 1),
        "goal_pose": np.concatenate([goal, np.tile([1.0, 0, 0, 0], (n, 1))], 1),
        "cube_contacts": (rng.uniform(size=(n, 2)) < 0.6).astype(float),
    }
    placed = Placed("cube_pose", "goal_pose", 0.03, "cube_contacts")
    rules = [
        Reached("tcp_pos", "cube_pose", 0.02),
        ReachReward("tcp_pos", "cube_pose", 0.02, 0.1),
        Lifted("cube_pose", 0.02, 0.05),
        Held("cube_pose", "cube_contacts", 0.02, 0.05),
        LiftReward("tcp_pos", "cube_pose", "cube_contacts", 0.02, 0.05, 0.5, 0.05),
        LiftReward("tcp_pos", "cube_pose", "cube_contacts", 0.02, 0.05),
        placed,
        Placed("cube_pose", "goal_pose", 0.03),
        PlaceReward("tcp_pos", "cube_pose", "goal_pose", placed, contacts="cube_contacts"),
        PlaceReward(
            "tcp_pos",
            "cube_pose",
            "goal_pose",
            placed,
            "",
            0.5,
            near_scale=0.05,
            behind=0.035,
            gate=0.05,
        ),
        PlaceReward("tcp_pos", "cube_pose", "goal_pose", placed, behind=0.035, over=0.06),
        PlaceReward("tcp_pos", "cube_pose", "goal_pose", placed, "cube_contacts", hold=True),
        SparseReward(placed),
        GoalReward("cube_pose", "goal_pose", 0.03, "dense"),
        GoalReward("cube_pose", "goal_pose", 0.03, "sparse"),
    ]
    batch = {k: torch.as_tensor(v) for k, v in worlds.items()}
    for rule in rules:
        assert batchable(rule), rule
        got = rule.evaluate(batch)
        assert isinstance(got, torch.Tensor) and got.shape == (n,), rule
        one = np.array([rule({k: v[i] for k, v in worlds.items()}) for i in range(n)])
        assert len(set(one.tolist())) > 1, rule  # both outcomes (or several rewards) occur
        np.testing.assert_allclose(got.numpy().astype(float), one, rtol=0, atol=1e-12)
    # A success of the user's own (no `evaluate`) keeps a reward on the host.
    assert not batchable(SparseReward(lambda o: True))


@pytest.mark.parametrize(
    ("reward_type", "low", "high", "least"),
    [("dense", 0.014, 0.018, 0.01), ("shaped", 0.027, 0.030, 0.025)],
)
def test_pick_cube_pays_a_gradient_from_the_first_step(reward_type, low, high, least) -> None:
    """PickCube's hand starts about 0.5 m from the cube: its first step pays a median 0.016
    over 20 seeds with the dense reward (a reach scale of 0.3 m; 0.1 m paid 1.8e-5), 0.029
    with the shaped one (0.5 m and 5 cm)."""
    import gymnasium as gym
    from conftest import menagerie

    import mjkdl.task  # noqa: F401  (registers the tasks)

    menagerie("franka_emika_panda")
    env = gym.make("mjkdl/PandaPickCube-v0", reward_type=reward_type)
    rewards = []
    for seed in range(20):
        env.reset(seed=seed)
        rewards.append(env.step(np.zeros(7, np.float32))[1])
    env.close()
    assert low < float(np.median(rewards)) < high, np.median(rewards)
    assert min(rewards) > least


def test_place_tasks_shaped_reward_pays_the_reach_from_the_first_step() -> None:
    """Push's and PickAndPlace's hand starts about 0.5 m from the cube, where the dense
    reach term (0.1 m) pays nothing. The shaped reward's goal term waits for the hand (at the
    push point, or grasping), so its first step pays the reach alone: a median 0.028 for
    PickAndPlace, 0.018 for Push, whose reach counts the way over the cube (`over`)."""
    import gymnasium as gym
    from conftest import menagerie

    import mjkdl.task  # noqa: F401  (registers the tasks)

    menagerie("franka_emika_panda")
    for task, median in (("Push", 0.018), ("PickAndPlace", 0.028)):
        env = gym.make(f"mjkdl/Panda{task}-v0", reward_type="shaped")
        first = []
        for seed in range(10):
            env.reset(seed=seed)
            first.append(env.step(np.zeros(env.action_space.shape, np.float32))[1])
        env.close()
        assert float(np.median(first)) == pytest.approx(median, abs=0.001), task
        assert max(first) < 0.03, (task, max(first))  # no goal term before the hand is there


def test_shaped_reward_is_the_object_tasks_only() -> None:
    import gymnasium as gym
    from conftest import menagerie

    import mjkdl.task  # noqa: F401  (registers the tasks)

    menagerie("franka_emika_panda")
    for task, cls in [("Reach", "PandaReachEnv"), ("PickCubeGoal", "PandaPickCubeGoalEnv")]:
        with pytest.raises(mjk.SpecError) as err:
            gym.make(f"mjkdl/Panda{task}-v0", reward_type="shaped")
        assert str(err.value) == (
            f"{cls}: reward_type must be one of ['dense', 'sparse'], got 'shaped' ('shaped' "
            "is offered by PandaPickAndPlaceEnv, PandaPickCubeEnv, PandaPushEnv, PandaStackEnv)"
        )
    with pytest.raises(mjk.SpecError) as err:
        gym.make("mjkdl/PandaPickCube-v0", reward_type="staged")
    assert str(err.value) == (
        "PandaPickCubeEnv: reward_type must be one of ['dense', 'sparse', 'shaped'], got 'staged'"
    )
