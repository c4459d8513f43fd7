"""The registered tasks with a standard RL library: Stable-Baselines3's checker and its HER
buffer (the `rl` extra; benchmarks/learning.py trains them for real)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from conftest import import_extra, menagerie

import mjkdl.task  # noqa: F401  (registers the tasks)
from mjkdl.task.registry import TASKS

sb3 = import_extra("rl", "stable_baselines3")


@pytest.fixture(autouse=True)
def _panda() -> None:
    menagerie("franka_emika_panda")


@pytest.mark.parametrize("env_id", list(TASKS))
def test_stable_baselines3_accepts_the_tasks(env_id: str) -> None:
    from stable_baselines3.common.env_checker import check_env

    env = gym.make(env_id)
    with _no_warning():
        # The env itself: SB3's checker calls compute_reward directly, which Gymnasium's
        # wrappers do not forward (SB3's algorithms reach it through get_wrapper_attr).
        check_env(env.unwrapped, warn=True)
    env.close()


class _no_warning:
    """SB3's checker warns about what it finds odd (asymmetric or unnormalised action
    spaces, ...): none of that may be reported."""

    def __enter__(self) -> None:
        import warnings

        self._catch = warnings.catch_warnings(record=True)
        self._caught = self._catch.__enter__()
        warnings.simplefilter("always")

    def __exit__(self, *exc: object) -> None:
        self._catch.__exit__(*exc)
        odd = [str(w.message) for w in self._caught if "stable_baselines3" in w.filename]
        assert odd == []


def test_her_relabels_goals_with_the_envs_own_reward() -> None:
    from stable_baselines3 import SAC, HerReplayBuffer

    env = gym.make("mjkdl/PandaReachGoal-v0")
    model = SAC(
        "MultiInputPolicy",
        env,
        replay_buffer_class=HerReplayBuffer,
        replay_buffer_kwargs={"n_sampled_goal": 4, "goal_selection_strategy": "future"},
        learning_starts=100,
        batch_size=64,
        seed=0,
    )
    model.learn(total_timesteps=220)  # two episodes and a little training
    batch = model.replay_buffer.sample(256)
    achieved = batch.next_observations["achieved_goal"].numpy()
    desired = batch.next_observations["desired_goal"].numpy()
    rewards = batch.rewards.numpy().ravel()
    expected = env.unwrapped.compute_reward(achieved, desired, {})
    np.testing.assert_allclose(rewards, expected, atol=1e-6)
    assert 0 < rewards.mean() < 1  # relabelled successes among the failures
    env.close()
