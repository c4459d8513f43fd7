"""Reward, success and termination helpers for the common cases, built on observation names.

`TaskSpec.reward`, `success` and `terminated` take the step's observation; these helpers
return such callables (picklable, so vector envs and Ray can ship them). A position
observation is any whose first three entries are x, y, z in the world: `{arm}_tcp_pos`,
`{name}_pose`.

The dense rewards lie in [0, 1] per step, grow with progress towards success, and pay a
success step at least as much as any step before success, so a policy that fails never earns
more than one that succeeds (docs/task.md gives the formulas).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import SpecError, SpecTypeError, unknown_name
from ..validate import real, text
from ._check import positive


def position(obs: Mapping[str, np.ndarray], key: str) -> np.ndarray:
    """The x, y, z held by position observation `key` (its first three entries)."""
    if type(obs) is not dict and not isinstance(obs, Mapping):
        raise SpecTypeError(f"the observation must be a mapping of names to arrays, got {obs!r}")
    if not isinstance(key, str):
        raise SpecTypeError(f"an observation name must be a string, got {key!r}")
    if key not in obs:
        raise unknown_name("observation", key, obs, where="the step's observation")
    value = np.asarray(obs[key], dtype=float)
    if value.ndim != 1 or len(value) < 3:
        raise SpecError(f"observation {key!r} has no x, y, z (shape {value.shape})")
    return value[:3]


def check_positions(fn: object, boxes: Mapping[str, Any], where: str) -> None:
    """When `fn` is one of these helpers: each observation it reads is in `boxes` and holds
    a position, so a misspelt name fails when the env is built, not at the first step."""
    positions = getattr(fn, "_positions", None)
    if positions is None:
        return
    for field, key in positions().items():
        if key not in boxes:
            raise unknown_name("observation", key, boxes, where=f"{where} ({field})")
        shape = boxes[key].shape
        if len(shape) != 1 or shape[0] < 3:
            raise SpecError(
                f"{where} ({field}): observation {key!r} has no x, y, z (shape {shape})"
            )


def distance(obs: Mapping[str, np.ndarray], a: str, b: str) -> float:
    """Metres between the positions held by observations `a` and `b`."""
    d = position(obs, a) - position(obs, b)
    return math.sqrt(d.dot(d))


def height(obs: Mapping[str, np.ndarray], key: str) -> float:
    """World z of the position held by observation `key`."""
    return float(position(obs, key)[2])


def _closeness(d: float, scale: float) -> float:
    """1 at distance 0, falling smoothly towards 0 over a few `scale`s."""
    return 1.0 - math.tanh(d / scale)


@dataclass(frozen=True)
class Reached:
    """Success (or termination): observations `a` and `b` are within `tolerance` metres."""

    a: str
    b: str
    tolerance: float

    def __post_init__(self) -> None:
        text(self.a, "Reached.a")
        text(self.b, "Reached.b")
        positive(self.tolerance, "Reached.tolerance")

    def _positions(self) -> dict[str, str]:
        return {"Reached.a": self.a, "Reached.b": self.b}

    def __call__(self, obs: Mapping[str, np.ndarray]) -> bool:
        return distance(obs, self.a, self.b) <= self.tolerance


@dataclass(frozen=True)
class ReachReward:
    """Dense reaching reward in [0, 1]: `0.5 * (1 - tanh(d / scale))`, plus 0.5 while `d`
    is within `success_distance` (the success `Reached(a, b, success_distance)` counts).
    `scale` sets where the pull is felt: with 0.25 m a step 30 cm away still pays for
    closing in, and the last centimetres pay most."""

    a: str
    b: str
    success_distance: float = 0.05
    scale: float = 0.25

    def __post_init__(self) -> None:
        text(self.a, "ReachReward.a")
        text(self.b, "ReachReward.b")
        positive(self.success_distance, "ReachReward.success_distance")
        positive(self.scale, "ReachReward.scale")

    def _positions(self) -> dict[str, str]:
        return {"ReachReward.a": self.a, "ReachReward.b": self.b}

    def __call__(self, obs: Mapping[str, np.ndarray]) -> float:
        d = distance(obs, self.a, self.b)
        return reach_reward(d, self.success_distance, self.scale)


def reach_reward(d: Any, success_distance: float, scale: float) -> Any:
    """`ReachReward`'s formula for a distance or an array of them (goal-conditioned envs)."""
    return 0.5 * (1.0 - np.tanh(np.asarray(d) / scale)) + 0.5 * (np.asarray(d) <= success_distance)


