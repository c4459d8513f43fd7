"""Seeded episodes: the same seed gives the same episode in another env, process or Ray actor."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from conftest import menagerie

import mjkdl as mjk
import mjkdl.task  # registers the tasks (mjk is the same package)
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
    assert not zero.success
    from mjkdl.task.experts import expert_for

    expert = expert_for(env)
    expert.reset()
    assert run_episode(env, 0, policy=expert).success
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


@pytest.fixture(scope="module")
def reach():
    menagerie("franka_emika_panda")
    env = gym.make("mjkdl/PandaReach-v0")
    yield env
    env.close()


@pytest.mark.parametrize(
    ("args", "kwargs", "error", "message"),
    [
        ((None, 0), {}, mjk.SpecTypeError, "env must be a gymnasium.Env, got None"),
        (("env", None), {}, mjk.SpecTypeError, "seed must be a non-negative integer, got None"),
        (("env", 1.7), {}, mjk.SpecTypeError, "seed must be a non-negative integer, got 1.7"),
        (("env", True), {}, mjk.SpecTypeError, "seed must be a non-negative integer, got True"),
        (("env", -1), {}, mjk.SpecError, "seed must be a non-negative integer, got -1"),
        (
            ("env", 0),
            {"policy": "x"},
            mjk.SpecTypeError,
            "policy must be callable (obs -> action) or None, got 'x'",
        ),
        (
            ("env", 0),
            {"max_steps": True},
            mjk.SpecTypeError,
            "max_steps must be a positive integer or None, got True",
        ),
        (
            ("env", 0),
            {"max_steps": 2.0},
            mjk.SpecTypeError,
            "max_steps must be a positive integer or None, got 2.0",
        ),
    ],
)
def test_run_episode_bad_arguments(reach, args, kwargs, error, message) -> None:
    args = tuple(reach if a == "env" else a for a in args)
    with pytest.raises(error) as err:
        run_episode(*args, **kwargs)
    assert str(err.value) == message


def test_counts_and_seeds_may_be_numpy_integers(reach) -> None:
    episode = run_episode(reach, np.int64(3), max_steps=np.int64(2))
    assert episode == run_episode(reach, 3, max_steps=2)
    assert type(episode.seed) is int and episode.steps == 2


ID = "mjkdl/PandaReach-v0"


@pytest.mark.parametrize(
    ("args", "kwargs", "error", "message"),
    [
        ((ID, [None]), {}, mjk.SpecTypeError, "seeds[0] must be a non-negative integer, got None"),
        ((ID, [0, 1.7]), {}, mjk.SpecTypeError, "seeds[1] must be a non-negative integer, got 1.7"),
        (
            (ID, [False]),
            {},
            mjk.SpecTypeError,
            "seeds[0] must be a non-negative integer, got False",
        ),
        (
            (ID, "123"),
            {},
            mjk.SpecTypeError,
            "seeds must be a list of non-negative integers, got '123'",
        ),
        (
            (ID, None),
            {},
            mjk.SpecTypeError,
            "seeds must be a list of non-negative integers, got None",
        ),
        (
            (ID, [0]),
            {"actors": True},
            mjk.SpecTypeError,
            "actors must be a positive integer, got True",
        ),
        (
            (ID, [0]),
            {"env_kwargs": 5},
            mjk.SpecTypeError,
            "env_kwargs must be a mapping of argument names or None, got 5",
        ),
        (
            (ID, [0]),
            {"policy": 3},
            mjk.SpecTypeError,
            "policy must be callable (obs -> action) or None, got 3",
        ),
        ((None, [0]), {}, mjk.SpecTypeError, "env_id must be a string, got None"),
    ],
)
def test_ray_collect_checks_its_arguments_first(args, kwargs, error, message) -> None:
    with pytest.raises(error) as err:  # before Ray starts
        ray_collect(*args, **kwargs)
    assert str(err.value) == message
