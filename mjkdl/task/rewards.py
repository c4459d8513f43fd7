"""Reward and termination helpers for the common cases, built on observation names.

`TaskSpec.reward` and `TaskSpec.terminated` take the step's observation; these helpers return
such callables (picklable, so vector envs and Ray can ship them). A position observation is any
whose first three entries are x, y, z in the world: `{arm}_tcp_pos`, `{name}_pose`.
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


def _position(obs: Mapping[str, np.ndarray], key: str) -> np.ndarray:
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
    d = _position(obs, a) - _position(obs, b)
    return math.sqrt(d.dot(d))


def height(obs: Mapping[str, np.ndarray], key: str) -> float:
    """World z of the position held by observation `key`."""
    return float(_position(obs, key)[2])


@dataclass(frozen=True)
class ReachReward:
    """Dense reward `clip(1 - distance(a, b) / scale, 0, 1)`: 1 on the target, 0 from
    `scale` metres away (dm_robotics_panda's `1 - distance` with `scale=1`)."""

    a: str
    b: str
    scale: float = 1.0

    def __post_init__(self) -> None:
        text(self.a, "ReachReward.a")
        text(self.b, "ReachReward.b")
        positive(self.scale, "ReachReward.scale")

    def _positions(self) -> dict[str, str]:
        return {"ReachReward.a": self.a, "ReachReward.b": self.b}

    def __call__(self, obs: Mapping[str, np.ndarray]) -> float:
        return min(1.0, max(0.0, 1.0 - distance(obs, self.a, self.b) / self.scale))


@dataclass(frozen=True)
class Reached:
    """Termination: observations `a` and `b` are within `tolerance` metres."""

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
class Lifted:
    """Termination (and sparse reward): the object of observation `key` is at least `lift`
    metres above `rest_z`, the height it rests at."""

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


@dataclass(frozen=True)
class LiftReward:
    """Sparse + shaped lifting reward, in [0, 1.5].

    Sparse: 1 once `Lifted(obj, rest_z, lift)`. Shaped, up to 0.5: a quarter for the TCP
    approaching the object (`near = 1 - tanh(distance / reach_scale)`) and a quarter for the
    height gained toward `lift`, scaled by `near` so pushing the object up from afar does not
    pay.
    """

    tcp: str
    obj: str
    rest_z: float
    lift: float
    reach_scale: float = 0.1

    def __post_init__(self) -> None:
        text(self.tcp, "LiftReward.tcp")
        text(self.obj, "LiftReward.obj")
        real(self.rest_z, "LiftReward.rest_z")
        positive(self.lift, "LiftReward.lift")
        positive(self.reach_scale, "LiftReward.reach_scale")

    def _positions(self) -> dict[str, str]:
        return {"LiftReward.tcp": self.tcp, "LiftReward.obj": self.obj}

    def __call__(self, obs: Mapping[str, np.ndarray]) -> float:
        z = height(obs, self.obj)
        near = 1.0 - math.tanh(distance(obs, self.tcp, self.obj) / self.reach_scale)
        gained = min(1.0, max(0.0, (z - self.rest_z) / self.lift))
        sparse = 1.0 if z >= self.rest_z + self.lift else 0.0
        return sparse + 0.25 * near * (1.0 + gained)
