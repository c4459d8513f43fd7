"""A registered task with a camera observation, for the demonstration tests (importable as
`demo_envs:` in a Gymnasium id, so a fresh process finds it too)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from mjkdl.task import CameraSensor, TaskEnv
from mjkdl.task.registry import panda_pick_cube_spec

CAMERA_ENV = "mjkdl_test/PickCubeCamera-v0"


def pick_cube_camera(render_mode: str | None = None, **kwargs: Any) -> TaskEnv:
    """PickCube with a 64x48 `front_rgb` observation."""
    spec = panda_pick_cube_spec()
    spec.sensors.append(CameraSensor("front", width=64, height=48))
    kwargs.setdefault("render_camera", "front")
    return TaskEnv(spec, render_mode, **kwargs)


if CAMERA_ENV not in gym.registry:
    gym.register(id=CAMERA_ENV, entry_point=f"{__name__}:pick_cube_camera")
