"""Goal-conditioned tasks in Gymnasium-Robotics' form, for hindsight experience replay.

`GoalTaskEnv` observes `{"observation", "achieved_goal", "desired_goal"}` and offers a
vectorised `compute_reward(achieved_goal, desired_goal, info)` that agrees with the reward of
`step`, and `compute_terminated` / `compute_truncated` as Gymnasium-Robotics' `GoalEnv` has
them, so a replay buffer (Stable-Baselines3's `HerReplayBuffer`) can relabel goals.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces

from ..errors import SpecError
from ..validate import text
from ._check import positive
from .env import TaskEnv
from .rewards import Reached, array_module, distances, position, reach_reward
from .spec import TaskSpec

REWARD_TYPES = ("dense", "sparse")


def reward_type(value: object) -> str:
    """`value` checked as one of `REWARD_TYPES`."""
    if value not in REWARD_TYPES:
        raise SpecError(f"reward_type must be one of {list(REWARD_TYPES)}, got {value!r}")
    return str(value)


@dataclass(frozen=True)
class GoalReward:
    """The reward of a goal-conditioned task from the distance `d` between the achieved and
    the desired goal: sparse, 1 within `threshold`, else 0; dense, `ReachReward`'s
    `0.5 * (1 - tanh(d / scale)) + 0.5 * (d <= threshold)`."""

    achieved: str
    desired: str
    threshold: float
    kind: str = "sparse"
    scale: float = 0.25

    def __post_init__(self) -> None:
        text(self.achieved, "GoalReward.achieved")
        text(self.desired, "GoalReward.desired")
        positive(self.threshold, "GoalReward.threshold")
        positive(self.scale, "GoalReward.scale")
        reward_type(self.kind)

    def _positions(self) -> dict[str, str]:
        return {"GoalReward.achieved": self.achieved, "GoalReward.desired": self.desired}

    def of_distance(self, d: Any) -> Any:
        """The reward for a distance or an array of distances (NumPy or torch)."""
        if self.kind == "sparse":
            xp = array_module(d)
            return xp.where(xp.asarray(d) <= self.threshold, 1.0, 0.0)
        return reach_reward(d, self.threshold, self.scale)

    def evaluate(self, obs: Mapping[str, Any]) -> Any:
        """Per world: the reward (an `ArrayRule`, so batched worlds evaluate it on the device)."""
        return self.of_distance(distances(obs, self.achieved, self.desired))

    def __call__(self, obs: Mapping[str, np.ndarray]) -> float:
        position(obs, self.achieved), position(obs, self.desired)
        return float(self.evaluate(obs))


class GoalTaskEnv(TaskEnv):
    """A `TaskEnv` whose success is an achieved goal within `threshold` of a desired one.

    `achieved` and `desired` name position observations (their x, y, z are the goals);
    `observation` concatenates every other vector observation in order, less `goal_keys`
    (observations that depend on the desired goal, which relabelling could not change) and
    `time`; image observations (cameras) stay beside the three keys. The spec's `reward`
    and `success` are replaced by `GoalReward` and `Reached` on the goals.
    """

    def __init__(
        self,
        spec: TaskSpec,
        render_mode: str | None = None,
        *,
        achieved: str,
        desired: str,
        threshold: float,
        reward_type: str = "sparse",
        goal_keys: Sequence[str] = (),
        **kwargs: Any,
    ) -> None:
        if not isinstance(spec, TaskSpec):
            raise SpecError(f"GoalTaskEnv takes a TaskSpec, got {type(spec).__name__}")
        self.goal_reward = GoalReward(achieved, desired, threshold, reward_type)
        spec = copy.copy(spec)
        spec.reward = self.goal_reward
        spec.success = Reached(achieved, desired, threshold)
        super().__init__(spec, render_mode, **kwargs)
        inner = self._task_space.spaces
        hidden = {desired, "time", *goal_keys}
        for key in hidden - {"time"}:
            if key not in inner:
                raise SpecError(
                    f"GoalTaskEnv: no observation named {key!r}; available: {', '.join(inner)}"
                )
        shapes = {k: b.shape for k, b in inner.items() if k not in hidden and b.shape is not None}
        self._vector_keys = [k for k, shape in shapes.items() if len(shape) == 1]
        self._image_keys = [k for k, shape in shapes.items() if len(shape) > 1]
        size = sum(shapes[k][0] for k in self._vector_keys)
        goal = spaces.Box(-np.inf, np.inf, (3,), np.float64)
        self.observation_space = spaces.Dict(
            {
                "observation": spaces.Box(-np.inf, np.inf, (size,), np.float64),
                "achieved_goal": goal,
                "desired_goal": goal,
                **{k: inner[k] for k in self._image_keys},
            },
            sort_keys=False,
        )

    @property
    def observation_layout(self) -> list[tuple[str, int]]:
        """The named observations `observation` concatenates, with their lengths, in order."""
        inner = self._task_space.spaces
        return [(k, int(np.prod(inner[k].shape or ()))) for k in self._vector_keys]

    def _goal_obs(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        g = self.goal_reward
        out = {
            "observation": np.concatenate([obs[k] for k in self._vector_keys]),
            "achieved_goal": obs[g.achieved][:3].copy(),
            "desired_goal": obs[g.desired][:3].copy(),
        }
        out.update((k, obs[k]) for k in self._image_keys)
        return out

    def reset(
        self, *, seed: int | None = None, options: Mapping[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        obs, info = super().reset(seed=seed, options=options)
        return self._goal_obs(obs), info

    def step(
        self, action: np.ndarray
    ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = super().step(action)
        return self._goal_obs(obs), reward, terminated, truncated, info

    def observe(self) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = super().observe()
        return self._goal_obs(obs), reward, terminated, truncated, info

    def compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        """The step reward for goals (arrays of shape (..., 3)), vectorised over leading
        axes: what `step` would have paid had `desired_goal` been the goal."""
        d = np.linalg.norm(np.asarray(achieved_goal) - np.asarray(desired_goal), axis=-1)
        return self.goal_reward.of_distance(d)

    def compute_terminated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        """Whether `step` would have ended the episode for these goals (Gymnasium-Robotics'
        `GoalEnv` API), vectorised like `compute_reward`: with `terminate_on_success` (and
        no `success_hold`) when the goals are within `threshold`, else never (the registered
        goal variants run to their time limit, as Gymnasium-Robotics' Fetch tasks do)."""
        d = np.linalg.norm(np.asarray(achieved_goal) - np.asarray(desired_goal), axis=-1)
        spec = self.task_spec
        if spec.terminate_on_success and spec.success_hold == 0 and spec.terminated is None:
            return d <= self.goal_reward.threshold
        return np.zeros(np.shape(d), dtype=bool)

    def compute_truncated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        """Never, whatever the goals (Gymnasium-Robotics' `GoalEnv` API): episodes end by time
        (Gymnasium's `TimeLimit`, or `TaskSpec.time_limit`), which no goal changes."""
        d = np.linalg.norm(np.asarray(achieved_goal) - np.asarray(desired_goal), axis=-1)
        return np.zeros(np.shape(d), dtype=bool)
