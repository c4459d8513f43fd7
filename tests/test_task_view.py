"""The task viewer and human rendering, under a virtual display (Xvfb).

Each window runs in a fresh interpreter: GLFW aborts the process when it is brought up again
on a new display after another test module's display went away.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import gymnasium as gym
import pytest
from conftest import ROOT, menagerie
from test_viewer import display  # noqa: F401  (the shared Xvfb fixture)

import mjkdl.task
from mjkdl.task import view


@pytest.fixture(autouse=True)
def _panda() -> None:
    menagerie("franka_emika_panda")


def run_script(code: str) -> dict:
    """Run `code` in a fresh interpreter on the current display; the JSON it prints last."""
    env = dict(os.environ, MUJOCO_GL="egl")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    done = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_human_render_opens_the_viewer(display: str) -> None:  # noqa: F811
    out = run_script("""
        import json
        import gymnasium as gym, numpy as np
        import mjkdl.task

        env = gym.make("mjkdl/PandaReach-v0", render_mode="human", hide_observations=())
        env.reset(seed=0)
        viewer = env.unwrapped._viewer
        opened = viewer is not None and viewer.is_running()
        for _ in range(2):
            obs, *_ = env.step(np.zeros(7, np.float32))
        env.close()
        print(json.dumps({"opened": opened, "time": float(obs["time"][0]),
                          "closed": not viewer.is_running()}))
    """)
    assert out == {"opened": True, "time": pytest.approx(0.2), "closed": True}


def test_view_runs_the_policy_with_plots_and_resets_on_backspace(display: str) -> None:  # noqa: F811
    out = run_script("""
        import json
        import gymnasium as gym, numpy as np
        from mjkdl.task import view
        from mjkdl.viewer import overlays as keys

        env = gym.make("mjkdl/PandaReach-v0", hide_observations=())
        task = env.unwrapped
        seen, viewers = [], []

        def policy(obs):
            seen.append(float(obs["time"][0]))
            if len(seen) == 1:
                viewers.append(task._stepper.__self__)
            if len(seen) == 3:  # Backspace, as the window's key callback queues it
                viewers[0]._on_key(keys.KEY_RESET)
            return np.array([0.1, 0, 0, 0, 0, 0, 0], np.float32)

        steps = view(env, policy, plots=["panda_tcp_pos", "goal_pose"], seed=1,
                     realtime_factor=0.0, max_steps=5)
        viewer = viewers[0]
        print(json.dumps({"steps": steps, "signals": viewer.signal_names, "seen": seen,
                          "closed": not viewer.is_running(),
                          "detached": task._stepper is None}))
        env.close()
    """)
    assert out["steps"] == 5
    assert out["signals"] == ["panda_tcp_pos", "goal_pose", "action", "reward"]
    # The episode restarted after the third step: the clock went back to zero.
    assert out["seen"] == pytest.approx([0.0, 0.1, 0.2, 0.0, 0.1])
    assert out["closed"] and out["detached"]


def test_view_bad_input() -> None:
    env = gym.make("mjkdl/PandaReach-v0")
    with pytest.raises(KeyError, match=r"'tcp_pos' in plots"):
        view(env, plots=["tcp_pos"])
    with pytest.raises(ValueError, match="policy must be callable"):
        view(env, policy=3)
    with pytest.raises(ValueError, match="TaskEnv"):
        view(gym.make("CartPole-v1"))
    env.close()
    assert isinstance(env.unwrapped, mjkdl.task.TaskEnv)


def test_gymnasiums_checker_with_its_render_modes(display: str) -> None:  # noqa: F811
    out = run_script("""
        import json, warnings
        import gymnasium as gym
        from gymnasium.utils.env_checker import check_env
        import mjkdl.task

        notes = {}
        for env_id in ("mjkdl/PandaReach-v0", "mjkdl/PandaPickCube-v0"):
            env = gym.make(env_id)
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                check_env(env.unwrapped)  # also builds the env in rgb_array and human mode
            notes[env_id] = [str(w.message) for w in caught if "infinity" not in str(w.message)]
            env.close()
        print(json.dumps(notes))
    """)
    assert out == {"mjkdl/PandaReach-v0": [], "mjkdl/PandaPickCube-v0": []}
