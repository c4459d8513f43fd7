"""Policies for the demonstration tests, importable as `demo_envs:fn` in a fresh process."""

from __future__ import annotations

from collections.abc import Callable, Mapping

import gymnasium as gym
import numpy as np

# PickCube with a 64x48 front camera observation (`front_rgb`).
CAMERA = {"camera_names": ["front"], "camera_size": [48, 64]}
Obs = Mapping[str, np.ndarray]


class Approach:
    """Closed loop: the TCP heads for a point above the cube, wobbling as the steps go by, the
    gripper closing after 5 steps; `reset()` (called at every episode start) restarts the
    count and counts the resets."""

    def __init__(self, env: gym.Env) -> None:
        space = env.action_space
        self.low, self.high = space.low, space.high
        self.resets = self.steps = 0

    def reset(self) -> None:
        self.resets += 1
        self.steps = 0

    def __call__(self, obs: Obs) -> np.ndarray:
        target = obs["cube_pose"][:3] + np.array([0.0, 0.0, 0.08])
        twist = np.zeros(7)
        twist[:3] = 3.0 * (target - obs["panda_tcp_pos"])
        twist[3:6] = 0.3 * np.sin(self.steps + np.arange(3))
        twist[6] = self.high[6] if self.steps > 5 else self.low[6]
        self.steps += 1
        return np.clip(twist, self.low, self.high).astype(np.float32)


def approach(env: gym.Env) -> Approach:
    return Approach(env)


def wrong_shape(env: gym.Env) -> Callable[[Obs], np.ndarray]:
    return lambda obs: np.zeros(3, np.float32)


def nan_after_two_steps(env: gym.Env) -> Callable[[Obs], np.ndarray]:
    steps = []

    def policy(obs: Obs) -> np.ndarray:
        a = np.zeros(env.action_space.shape, np.float32)
        if len(steps) >= 2:
            a[1] = np.nan
        steps.append(1)
        return a

    return policy


def not_callable(env: gym.Env) -> int:
    return 3
