"""Reward, success and termination helpers for the common cases, built on observation names.

`TaskSpec.reward`, `success` and `terminated` take the step's observation; these helpers
return such callables (picklable, so vector envs and Ray can ship them). A position
observation is any whose first three entries are x, y, z in the world: `{arm}_tcp_pos`,
`{name}_pose`.

Each helper is one formula, written once in `evaluate(obs)` against whichever array module
holds the observation (NumPy, or torch), for any leading batch axes: the CPU env calls the
helper on one world's NumPy observation (`__call__`, a Python float or bool), the batched
backend calls `evaluate` on every world's tensors at once on its device (`ArrayRule`).

The dense rewards lie in [0, 1] per step, grow with progress towards success, and pay a
success step at least as much as any step before success, so a policy that fails never earns
more than one that succeeds (docs/task.md gives the formulas).
"""

from __future__ import annotations

import sys
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Protocol, TypeGuard, runtime_checkable

import numpy as np

from ..errors import SpecError, SpecTypeError, unknown_name
from ..validate import real, text
from ._check import positive


@runtime_checkable
class ArrayRule(Protocol):
    """A reward, success or termination whose `evaluate(obs)` takes observations with leading
    batch axes (NumPy arrays or torch tensors) and returns one value per world, in the same
    array module: the batched backend evaluates such a rule for all worlds on its device
    (any other callable runs on the host, world by world)."""

    def evaluate(self, obs: Mapping[str, Any]) -> Any: ...


def array_module(value: Any) -> Any:
    """The module whose functions apply to `value`: torch for a tensor, else NumPy."""
    torch = sys.modules.get("torch")
    if torch is not None and isinstance(value, torch.Tensor):
        return torch
    return np


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
    position(obs, a), position(obs, b)
    return float(distances(obs, a, b))


def height(obs: Mapping[str, np.ndarray], key: str) -> float:
    """World z of the position held by observation `key`."""
    return float(position(obs, key)[2])


def batchable(rule: object) -> TypeGuard[ArrayRule]:
    """`rule` is an `ArrayRule` all the way down (a reward's `success` included), so the
    batched backend can evaluate it on its device."""
    inner = getattr(rule, "success", None)
    return isinstance(rule, ArrayRule) and (inner is None or batchable(inner))


def _outcome(rule: Any, obs: Mapping[str, Any]) -> Any:
    """A nested rule's value: batched where it can be, else its plain call (one world)."""
    return rule.evaluate(obs) if isinstance(rule, ArrayRule) else rule(obs)


def _xyz(obs: Mapping[str, Any], key: str) -> Any:
    """x, y, z of position observation `key`, over any leading axes (NumPy: as float64)."""
    value = obs[key]
    if array_module(value) is np:
        value = np.asarray(value, dtype=float)
    return value[..., :3]


def _flags(obs: Mapping[str, Any], key: str) -> Any:
    """Which entries of the `ContactSensor` observation `key` are in contact."""
    value = obs[key]
    if array_module(value) is np:
        value = np.asarray(value)
    return value > 0.5


def distances(obs: Mapping[str, Any], a: str, b: str) -> Any:
    """Metres between position observations `a` and `b` per world, over any leading axes
    (NumPy arrays or torch tensors)."""
    d = _xyz(obs, a) - _xyz(obs, b)
    return array_module(d).sqrt((d * d).sum(-1))


def _grasped(obs: Mapping[str, Any], key: str) -> Any:
    """Every entry of the `ContactSensor` observation `key` is in contact."""
    return _flags(obs, key).all(-1)


def _touched(obs: Mapping[str, Any], key: str) -> Any:
    """Some entry of the `ContactSensor` observation `key` is in contact."""
    return _flags(obs, key).any(-1)