@dataclass(frozen=True)
class Lifted:
    """The object of observation `key` is at least `lift` metres above `rest_z`, the height
    it rests at."""

    key: str
    rest_z: float
    lift: float

    def __post_init__(self) -> None:
        text(self.key, "Lifted.key")
        real(self.rest_z, "Lifted.rest_z")
        positive(self.lift, "Lifted.lift")

    def _positions(self) -> dict[str, str]:
        return {"Lifted.key": self.key}

    def __call__(self, obs: Mapping[str, np.ndarray]) -> bool:
        return height(obs, self.key) >= self.rest_z + self.lift


def _grasped(obs: Mapping[str, np.ndarray], key: str) -> bool:
    """Every entry of the `ContactSensor` observation `key` is in contact."""
    if key not in obs:
        raise unknown_name("observation", key, obs, where="the step's observation")
    return bool(np.all(np.asarray(obs[key]) > 0.5))


@dataclass(frozen=True)
class Held:
    """Success of a pick: `Lifted(obj, rest_z, lift)` while the object touches every body of
    the `ContactSensor` observation `contacts` (both fingers: held, not balanced or tossed)."""

    obj: str
    contacts: str
    rest_z: float
    lift: float

    def __post_init__(self) -> None:
        text(self.obj, "Held.obj")
        text(self.contacts, "Held.contacts")
        real(self.rest_z, "Held.rest_z")
        positive(self.lift, "Held.lift")

    def _positions(self) -> dict[str, str]:
        return {"Held.obj": self.obj}

    def __call__(self, obs: Mapping[str, np.ndarray]) -> bool:
        lifted = height(obs, self.obj) >= self.rest_z + self.lift
        return lifted and _grasped(obs, self.contacts)


@dataclass(frozen=True)
class LiftReward:
    """Staged dense pick reward in [0, 1]: reach, grasp, lift, then hold.

    Before success, `0.25 * (1 - tanh(d / reach_scale))` for the TCP nearing the object, plus
    0.25 while it is grasped (touching every body of `contacts`), plus, while grasped, up to
    0.25 for the height gained towards `lift`: at most 0.75. A success step (`Held` with the
    same fields) pays 1.
    """

    tcp: str
    obj: str
    contacts: str
    rest_z: float
    lift: float
    reach_scale: float = 0.1

    def __post_init__(self) -> None:
        text(self.tcp, "LiftReward.tcp")
        text(self.obj, "LiftReward.obj")
        text(self.contacts, "LiftReward.contacts")
        real(self.rest_z, "LiftReward.rest_z")
        positive(self.lift, "LiftReward.lift")
        positive(self.reach_scale, "LiftReward.reach_scale")

    def _positions(self) -> dict[str, str]:
        return {"LiftReward.tcp": self.tcp, "LiftReward.obj": self.obj}

    def __call__(self, obs: Mapping[str, np.ndarray]) -> float:
        gained = (height(obs, self.obj) - self.rest_z) / self.lift
        grasped = _grasped(obs, self.contacts)
        if grasped and gained >= 1.0:
            return 1.0
        reward = 0.25 * _closeness(distance(obs, self.tcp, self.obj), self.reach_scale)
        if grasped:
            reward += 0.25 + 0.25 * max(0.0, gained)
        return reward


