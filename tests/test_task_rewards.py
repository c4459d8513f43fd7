"""Reward and termination helpers against hand-computed numbers."""

from __future__ import annotations

import math

import numpy as np
import pytest

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
