"""Plain dataclasses that describe a scene; `compile.py` turns them into a MuJoCo model."""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import mujoco


class AttachKind(enum.Enum):
    """What kind of MuJoCo element a model is mounted on."""

    Body = "body"
    Site = "site"
    Frame = "frame"


@dataclass
class AttachTarget:
    """A mount point: a body, site or frame by name (names inside a robot omit its prefix)."""

    kind: AttachKind = AttachKind.Site
    name: str = ""


class Shape(enum.Enum):
    """Primitive geom shapes; `size` follows MuJoCo's geom size convention for each."""

    BOX = "box"
    SPHERE = "sphere"
    CYLINDER = "cylinder"
    CAPSULE = "capsule"
    ELLIPSOID = "ellipsoid"


class Condim(enum.IntEnum):
    """MuJoCo contact dimensionality."""

    Frictionless = 1
    Sliding = 3
    Torsional = 4
    Rolling = 6


def _zeros3() -> list[float]:
    return [0.0, 0.0, 0.0]


@dataclass
class AttachmentSpec:
    """An MJCF model (gripper, sensor, tool) mounted on a robot, offset by `pos`/`euler`."""

    mjcf_path: str | Path = ""
    attach_to: AttachTarget | None = None
    prefix: str = ""
    pos: list[float] = field(default_factory=_zeros3)
    euler: list[float] = field(default_factory=_zeros3)


@dataclass
class RobotSpec:
    """A robot from an MJCF or URDF file, in the world at `pos`/`euler` or on `attach_to`.

    URDF only: `srdf` names an SRDF whose `disable_collisions` pairs are excluded (found next
    to the URDF when empty); `floating=True` gives the root link a free joint.
    """

    path: str | Path = ""
    prefix: str = ""
    attach_to: AttachTarget | None = None
    pos: list[float] = field(default_factory=_zeros3)
    euler: list[float] = field(default_factory=_zeros3)
    attachments: list[AttachmentSpec] = field(default_factory=list)
    srdf: str | Path = ""
    floating: bool = False


@dataclass
class SceneObject:
    """A primitive (`shape`, `size`, `mass`, `rgba`, `friction`, `condim`) or an MJCF file
    (whose own geoms keep their properties); placed at `pos`/`euler` (degrees); free unless
    `fixed`. A `marker` is a primitive that only shows (a goal): no collisions, no mass, moved
    by `Scene.set_body_pose` and never by physics (a MuJoCo mocap body)."""

    name: str = ""
    mjcf_path: str | Path = ""
    shape: Shape | None = None
    size: list[float] = field(default_factory=list)
    rgba: list[float] = field(default_factory=lambda: [0.5, 0.5, 0.5, 1.0])
    mass: float = 0.0
    friction: list[float] = field(default_factory=lambda: [1.0, 0.005, 0.0001])
    condim: Condim = Condim.Sliding
    pos: list[float] = field(default_factory=_zeros3)
    euler: list[float] = field(default_factory=_zeros3)
    fixed: bool = False
    marker: bool = False


@dataclass
class CameraSpec:
    """A camera; `pos` and `fovy` (degrees) are required.

    With `attach_to` (a body or site) the camera rides on it, `pos`/`euler` relative to it —
    a wrist camera; without, it is fixed in the world.
    """

    name: str = ""
    pos: list[float] | None = None
    euler: list[float] = field(default_factory=_zeros3)
    fovy: float | None = None
    attach_to: AttachTarget | None = None


@dataclass
class ForceTorqueSensorSpec:
    """A force/torque sensor pair (MuJoCo `force` and `torque` sensor names)."""

    name: str = ""
    force_sensor: str = ""
    torque_sensor: str = ""


@dataclass
class ToolFrameSpec:
    """The tool mounted below a robot's tip: its root body, TCP and F/T sensors.

    The TCP is `tcp_site` (or the tip body when empty) offset by `tcp_pos`/`tcp_euler` in
    that frame: Panda's hand has no TCP site, its fingertip centre is `tcp_pos=[0, 0, 0.1034]`.
    """

    tool_body: str = ""
    tcp_site: str = ""
    tcp_pos: list[float] = field(default_factory=_zeros3)
    tcp_euler: list[float] = field(default_factory=_zeros3)
    ft_sensors: list[ForceTorqueSensorSpec] = field(default_factory=list)


@dataclass
class SceneSpec:
    """A whole scene. `timestep`, `add_floor` and `add_skybox` must be set explicitly."""

    timestep: float | None = None
    add_floor: bool | None = None
    add_skybox: bool | None = None
    gravity_z: float = -9.81
    robots: list[RobotSpec] = field(default_factory=list)
    objects: list[SceneObject] = field(default_factory=list)
    cameras: list[CameraSpec] = field(default_factory=list)


@dataclass
class ResetOptions:
    """How `Env.reset` starts: from MuJoCo's defaults or from a keyframe (index or name)."""

    keyframe: int | str = 0
    use_keyframe: bool = False


@dataclass
class ResetContext:
    """What a reset hook receives."""

    env: Any
    model: mujoco.MjModel
    data: mujoco.MjData
    options: ResetOptions


class CtrlMode(enum.Enum):
    """How `Robot.update()` drives the joints."""

    POSITION = "position"
    VELOCITY = "velocity"
    TORQUE = "torque"


def scene_object_site_name(obj: SceneObject, site: str) -> str:
    """The compiled name of `site` authored inside the MJCF-backed object `obj`."""
    return f"{obj.name}/{site}"
