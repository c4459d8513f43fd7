"""Reward and termination helpers against hand-computed numbers."""

from __future__ import annotations

import math

import numpy as np
import pytest

import mjkdl as mjk
from mjkdl.task import Lifted, LiftReward, Reached, ReachReward, distance, height


def obs(tcp, cube) -> dict[str, np.ndarray]:
    return {"tcp_pos": np.array(tcp, float), "cube_pose": np.array([*cube, 1, 0, 0, 0], float)}


def test_distance_and_height() -> None:
    o = obs([0.0, 0.0, 0.0], [0.3, 0.4, 0.0])
    assert distance(o, "tcp_pos", "cube_pose") == pytest.approx(0.5, abs=1e-15)
    assert height(o, "cube_pose") == 0.0


def test_reach_reward_is_one_minus_distance_clipped() -> None:
    assert ReachReward("tcp_pos", "cube_pose")(obs([0, 0, 0], [0.3, 0.4, 0])) == pytest.approx(0.5)
    assert ReachReward("tcp_pos", "cube_pose")(obs([0, 0, 0], [3, 4, 0])) == 0.0
    assert ReachReward("tcp_pos", "cube_pose", scale=2.0)(obs([0, 0, 0], [0.6, 0.8, 0])) == (
        pytest.approx(0.5)
    )
    assert ReachReward("tcp_pos", "cube_pose")(obs([1, 1, 1], [1, 1, 1])) == 1.0


def test_reached_and_lifted() -> None:
    assert Reached("tcp_pos", "cube_pose", 0.05)(obs([0, 0, 0], [0.03, 0.04, 0]))
    assert not Reached("tcp_pos", "cube_pose", 0.049)(obs([0, 0, 0], [0.03, 0.04, 0]))
    assert Lifted("cube_pose", rest_z=0.02, lift=0.1)(obs([0, 0, 0], [0, 0, 0.1201]))
    assert not Lifted("cube_pose", rest_z=0.02, lift=0.1)(obs([0, 0, 0], [0, 0, 0.1199]))


def test_lift_reward_sparse_plus_shaped() -> None:
    r = LiftReward("tcp_pos", "cube_pose", rest_z=0.02, lift=0.1, reach_scale=0.1)
    # Far away, at rest: 0.25 * (1 - tanh(5)).
    assert r(obs([0, 0, 0.52], [0, 0, 0.02])) == pytest.approx(0.25 * (1 - math.tanh(5.0)))
    # TCP on the cube, raised half way: 0.25 * 1 * (1 + 0.5).
    assert r(obs([0, 0, 0.07], [0, 0, 0.07])) == pytest.approx(0.375)
    # Lifted: the sparse 1 plus the full shaped 0.5.
    assert r(obs([0, 0, 0.13], [0, 0, 0.13])) == pytest.approx(1.5)


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
            lambda: LiftReward("t", "o", rest_z=None, lift=0.1),
            mjk.SpecTypeError,
            "LiftReward.rest_z must be a number, got None",
        ),
        (
            lambda: LiftReward("t", "o", rest_z=0.0, lift=0),
            mjk.SpecError,
            "LiftReward.lift must be positive, got 0",
        ),
        (
            lambda: LiftReward("t", "o", 0.0, 0.1, reach_scale=0),
            mjk.SpecError,
            "LiftReward.reach_scale must be positive, got 0",
        ),
        (
            lambda: LiftReward(5, "o", 0.0, 0.1),
            mjk.SpecTypeError,
            "LiftReward.tcp must be a string, got 5",
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