def _checked(obs: Mapping[str, Any], rule: Any) -> None:
    """One world's observation holds what `rule` (and a `success` inside it) reads: the CPU
    env's call, every step, fails naming the observation."""
    for key in rule._positions().values():
        position(obs, key)
    contacts = getattr(rule, "contacts", "")
    if contacts and contacts not in obs:
        raise unknown_name("observation", contacts, obs, where="the step's observation")
    inner = getattr(rule, "success", None)
    if inner is not None and hasattr(inner, "_positions"):
        _checked(obs, inner)


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

    def evaluate(self, obs: Mapping[str, Any]) -> Any:
        """Per world: within `tolerance`."""
        return distances(obs, self.a, self.b) <= self.tolerance

    def __call__(self, obs: Mapping[str, np.ndarray]) -> bool:
        _checked(obs, self)
        return bool(self.evaluate(obs))


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

    def evaluate(self, obs: Mapping[str, Any]) -> Any:
        """Per world: the reward."""
        return reach_reward(distances(obs, self.a, self.b), self.success_distance, self.scale)

    def __call__(self, obs: Mapping[str, np.ndarray]) -> float:
        _checked(obs, self)
        return float(self.evaluate(obs))


def reach_reward(d: Any, success_distance: float, scale: float) -> Any:
    """`ReachReward`'s formula for a distance or an array of them (NumPy or torch)."""
    xp = array_module(d)
    if xp is np:
        d = np.asarray(d)
    return 0.5 * (1.0 - xp.tanh(d / scale)) + 0.5 * (d <= success_distance)


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

    def evaluate(self, obs: Mapping[str, Any]) -> Any:
        """Per world: lifted."""
        return _xyz(obs, self.key)[..., 2] >= self.rest_z + self.lift

    def __call__(self, obs: Mapping[str, np.ndarray]) -> bool:
        _checked(obs, self)
        return bool(self.evaluate(obs))


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

    def evaluate(self, obs: Mapping[str, Any]) -> Any:
        """Per world: lifted and grasped."""
        lifted = _xyz(obs, self.obj)[..., 2] >= self.rest_z + self.lift
        return lifted & _grasped(obs, self.contacts)

    def __call__(self, obs: Mapping[str, np.ndarray]) -> bool:
        _checked(obs, self)
        return bool(self.evaluate(obs))


@dataclass(frozen=True)
class LiftReward:
    """Staged dense pick reward in [0, 1]: reach, grasp, lift, then hold.

    Before success, `0.25 * (1 - tanh(d / reach_scale))` for the TCP nearing the object, plus
    0.25 while it is grasped (touching every body of `contacts`), plus, while grasped, up to
    0.25 for the height gained towards `lift`: at most 0.75. A success step (`Held` with the
    same fields) pays 1.

    `reach_scale` 0.3 m gives a learner a gradient from where PickCube's episodes start, the
    hand about 0.5 m from the cube: the first step pays 0.016 there (median over 20 seeds),
    where 0.1 m paid 1.8e-5 (tanh saturates beyond three scales).

    With `near_scale` (PickCube's `reward_type="shaped"`) the reach stage is the mean of two
    such terms, `1 - tanh(d / reach_scale)` pulling from afar and `1 - tanh(d / near_scale)`
    paying the last centimetres, where a grasp needs the fingers around the cube.
    """

    tcp: str
    obj: str
    contacts: str
    rest_z: float
    lift: float
    reach_scale: float = 0.3
    near_scale: float = 0.0
    """0: one reach term; else the scale in metres of the second, near one."""

    def __post_init__(self) -> None:
        text(self.tcp, "LiftReward.tcp")
        text(self.obj, "LiftReward.obj")
        text(self.contacts, "LiftReward.contacts")
        real(self.rest_z, "LiftReward.rest_z")
        positive(self.lift, "LiftReward.lift")
        positive(self.reach_scale, "LiftReward.reach_scale")
        if real(self.near_scale, "LiftReward.near_scale") < 0:
            raise SpecError(f"LiftReward.near_scale must be >= 0 (0: off), got {self.near_scale!r}")

    def _positions(self) -> dict[str, str]:
        return {"LiftReward.tcp": self.tcp, "LiftReward.obj": self.obj}

    def evaluate(self, obs: Mapping[str, Any]) -> Any:
        """Per world: the reward."""
        gained = (_xyz(obs, self.obj)[..., 2] - self.rest_z) / self.lift
        grasped = _grasped(obs, self.contacts)
        xp = array_module(gained)
        d = distances(obs, self.tcp, self.obj)
        reach = 0.25 * (1.0 - xp.tanh(d / self.reach_scale))
        if self.near_scale:
            reach = 0.5 * reach + 0.125 * (1.0 - xp.tanh(d / self.near_scale))
        staged = xp.where(grasped, reach + (0.25 + 0.25 * gained.clip(min=0.0)), reach)
        return xp.where(grasped & (gained >= 1.0), 1.0, staged)

    def __call__(self, obs: Mapping[str, np.ndarray]) -> float:
        _checked(obs, self)
        return float(self.evaluate(obs))


