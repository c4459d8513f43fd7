"""Seeded episodes: the same seed gives the same episode in another env, process or Ray actor."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from conftest import menagerie

import mjkdl.task  # noqa: F401  (registers the tasks)
from mjkdl.task import Episode, ray_collect, run_episode

SEEDS = [0, 1, 2, 3]
STEPS = 3


@pytest.fixture(autouse=True)
def _panda() -> None:
    menagerie("franka_emika_panda")


def sequential(seeds: list[int]) -> list[Episode]:
    env = gym.make("mjkdl/PandaReach-v0")
    try:
        return [run_episode(env, s, max_steps=STEPS) for s in seeds]
    finally:
        env.close()


def test_run_episode_depends_on_the_seed_alone() -> None:
    first = sequential(SEEDS)
    again = sequential(list(reversed(SEEDS)))[::-1]
    assert first == again
    assert all(e.steps == STEPS and not e.truncated for e in first)
    assert len({e.total_reward for e in first}) == len(SEEDS)
    env = gym.make("mjkdl/PandaReach-v0")
    zero = run_episode(env, 0, policy=lambda obs: np.zeros(7, np.float32))
    assert zero.steps == 100 and zero.truncated and not zero.terminated  # 10 s of 0.1 s
    with pytest.raises(ValueError, match="max_steps"):
        run_episode(env, 0, max_steps=0)
    env.close()


def test_ray_actors_return_the_sequential_episodes() -> None:
    import ray  # the dev extra installs it: a missing ray is a failure here, not a skip
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        remote = ray_collect("mjkdl/PandaReach-v0", SEEDS, actors=2, max_steps=STEPS)
    finally:
        ray.shutdown()
    assert remote == sequential(SEEDS)
