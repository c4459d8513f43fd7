"""`view(env, policy)`: an episode loop in the interactive viewer, with live plots.

Like dm_robotics_panda's application with plots: the policy acts every control period, the
viewer shows every physics step in real time, and plots follow chosen observations, the action
and the reward. Backspace starts a new episode; F1 shows MuJoCo's key help, the viewer's own
keys (F8-F12) are listed in `SimulateViewer`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from ..errors import SpecError, unknown_name
from .env import TaskEnv
from .rollout import Policy


def _task_viewer(env: TaskEnv, title: str) -> Any:
    """A SimulateViewer whose Backspace asks the episode loop for `env.reset()` (initializers
    included) instead of resetting the scene under it."""
    from ..viewer import SimulateViewer  # needs a display: imported only when viewing

    class TaskViewer(SimulateViewer):
        reset_requested = False

        def _reset(self) -> None:
            self.reset_requested = True

    return TaskViewer.open(env.scene, title)


def view(
    env: gym.Env,
    policy: Policy | None = None,
    plots: Sequence[str] = (),
    *,
    seed: int | None = None,
    title: str = "mjkdl task",
    camera: str = "",
    realtime_factor: float = 1.0,
    max_steps: int | None = None,
) -> int:
    """Run `policy(obs) -> action` on `env` (a `TaskEnv`, wrapped or not) in the viewer until
    its window is closed (or `max_steps` control steps); return the steps taken.

    `plots` names 1-D observations to plot live (e.g. "panda_tcp_pos"); the action and the
    reward are always plotted. `policy=None` sends the middle of the action space. Episodes
    restart when they end or on Backspace; the first uses `seed`. Needs a display (see
    `SimulateViewer`).
    """
    task = env.unwrapped
    if not isinstance(task, TaskEnv):
        raise SpecError(f"view() takes a TaskEnv (or a wrapper of one), got {type(task).__name__}")
    if policy is not None and not callable(policy):
        raise SpecError(f"view(): policy must be callable obs -> action, got {policy!r}")
    if isinstance(plots, str):
        plots = [plots]
    for name in plots:
        if name not in task.observation_space.spaces:
            raise unknown_name("observation", str(name), task.observation_space.spaces, "plots")
    box = task.action_space
    idle = ((box.low + box.high) / 2).astype(box.dtype)
    act: Policy = policy if policy is not None else (lambda obs: idle)

    state: dict[str, Any] = {"reward": np.zeros(1), "action": idle.astype(float)}
    obs, _ = env.reset(seed=seed)
    state["obs"] = obs
    viewer = _task_viewer(task, title)
    steps = 0
    try:
        viewer.realtime_factor = realtime_factor
        if camera:
            viewer.use_camera(camera)
        for name in plots:
            viewer.add_signal(name, lambda name=name: state["obs"][name])
        viewer.add_signal("action", lambda: state["action"], task.action_labels)
        viewer.add_signal("reward", lambda: state["reward"])
        task._stepper = viewer.step
        while viewer.is_running() and (max_steps is None or steps < max_steps):
            action = act(state["obs"])
            state["action"] = np.asarray(action, dtype=float)
            obs, reward, terminated, truncated, _ = env.step(action)
            steps += 1
            state["obs"], state["reward"] = obs, np.array([reward])
            if terminated or truncated or viewer.reset_requested:
                viewer.reset_requested = False
                state["obs"], _ = env.reset()
                task._stepper = viewer.step if viewer.is_running() else None
    finally:
        task._stepper = None
        viewer.close()
    return steps