@dataclass(frozen=True)
class SparseReward:
    """1 on the steps where `success(obs)` holds, else 0."""

    success: Any

    def __post_init__(self) -> None:
        if not callable(self.success):
            raise SpecTypeError(f"SparseReward.success must be callable, got {self.success!r}")

    def _positions(self) -> dict[str, str]:
        inner = getattr(self.success, "_positions", None)
        return inner() if inner is not None else {}

    def __call__(self, obs: Mapping[str, np.ndarray]) -> float:
        return 1.0 if self.success(obs) else 0.0


@dataclass(frozen=True)
class Placed:
    """Success of a placement: the object of `obj` within `tolerance` metres of the goal
    position `goal`, and, with `contacts` (a `ContactSensor` observation), let go of: no
    finger touches it (a stacked cube that stays where it was put)."""

    obj: str
    goal: str
    tolerance: float
    contacts: str = ""

    def __post_init__(self) -> None:
        text(self.obj, "Placed.obj")
        text(self.goal, "Placed.goal")
        positive(self.tolerance, "Placed.tolerance")
        if not isinstance(self.contacts, str):
            raise SpecTypeError(f"Placed.contacts must be a string, got {self.contacts!r}")

    def _positions(self) -> dict[str, str]:
        return {"Placed.obj": self.obj, "Placed.goal": self.goal}

    def __call__(self, obs: Mapping[str, np.ndarray]) -> bool:
        there = distance(obs, self.obj, self.goal) <= self.tolerance
        if not self.contacts or not there:
            return there
        return not bool(np.any(np.asarray(obs[self.contacts]) > 0.5))


@dataclass(frozen=True)
class PlaceReward:
    """Staged dense reward in [0, 1] for bringing an object to a goal (push, pick and place,
    stack): `place_reward` of the TCP-object and object-goal distances and, with `contacts`,
    whether the fingers hold the object. A success step (`success`) pays 1."""

    tcp: str
    obj: str
    goal: str
    success: Any
    contacts: str = ""
    reach_scale: float = 0.1
    goal_scale: float = 0.25

    def __post_init__(self) -> None:
        text(self.tcp, "PlaceReward.tcp")
        text(self.obj, "PlaceReward.obj")
        text(self.goal, "PlaceReward.goal")
        if not callable(self.success):
            raise SpecTypeError(f"PlaceReward.success must be callable, got {self.success!r}")
        if not isinstance(self.contacts, str):
            raise SpecTypeError(f"PlaceReward.contacts must be a string, got {self.contacts!r}")
        positive(self.reach_scale, "PlaceReward.reach_scale")
        positive(self.goal_scale, "PlaceReward.goal_scale")

    def _positions(self) -> dict[str, str]:
        return {
            "PlaceReward.tcp": self.tcp,
            "PlaceReward.obj": self.obj,
            "PlaceReward.goal": self.goal,
        }

    def __call__(self, obs: Mapping[str, np.ndarray]) -> float:
        if self.success(obs):
            return 1.0
        grasped = _grasped(obs, self.contacts) if self.contacts else False
        return float(
            place_reward(
                distance(obs, self.tcp, self.obj),
                distance(obs, self.obj, self.goal),
                grasped,
                self.reach_scale,
                self.goal_scale,
            )
        )


def place_reward(
    d_reach: Any, d_goal: Any, grasped: Any, reach_scale: float, goal_scale: float
) -> Any:
    """`PlaceReward`'s formula before success, for numbers or arrays with a leading batch
    axis: `0.25 * (1 - tanh(d_reach / reach_scale)) + 0.25 * grasped
    + 0.5 * (1 - tanh(d_goal / goal_scale))`, below 1 whenever `d_goal > 0`."""
    reach = 1.0 - np.tanh(np.asarray(d_reach) / reach_scale)
    goal = 1.0 - np.tanh(np.asarray(d_goal) / goal_scale)
    return 0.25 * reach + 0.25 * np.asarray(grasped, dtype=float) + 0.5 * goal
