"""Randomization at reset: callables `(env, rng)` that `TaskSpec.initializers` runs in order.

Each draws only from the generator it is given (the env's, seeded by `reset(seed=...)`), so
the same seed gives the same episode in any process. Any other callable of that signature
works too.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import mujoco
import numpy as np
import pinocchio as pin

from ..compile import euler_quat, vector
from ..errors import SpecError, unknown_name
from ..names import model_id
from ..validate import flag, real, text
from ._check import integer, names

if TYPE_CHECKING:
    from ..robot import Robot
    from .env import TaskEnv


def _box(low: object, high: object, n: int, where: str) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = vector(low, n, f"{where}.low"), vector(high, n, f"{where}.high")
    if np.any(lo > hi):
        raise SpecError(f"{where}: low must not exceed high, got low={lo}, high={hi}")
    return lo, hi


def _robot(env: TaskEnv, arm: object, cls: str) -> tuple[Robot, str]:
    """The arm called `arm` and the name of the initializer for messages, `cls('arm')`."""
    name = text(arm, f"{cls}.arm")
    where = f"{cls}({name!r})"
    if name not in env.robots:
        raise unknown_name("arm", name, env.robots, where=f"{where}.arm (TaskSpec.arms)")
    return env.robots[name], where


@dataclass
class PropPlacer:
    """Puts free or marker `bodies` at random positions in the box `low`..`high` (xyz, world), each
    without contact with anything — the scene, the arms and the props placed before it —
    as MuJoCo's collision detection sees it (margins included). Orientation: a random yaw
    about the world z when `random_yaw`, else the body's initial one. With `min_distance`,
    each also lands at least that far (horizontally) from the body `away_from`, placed
    before it: a goal drawn on top of its object would start an episode already solved. A
    body that still touches something after `max_tries` draws raises, naming it."""

    bodies: Sequence[str]
    low: Sequence[float]
    high: Sequence[float]
    random_yaw: bool = True
    max_tries: int = 100
    away_from: str = ""
    min_distance: float = 0.0

    def __call__(self, env: TaskEnv, rng: np.random.Generator) -> None:
        where = "PropPlacer"
        lo, hi = _box(self.low, self.high, 3, where)
        bodies = names(self.bodies, f"{where}.bodies")
        max_tries = integer(self.max_tries, f"{where}.max_tries")
        random_yaw = flag(self.random_yaw, f"{where}.random_yaw")
        gap = real(self.min_distance, f"{where}.min_distance")
        if gap < 0:
            raise SpecError(f"{where}.min_distance must be >= 0 (0: off), got {gap!r}")
        if gap and not text(self.away_from, f"{where}.away_from"):
            raise SpecError(
                f"{where}.min_distance needs {where}.away_from: the body to keep clear of"
            )
        scene = env.scene
        model, data = scene.model, scene.data
        ids = [
            self._free_body(model, name, f"{where}.bodies[{i}]") for i, name in enumerate(bodies)
        ]
        away = (
            model_id(model, mujoco.mjtObj.mjOBJ_BODY, "body", self.away_from, f"{where}.away_from")
            if gap
            else -1
        )
        # Geoms of each prop's subtree; contacts with props not yet placed do not count.
        owner = {g: b for b in ids for g in _subtree_geoms(model, b)}
        pending = set(ids)
        for name, body in zip(bodies, ids, strict=True):
            pending.discard(body)
            for _ in range(max_tries):
                pos = rng.uniform(lo, hi)
                if away >= 0 and math.dist(pos[:2], data.xpos[away, :2]) < gap:
                    continue
                quat = None
                if random_yaw:
                    yaw = rng.uniform(-math.pi, math.pi)
                    quat = [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]
                scene.set_body_pose(name, pos.tolist(), quat)
                mujoco.mj_kinematics(model, data)
                mujoco.mj_collision(model, data)
                if not _touches(data, body, owner, pending):
                    break
            else:
                apart = f" and {gap} m from {self.away_from!r}" if gap else ""
                raise SpecError(
                    f"{where}: cannot place body {name!r} without contact{apart} in "
                    f"{max_tries} tries inside low={lo.tolist()}, high={hi.tolist()}; enlarge "
                    "the box or move it clear of the scene"
                )
        mujoco.mj_forward(model, data)

    @staticmethod
    def _free_body(model: mujoco.MjModel, name: str, where: str) -> int:
        b = model_id(model, mujoco.mjtObj.mjOBJ_BODY, "body", name, where)
        if model.body_mocapid[b] >= 0:
            return b
        j = model.body_jntadr[b]
        if model.body_jntnum[b] < 1 or int(model.jnt_type[j]) != int(mujoco.mjtJoint.mjJNT_FREE):
            raise SpecError(
                f"{where}: body {name!r} is neither a free body (fixed=False objects are) nor a "
                "marker"
            )
        return b


@dataclass
class PlaceAbove:
    """Puts the free or marker body `body` `height` metres straight above body `base`, with
    its initial orientation: a target on top of a cube placed before it (Stack's)."""

    body: str
    base: str
    height: float

    def __call__(self, env: TaskEnv, rng: np.random.Generator) -> None:
        where = "PlaceAbove"
        height = real(self.height, f"{where}.height")
        scene = env.scene
        model, data = scene.model, scene.data
        PropPlacer._free_body(model, text(self.body, f"{where}.body"), f"{where}.body")
        base = model_id(model, mujoco.mjtObj.mjOBJ_BODY, "body", self.base, f"{where}.base")
        mujoco.mj_kinematics(model, data)
        pos = data.xpos[base] + np.array([0.0, 0.0, height])
        scene.set_body_pose(self.body, pos.tolist())
        mujoco.mj_forward(model, data)


def _subtree_geoms(model: mujoco.MjModel, root: int) -> list[int]:
    bodies = [b for b in range(model.nbody) if model.body_rootid[b] == root]
    return [g for g in range(model.ngeom) if model.geom_bodyid[g] in bodies]


def _touches(data: mujoco.MjData, body: int, owner: dict[int, int], pending: set[int]) -> bool:
    """Whether a contact involves `body`'s geoms and something other than a pending prop."""
    for k in range(data.ncon):
        c = data.contact[k]
        a, b = owner.get(int(c.geom1)), owner.get(int(c.geom2))
        if a == body and b not in pending:
            return True
        if b == body and a not in pending:
            return True
    return False


@dataclass
class PoseInitializer:
    """Puts arm `arm`'s TCP at a random pose in the 6-D box `low`..`high` (xyz in metres,
    intrinsic xyz Euler angles in degrees, world frame), solved by `Robot.ik` from the
    current joint positions (with its own restarts); a pose IK cannot reach is redrawn, up
    to `max_tries` times, then an error names the arm."""

    arm: str
    low: Sequence[float]
    high: Sequence[float]
    max_tries: int = 20

    def __call__(self, env: TaskEnv, rng: np.random.Generator) -> None:
        robot, where = _robot(env, self.arm, "PoseInitializer")
        lo, hi = _box(self.low, self.high, 6, where)
        max_tries = integer(self.max_tries, f"{where}.max_tries")
        q0 = robot.jnt_pos_msr.copy()
        mujoco.mj_forward(env.scene.model, env.scene.data)
        best = math.inf
        for _ in range(max_tries):
            x = rng.uniform(lo, hi)
            target = pin.SE3(pin.Quaternion(*euler_quat(x[3:], where)).matrix(), x[:3])
            result = robot.ik(target, q0)
            if result.success:
                robot.set_joint_pos(result.q)
                return
            best = min(best, result.position_error)
        raise SpecError(
            f"{where}: no pose in low={lo.tolist()}, high={hi.tolist()} was reachable in "
            f"{max_tries} draws (best position error {best:.3g} m); shrink the box"
        )


@dataclass
class JointInitializer:
    """Puts arm `arm`'s joints at uniform random positions in `low`..`high` (chain order)."""

    arm: str
    low: Sequence[float]
    high: Sequence[float]

    def __call__(self, env: TaskEnv, rng: np.random.Generator) -> None:
        robot, where = _robot(env, self.arm, "JointInitializer")
        lo, hi = _box(self.low, self.high, robot.n_joints, where)
        limits = robot.joint_limits
        outside = (lo < limits[:, 0]) | (hi > limits[:, 1])
        if outside.any():
            names = ", ".join(np.array(robot.joint_names)[outside])
            raise SpecError(f"{where}: the box leaves the joint limits of {names}")
        robot.set_joint_pos(rng.uniform(lo, hi))


@dataclass
class PhysicsRandomizer:
    """Scales the masses (and inertias) and the sliding friction of `bodies`' geoms by
    uniform factors, and gives them random colours when `colors`, editing the compiled
    model in place — no rebuild. Factors apply to the values the model had when this
    initializer first ran, so they do not compound over episodes; derived constants are
    recomputed (`mj_setConst`) and every arm's Pinocchio model reloads its inertias, so an
    arm's own links may be randomized too."""

    bodies: Sequence[str]
    mass_scale: tuple[float, float] = (1.0, 1.0)
    friction_scale: tuple[float, float] = (1.0, 1.0)
    colors: bool = False
    _nominal: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __call__(self, env: TaskEnv, rng: np.random.Generator) -> None:
        where = "PhysicsRandomizer"
        model, data = env.scene.model, env.scene.data
        mass = vector(self.mass_scale, 2, f"{where}.mass_scale", positive=True)
        friction = vector(self.friction_scale, 2, f"{where}.friction_scale", positive=True)
        colors = flag(self.colors, f"{where}.colors")
        if self._nominal.get("model") is not model:
            ids = []
            body = mujoco.mjtObj.mjOBJ_BODY
            for i, name in enumerate(names(self.bodies, f"{where}.bodies")):
                ids.append(model_id(model, body, "body", name, f"{where}.bodies[{i}]"))
            geoms = np.flatnonzero(np.isin(model.geom_bodyid, ids))
            self._nominal.update(
                model=model,
                bodies=np.array(ids),
                geoms=geoms,
                mass=model.body_mass[ids].copy(),
                inertia=model.body_inertia[ids].copy(),
                friction=model.geom_friction[geoms, 0].copy(),
            )
        nom = self._nominal
        bodies, geoms = nom["bodies"], nom["geoms"]
        k = rng.uniform(min(mass), max(mass), len(bodies))
        model.body_mass[bodies] = nom["mass"] * k
        model.body_inertia[bodies] = nom["inertia"] * k[:, None]
        model.geom_friction[geoms, 0] = nom["friction"] * rng.uniform(
            min(friction), max(friction), len(geoms)
        )
        if colors:
            model.geom_rgba[geoms, :3] = rng.uniform(0.0, 1.0, (len(geoms), 3))
        qpos, qvel = data.qpos.copy(), data.qvel.copy()
        mujoco.mj_setConst(model, data)
        data.qpos[:], data.qvel[:] = qpos, qvel
        for robot in env.robots.values():  # their Pinocchio models follow the new masses
            robot.reload_inertias()