def success_bonus(reward: float, steps: int, horizon: float) -> float:
    """The reward of the step on which `TaskSpec.terminate_on_success` ends an episode after
    `steps` control steps of at most `horizon`: `reward * (1 + horizon - steps)`, since each
    step the end cuts off would have paid about as much (a policy is not paid less for
    finishing early); `reward` without a finite horizon. The one definition of the bonus:
    `TaskEnv.step` and `TaskEnv.observe` (a restored state) both pay it."""
    if not np.isfinite(horizon):
        return reward
    return reward * (1 + max(0, horizon - steps))


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

    def evaluate(self, obs: Mapping[str, Any]) -> Any:
        """Per world: 1.0 or 0.0."""
        done = _outcome(self.success, obs)
        return array_module(done).where(done, 1.0, 0.0)

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

    def evaluate(self, obs: Mapping[str, Any]) -> Any:
        """Per world: placed (and let go of)."""
        there = distances(obs, self.obj, self.goal) <= self.tolerance
        if not self.contacts:
            return there
        return there & ~_touched(obs, self.contacts)

    def __call__(self, obs: Mapping[str, np.ndarray]) -> bool:
        _checked(obs, self)
        return bool(self.evaluate(obs))


@dataclass(frozen=True)
class PlaceReward:
    """Staged dense reward in [0, 1] for bringing an object to a goal (push, pick and place,
    stack): `place_reward` of the TCP-object and object-goal distances and, with `contacts`,
    whether the fingers hold the object. A success step (`success`) pays 1. With
    `near_scale` (`reward_type="shaped"`) the reach stage is two terms, as `LiftReward`'s.

    Four choices fit the reward to its task. `behind` > 0 moves the reach point that many
    metres behind the object, on the far side from the goal in the horizontal plane: a hand
    there pushes the object towards the goal. `gate` > 0 pays the goal term only while the
    TCP is that near its reach point, so a hand that knocks the object about on its way is
    not taught to keep away from it (ManiSkill's PushCube does both). `hold` pays the goal
    term only while the object is grasped, so pushing it under a goal in the air pays nothing
    (ManiSkill's PickCube gates its place term the same way). `over` charges a hand on the
    object's near side the way over the object to a reach point `behind` it, not the
    straight line through the object, which holds a learner's hand against its near side."""

    tcp: str
    obj: str
    goal: str
    success: Any
    contacts: str = ""
    reach_scale: float = 0.1
    goal_scale: float = 0.25
    near_scale: float = 0.0
    """0: one reach term; else the scale in metres of the second, near one."""
    behind: float = 0.0
    """0: reach the object; else the point this many metres behind it, away from the goal."""
    hold: bool = False
    """Pay the goal term only while `contacts` all touch the object."""
    gate: float = 0.0
    """0: off; else pay the goal term only while the TCP is this near its reach point."""
    over: float = 0.0
    """0: the straight distance to the reach point; else, for a hand more than `gate` past
    the reach point towards the goal, the way over the object, this many metres above the
    reach point (needs `behind`)."""

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
        if real(self.near_scale, "PlaceReward.near_scale") < 0:
            raise SpecError(
                f"PlaceReward.near_scale must be >= 0 (0: off), got {self.near_scale!r}"
            )
        if real(self.behind, "PlaceReward.behind") < 0:
            raise SpecError(f"PlaceReward.behind must be >= 0 (0: off), got {self.behind!r}")
        if real(self.gate, "PlaceReward.gate") < 0:
            raise SpecError(f"PlaceReward.gate must be >= 0 (0: off), got {self.gate!r}")
        if real(self.over, "PlaceReward.over") < 0:
            raise SpecError(f"PlaceReward.over must be >= 0 (0: off), got {self.over!r}")
        if self.over and not self.behind:
            raise SpecError(
                "PlaceReward.over needs PlaceReward.behind: the path goes over the object to "
                "the reach point behind it"
            )
        if not isinstance(self.hold, bool):
            raise SpecTypeError(f"PlaceReward.hold must be True or False, got {self.hold!r}")
        if self.hold and not self.contacts:
            raise SpecError(
                "PlaceReward.hold needs PlaceReward.contacts: the ContactSensor observation "
                "that says the object is grasped"
            )

    def _positions(self) -> dict[str, str]:
        return {
            "PlaceReward.tcp": self.tcp,
            "PlaceReward.obj": self.obj,
            "PlaceReward.goal": self.goal,
        }

    def evaluate(self, obs: Mapping[str, Any]) -> Any:
        """Per world: the reward."""
        grasped = _grasped(obs, self.contacts) if self.contacts else False
        if self.behind:
            d_reach = _behind_distance(
                obs, self.tcp, self.obj, self.goal, self.behind, self.over, self.gate
            )
        else:
            d_reach = distances(obs, self.tcp, self.obj)
        staged = place_reward(
            d_reach,
            distances(obs, self.obj, self.goal),
            grasped,
            self.reach_scale,
            self.goal_scale,
            self.near_scale,
            self.hold,
            self.gate,
        )
        return array_module(staged).where(_outcome(self.success, obs), 1.0, staged)

    def __call__(self, obs: Mapping[str, np.ndarray]) -> float:
        _checked(obs, self)
        return float(self.evaluate(obs))


