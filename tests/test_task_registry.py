"""Registered Panda tasks: Gymnasium's checker, rendering, async vector envs."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from conftest import menagerie
from gymnasium.utils.env_checker import check_env

import mjkdl.task  # noqa: F401  (registers the tasks)
from mjkdl.task import TaskEnv
from mjkdl.task.registry import BALL_RADIUS, CUBE_HALF

TASKS = ["mjkdl/PandaReach-v0", "mjkdl/PandaPickCube-v0"]


@pytest.fixture(autouse=True)
def _panda() -> None:
    menagerie("franka_emika_panda")


@pytest.mark.parametrize("env_id", TASKS)
def test_registered_tasks_pass_gymnasiums_checker(env_id: str) -> None:
    env = gym.make(env_id)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=True)
    # Only the unbounded-state notices Gymnasium's own MuJoCo envs get too.
    others = [str(w.message) for w in caught if "infinity" not in str(w.message)]
    assert others == []
    assert env.action_space.shape == (7,)
    assert env.unwrapped.control_timestep == pytest.approx(0.1)
    assert env.unwrapped.scene.timestep() == 0.002
    env.close()


def test_reach_places_the_ball_on_the_floor_and_rewards_closeness() -> None:
    env = gym.make("mjkdl/PandaReach-v0")
    obs, _ = env.reset(seed=3)
    ball = obs["goal_pose"][:3]
    assert 0.35 <= ball[0] <= 0.65 and -0.3 <= ball[1] <= 0.3
    obs, reward, terminated, truncated, _ = env.step(np.zeros(7, np.float32))
    distance = np.linalg.norm(obs["goal_pose"][:3] - obs["panda_tcp_pos"])
    assert reward == pytest.approx(max(0.0, 1.0 - distance))
    assert obs["goal_pose"][2] == pytest.approx(BALL_RADIUS, abs=2e-3)  # resting on the floor
    assert not terminated and not truncated
    env.close()


def test_pick_cube_pays_for_a_lift() -> None:
    env = gym.make("mjkdl/PandaPickCube-v0").unwrapped
    obs, _ = env.reset(seed=0)
    assert obs["cube_pose"][2] == pytest.approx(CUBE_HALF + 0.002, abs=1e-9)
    # Teleport the cube into the closed hand's reach, lifted: the episode ends with the bonus.
    env.scene.set_body_pose("cube", [*obs["panda_tcp_pos"][:2], 0.2])
    obs, reward, terminated, *_ = env.step(np.zeros(7, np.float32))
    assert terminated and reward >= 1.0
    env.close()


def test_rgb_array_render_of_a_registered_task() -> None:
    env = gym.make(
        "mjkdl/PandaReach-v0", render_mode="rgb_array", render_width=96, render_height=64
    )
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (64, 96, 3) and frame.dtype == np.uint8 and frame.std() > 5
    env.close()


def rollout(env, seeds: list[int], actions: np.ndarray) -> np.ndarray:
    """Observed TCP positions and rewards of sequential episodes, one per seed."""
    out = []
    for k, seed in enumerate(seeds):
        obs, _ = env.reset(seed=seed)
        trace = [obs["panda_tcp_pos"]]
        for a in actions[:, k]:
            obs, reward, *_ = env.step(a)
            trace += [obs["panda_tcp_pos"], [reward]]
        out.append(np.concatenate(trace))
    return np.array(out)


def test_async_vector_env_repeats_sequential_episodes() -> None:
    rng = np.random.default_rng(0)
    n, steps = 2, 4
    actions = rng.uniform(-1, 1, (steps, n, 7)).astype(np.float32)
    actions[..., 6] = (actions[..., 6] > 0).astype(np.float32)
    vec = gym.make_vec("mjkdl/PandaReach-v0", num_envs=n, vectorization_mode="async")
    try:
        obs, _ = vec.reset(seed=100)
        traces = [[obs["panda_tcp_pos"][k]] for k in range(n)]
        for a in actions:
            obs, reward, *_ = vec.step(a)
            for k in range(n):
                traces[k] += [obs["panda_tcp_pos"][k], [reward[k]]]
    finally:
        vec.close()
    env = gym.make("mjkdl/PandaReach-v0")
    sequential = rollout(env, [100, 101], actions)
    env.close()
    np.testing.assert_array_equal(np.array([np.concatenate(t) for t in traces]), sequential)


def test_tasks_build_from_their_factories() -> None:
    from mjkdl.task.registry import panda_pick_cube, panda_reach

    for factory in (panda_reach, panda_pick_cube):
        env = factory()
        assert isinstance(env, TaskEnv) and env.render_mode is None
        env.close()
