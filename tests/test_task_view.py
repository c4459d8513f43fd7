"""The task viewer and human rendering, under a virtual display (Xvfb)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from conftest import menagerie
from test_viewer import display  # noqa: F401  (the shared Xvfb fixture)

import mjkdl.task
from mjkdl.task import view
from mjkdl.viewer import overlays as keys


@pytest.fixture(autouse=True)
def _panda() -> None:
    menagerie("franka_emika_panda")


def test_human_render_opens_the_viewer(display: str) -> None:  # noqa: F811
    env = gym.make("mjkdl/PandaReach-v0", render_mode="human")
    env.reset(seed=0)
    viewer = env.unwrapped._viewer
    assert viewer is not None and viewer.is_running()
    for _ in range(2):
        obs, *_ = env.step(np.zeros(7, np.float32))
    assert obs["time"][0] == pytest.approx(0.2)
    env.close()
    assert not viewer.is_running()


def test_view_runs_the_policy_with_plots_and_resets_on_backspace(display: str) -> None:  # noqa: F811
    env = gym.make("mjkdl/PandaReach-v0")
    task = env.unwrapped
    seen: list[float] = []
    viewers = []

    def policy(obs):
        seen.append(float(obs["time"][0]))
        if len(seen) == 1:
            viewers.append(task._stepper.__self__)
        if len(seen) == 3:  # Backspace, as the window's key callback queues it
            viewers[0]._on_key(keys.KEY_RESET)
        return np.array([0.1, 0, 0, 0, 0, 0, 0], np.float32)

    steps = view(
        env, policy, plots=["panda_tcp_pos", "goal_pose"], seed=1, realtime_factor=0.0, max_steps=5
    )
    assert steps == 5
    viewer = viewers[0]
    assert viewer.signal_names == ["panda_tcp_pos", "goal_pose", "action", "reward"]
    # Episode restarted after the third step: the clock went back to zero.
    assert seen == pytest.approx([0.0, 0.1, 0.2, 0.0, 0.1])
    assert not viewer.is_running() and task._stepper is None
    env.close()


def test_view_bad_input() -> None:
    env = gym.make("mjkdl/PandaReach-v0")
    with pytest.raises(KeyError, match=r"'tcp_pos' in plots"):
        view(env, plots=["tcp_pos"])
    with pytest.raises(ValueError, match="policy must be callable"):
        view(env, policy=3)
    with pytest.raises(ValueError, match="TaskEnv"):
        view(gym.make("CartPole-v1"))
    env.close()
    assert mjkdl.task.TaskEnv is type(env.unwrapped)
