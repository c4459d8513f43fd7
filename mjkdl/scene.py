"""Runtime owners: `Scene` compiles a `SceneSpec` and owns MuJoCo's model and data."""

from __future__ import annotations

import copy
import weakref
from collections.abc import Sequence
from typing import TYPE_CHECKING

import mujoco
import numpy as np
import pinocchio as pin

from .compile import compile_scene, vector
from .errors import SpecError, unknown_name
from .spec import SceneSpec, ToolFrameSpec

if TYPE_CHECKING:
    from typing_extensions import Self

    from .robot import Robot


def mujoco_version() -> str:
    """MuJoCo's version string."""
    return mujoco.__version__


class Scene:
    """A compiled scene: MuJoCo's `MjModel`/`MjData` plus name-based helpers."""

    def __init__(self, spec: SceneSpec, mjspec: mujoco.MjSpec, model: mujoco.MjModel) -> None:
        self._spec = spec
        self._mjspec = mjspec
        self._model: mujoco.MjModel | None = model
        self._data: mujoco.MjData | None = mujoco.MjData(model)
        self._robots: weakref.WeakSet[Robot] = weakref.WeakSet()
        mujoco.mj_forward(model, self._data)

    @classmethod
    def build(cls, spec: SceneSpec) -> Self:
        """Compile `spec` (a private copy of it is kept) and return the scene."""
        if not isinstance(spec, SceneSpec):
            raise SpecError(f"build() takes a SceneSpec, got {type(spec).__name__}")
        own = copy.deepcopy(spec)
        mjspec, model = compile_scene(own)
        return cls(own, mjspec, model)

    # ------------------------------------------------------------------ ownership

    @property
    def model(self) -> mujoco.MjModel:
        """The compiled `mujoco.MjModel`."""
        self._check_open()
        assert self._model is not None
        return self._model

    @property
    def data(self) -> mujoco.MjData:
        """The `mujoco.MjData` that the simulation advances."""
        self._check_open()
        assert self._data is not None
        return self._data

    @property
    def spec(self) -> SceneSpec:
        """The scene description this scene was built from."""
        self._check_open()
        return self._spec

    @property
    def closed(self) -> bool:
        """Whether `close()` was called."""
        return self._model is None

    def close(self) -> None:
        """Release MuJoCo's model and data; later calls on this scene raise RuntimeError."""
        self._model = None
        self._data = None
        self._mjspec = None
        self._robots = weakref.WeakSet()

    def __enter__(self) -> Self:
        self._check_open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _check_open(self) -> None:
        if self._model is None:
            raise RuntimeError(f"this {type(self).__name__} is closed")

    # ------------------------------------------------------------------ clock

    def time(self) -> float:
        """Simulation time in seconds."""
        return float(self.data.time)

    def timestep(self) -> float:
        """MuJoCo's integration timestep in seconds."""
        return float(self.model.opt.timestep)

    def step(self, n: int = 1) -> None:
        """Advance the simulation `n` timesteps."""
        self._check_open()
        if n == 1:
            mujoco.mj_step(self._model, self._data)
            return
        if not isinstance(n, (int, np.integer)) or n < 0:
            raise SpecError(f"step(n): n must be a non-negative integer, got {n!r}")
        mujoco.mj_step(self._model, self._data, int(n))

    def forward(self) -> None:
        """Recompute derived quantities (poses, forces) from the current state."""
        self._check_open()
        mujoco.mj_forward(self._model, self._data)

    # ------------------------------------------------------------------ names

    def _id(self, obj: mujoco.mjtObj, kind: str, name: str) -> int:
        model = self.model
        i = mujoco.mj_name2id(model, obj, name) if isinstance(name, str) else -1
        if i < 0:
            count = {
                mujoco.mjtObj.mjOBJ_BODY: model.nbody,
                mujoco.mjtObj.mjOBJ_SITE: model.nsite,
                mujoco.mjtObj.mjOBJ_ACTUATOR: model.nu,
                mujoco.mjtObj.mjOBJ_CAMERA: model.ncam,
                mujoco.mjtObj.mjOBJ_JOINT: model.njnt,
                mujoco.mjtObj.mjOBJ_SENSOR: model.nsensor,
                mujoco.mjtObj.mjOBJ_KEY: model.nkey,
            }[obj]
            known = [mujoco.mj_id2name(model, obj, k) or "" for k in range(count)]
            raise unknown_name(kind, str(name), known, where="the scene")
        return i

    def body_id(self, name: str) -> int:
        """MuJoCo id of body `name` (KeyError with close matches when unknown)."""
        return self._id(mujoco.mjtObj.mjOBJ_BODY, "body", name)

    def site_id(self, name: str) -> int:
        """MuJoCo id of site `name`."""
        return self._id(mujoco.mjtObj.mjOBJ_SITE, "site", name)

    def actuator_id(self, name: str) -> int:
        """MuJoCo id of actuator `name`."""
        return self._id(mujoco.mjtObj.mjOBJ_ACTUATOR, "actuator", name)

    def camera_names(self) -> list[str]:
        """Names of the compiled fixed cameras, in model order."""
        model = self.model
        return [model.camera(i).name for i in range(model.ncam)]

    def has_actuator(self, name: str) -> bool:
        """Whether an actuator called `name` exists."""
        return mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_ACTUATOR, name) >= 0

    def set_actuator_ctrl(self, name: str, value: float) -> None:
        """Set the control input of actuator `name` (clamped by MuJoCo to its ctrlrange)."""
        i = self.actuator_id(name)
        v = float(value)
        if not np.isfinite(v):
            raise SpecError(f"set_actuator_ctrl({name!r}): value must be finite, got {value!r}")
        self.data.ctrl[i] = v

    # ------------------------------------------------------------------ poses

    def body_frame(self, name: str) -> pin.SE3:
        """World pose of body `name` as of the last forward computation."""
        i = self.body_id(name)
        data = self.data
        return pin.SE3(data.xmat[i].reshape(3, 3).copy(), data.xpos[i].copy())

    def site_frame(self, name: str) -> pin.SE3:
        """World pose of site `name` as of the last forward computation."""
        i = self.site_id(name)
        data = self.data
        return pin.SE3(data.site_xmat[i].reshape(3, 3).copy(), data.site_xpos[i].copy())

    def set_body_pose(
        self, name: str, pos: Sequence[float], quat: Sequence[float] | None = None
    ) -> None:
        """Place a free (or mocap) body at `pos` with `quat` [w, x, y, z].

        `quat=None` keeps the current orientation. A free body's velocity is zeroed, as a
        teleported object should not keep moving. Call `forward()` to update derived poses.
        """
        i = self.body_id(name)
        model, data = self.model, self.data
        p = vector(pos, 3, f"set_body_pose({name!r}).pos")
        q = None if quat is None else vector(quat, 4, f"set_body_pose({name!r}).quat")
        if q is not None:
            norm = np.linalg.norm(q)
            if norm < 1e-12:
                raise SpecError(f"set_body_pose({name!r}).quat must be non-zero, got {quat!r}")
            q = q / norm
        mocap = model.body_mocapid[i]
        if mocap >= 0:
            data.mocap_pos[mocap] = p
            if q is not None:
                data.mocap_quat[mocap] = q
            return
        j = model.body_jntadr[i]
        if model.body_jntnum[i] < 1 or int(model.jnt_type[j]) != int(mujoco.mjtJoint.mjJNT_FREE):
            raise SpecError(
                f"set_body_pose({name!r}): body has no free joint (only free objects and mocap "
                "bodies can be placed)"
            )
        adr, dof = model.jnt_qposadr[j], model.jnt_dofadr[j]
        data.qpos[adr : adr + 3] = p
        if q is not None:
            data.qpos[adr + 3 : adr + 7] = q
        data.qvel[dof : dof + 6] = 0.0

    # ------------------------------------------------------------------ robots

    def create_robot(
        self,
        base_body: str,
        tip_body: str,
        prefix: str = "",
        tool: ToolFrameSpec | None = None,
    ) -> Robot:
        """A `Robot` handle on the chain from `base_body` to `tip_body` (names without prefix)."""
        from .robot import Robot

        self._check_open()
        robot = Robot(self, base_body, tip_body, prefix=prefix, tool=tool)
        self._robots.add(robot)
        return robot

    def _registered_robots(self) -> list[Robot]:
        return list(self._robots)