def place_reward(
    d_reach: Any,
    d_goal: Any,
    grasped: Any,
    reach_scale: float,
    goal_scale: float,
    near_scale: float = 0.0,
    hold: bool = False,
    gate: float = 0.0,
) -> Any:
    """`PlaceReward`'s formula before success, for numbers or arrays with a leading batch
    axis (NumPy or torch): `0.25 * (1 - tanh(d_reach / reach_scale)) + 0.25 * grasped
    + 0.5 * (1 - tanh(d_goal / goal_scale))`, below 1 whenever `d_goal > 0`; with
    `near_scale` the reach term is the mean of `1 - tanh(d_reach / reach_scale)` and
    `1 - tanh(d_reach / near_scale)`; with `hold` the goal term is paid only when grasped, with
    `gate` only while `d_reach <= gate`."""
    xp = array_module(d_reach)
    if xp is np:
        d_reach, d_goal, grasped = np.asarray(d_reach), np.asarray(d_goal), np.asarray(grasped)
    reach = 1.0 - xp.tanh(d_reach / reach_scale)
    if near_scale:
        reach = 0.5 * reach + 0.5 * (1.0 - xp.tanh(d_reach / near_scale))
    goal = 1.0 - xp.tanh(d_goal / goal_scale)
    if hold:
        goal = goal * grasped
    if gate:
        goal = goal * (d_reach <= gate)
    return 0.25 * reach + 0.25 * grasped + 0.5 * goal


def _behind_distance(
    obs: Mapping[str, Any],
    tcp: str,
    obj: str,
    goal: str,
    behind: float,
    over: float = 0.0,
    margin: float = 0.0,
) -> Any:
    """Metres from `tcp` to the point `behind` metres from `obj` on its far side from `goal`,
    in the horizontal plane at the object's height (a pose that pushes it to the goal).

    With `over`, a hand more than `margin` past that point towards the goal is charged the
    path up or down to `over` above the point, across and down: the straight line from the
    object's near side runs through the object, and a reward of that distance keeps a
    learner's hand pressed against it."""
    o, g, t = _xyz(obs, obj), _xyz(obs, goal), _xyz(obs, tcp)
    xp = array_module(o)
    ux, uy = g[..., 0] - o[..., 0], g[..., 1] - o[..., 1]
    norm = xp.sqrt(ux * ux + uy * uy) + 1e-9  # the object on its goal: any side will do
    ux, uy = ux / norm, uy / norm
    ex = t[..., 0] - o[..., 0] + behind * ux
    ey = t[..., 1] - o[..., 1] + behind * uy
    ez = t[..., 2] - o[..., 2]
    straight = xp.sqrt(ex * ex + ey * ey + ez * ez)
    if not over:
        return straight
    around = abs(ez - over) + xp.sqrt(ex * ex + ey * ey) + over
    return xp.where(ex * ux + ey * uy <= margin, straight, around)
