"""Plain dataclasses that describe a scene; `compile.py` turns them into a MuJoCo model."""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from math import pi
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import mujoco


class AttachKind(enum.Enum):
    """What kind of MuJoCo element a model is mounted on."""

    Body = "body"
    """A body: the mounted model's root becomes its child."""
    Site = "site"
    """A site: the mounted model takes the site's pose (the usual tool flange)."""
    Frame = "frame"
    """An MJCF `<frame>`."""


@dataclass
class AttachTarget:
    """A mount point: a body, site or frame by name (names inside a robot omit its prefix)."""

    kind: AttachKind = AttachKind.Site
    """Whether `name` is a body, a site or a frame (default: a site)."""
    name: str = ""
    """The element's name; inside a robot without the robot's prefix. Required (no default)."""


class Shape(enum.Enum):
    """Primitive geom shapes; `size` follows MuJoCo's geom size convention for each."""

    BOX = "box"
    """`size`: three half-lengths."""
    SPHERE = "sphere"
    """`size`: the radius."""
    CYLINDER = "cylinder"
    """`size`: radius and half-height."""
    CAPSULE = "capsule"
    """`size`: radius and half-height of the cylindrical part."""
    ELLIPSOID = "ellipsoid"
    """`size`: three radii."""


class Condim(enum.IntEnum):
    """MuJoCo contact dimensionality."""

    Frictionless = 1
    """Normal force only."""
    Sliding = 3
    """Plus tangential (sliding) friction: MuJoCo's default."""
    Torsional = 4
    """Plus torsional friction: grasped objects do not spin about the contact normal."""
    Rolling = 6
    """Plus rolling friction."""


def _zeros3() -> list[float]:
    return [0.0, 0.0, 0.0]


class _Required:
    """The default of a field that must be set: building a spec that still holds it raises,
    naming the field (there is no invented default)."""

    def __repr__(self) -> str:
        return "REQUIRED"


REQUIRED: Any = _Required()
"""Marks a required field of a description: `SceneSpec(timestep=REQUIRED)` is unset."""


@dataclass
class AttachmentSpec:
    """An MJCF model (gripper, sensor, tool) mounted on a robot, offset by `pos`/`euler`."""

    mjcf_path: str | Path = ""
    """The MJCF file to mount. Required."""
    attach_to: AttachTarget | None = None
    """Where on the robot it goes (names without the robot's prefix). Required."""
    prefix: str = ""
    """Added to every name of the mounted model (after the robot's own prefix)."""
    pos: list[float] = field(default_factory=_zeros3)
    """Offset from `attach_to`, metres."""
    euler: list[float] = field(default_factory=_zeros3)
    """Rotation from `attach_to`: intrinsic xyz Euler angles, degrees."""


@dataclass
class GripperDrive:
    """A parallel gripper that squeezes with a set force and moves its fingers at a set speed,
    as real hands do (the Franka Hand's `grasp(width, speed, force)`), instead of the soft
    position servo of its model. Applied when the scene is built (docs/physics.md):

    - the actuator's servo is made stiff and force-limited, so a closed command on an object
      presses each finger on it with `force` (from 5 mm short of the commanded position on);
    - each finger joint gets the damping `force / speed`, so a free finger moves at `speed`;
    - the fingers' pad geoms (`pads`) get stiff, overdamped contacts that win over the
      object's (`solref` 0.004 s with damping ratio 2, `solimp` 0.95-0.99: as stiff as
      Menagerie's Robotiq 2F-85 pads; by `solmix`, so the object keeps its friction and
      condim).

    The actuator (named without the robot's prefix) must be a position servo on slide finger
    joints, directly or through a fixed tendon with equal coefficients (Menagerie's Panda hand).
    The defaults are the Franka Hand's: `GripperDrive.franka_hand()`.
    """

    actuator: str = ""
    """The gripper's position-servo actuator, without the robot's prefix. Required."""
    force: float = 20.0
    """Force each finger presses on a held object, N (frankx's Franka Hand default; Franka's
    datasheet: 70 N continuous, 140 N peak)."""
    speed: float = 0.05
    """Speed of each finger moving freely, m/s (the Franka Hand's maximum: 0.05 m/s per
    finger, libfranka's `speed` of 0.1 m/s on the width)."""
    pads: str = ""
    """The finger geoms that get the pads' contacts: those whose name or default class,
    without the robot's prefix, starts with this; "" for every geom of the finger bodies."""

    @classmethod
    def franka_hand(cls) -> GripperDrive:
        """Menagerie's Panda hand (`actuator8`) at the Franka Hand's 20 N and 0.05 m/s, its
        fingertip pads (classes `fingertip_pad_collision_*`) stiff, the rest of its fingers
        as the model has them."""
        return cls(actuator="actuator8", pads="fingertip_pad_collision")


@dataclass
class JointImpedanceDrive:
    """An arm whose joints track position setpoints through a joint impedance, as a Franka
    robot's own controller does, instead of its model's servos. Applied when the scene is
    built: each of `actuators` becomes tau = K (ctrl - q) - D dq on its joint, within
    ±`torque_limit`, with D = 2 sqrt(K m), critical damping of the joint's own inertia m (the
    mass matrix's diagonal, armature included) at `damping_pose`; and the robot's weight is
    cancelled by MuJoCo (`gravcomp` on its bodies, through its joints' actuators, so measured
    joint torques include it), as the arm compensates its own gravity. A setpoint velocity
    dq_d enters as ctrl = q_d + (D / K) dq_d. The defaults are the Franka robot's:
    `JointImpedanceDrive.franka()`.
    """

    actuators: list[str] = field(default_factory=list)
    """The arm's actuators, without the robot's prefix, each on one hinge or slide joint
    (no activation dynamics). Required."""
    stiffness: list[float] = field(default_factory=list)
    """K per actuator, N·m/rad (N/m on a slide joint)."""
    torque_limit: list[float] = field(default_factory=list)
    """The torque each joint may exert, N·m (N on a slide joint), on top of gravity."""
    damping_pose: list[float] = field(default_factory=list)
    """The actuated joints' positions at which their inertia sets the damping."""

    @classmethod
    def franka(cls) -> JointImpedanceDrive:
        """Menagerie's Panda (`actuator1`..`actuator7`) with the Franka robot's default joint
        stiffness, its joint torque limits (the Panda's and the FR3's) and damping set in
        libfranka's start pose."""
        return cls(
            actuators=[f"actuator{i}" for i in range(1, 8)],
            stiffness=[3000.0, 3000.0, 3000.0, 2500.0, 2500.0, 2000.0, 2000.0],
            torque_limit=[87.0] * 4 + [12.0] * 3,
            damping_pose=[0.0, -pi / 4, 0.0, -3 * pi / 4, 0.0, pi / 2, pi / 4],
        )


@dataclass
class RobotSpec:
    """A robot from an MJCF or URDF file, in the world at `pos`/`euler` or on `attach_to`.

    URDF only: `srdf` names an SRDF whose `disable_collisions` pairs are excluded (found next
    to the URDF when empty); `floating=True` gives the root link a free joint.
    """

    path: str | Path = ""
    """The robot's MJCF or URDF file. Required."""
    prefix: str = ""
    """Added to every name of the robot (bodies, joints, actuators, ...), e.g. "left/"."""
    attach_to: AttachTarget | None = None
    """Where to mount the robot (a body, site or frame of an object or an earlier robot); None: the
    world."""
    pos: list[float] = field(default_factory=_zeros3)
    """Position of the robot's root in the world or in `attach_to`, metres."""
    euler: list[float] = field(default_factory=_zeros3)
    """Orientation of the robot's root: intrinsic xyz Euler angles, degrees."""
    attachments: list[AttachmentSpec] = field(default_factory=list)
    """Tools mounted on the robot, in order (each may mount on what an earlier one added)."""
    srdf: str | Path = ""
    """URDF only: an SRDF whose `disable_collisions` pairs are excluded ("": one next to the URDF,
    if any)."""
    floating: bool = False
    """URDF only: give the root link a free joint (a mobile or floating base)."""
    grippers: list[GripperDrive] = field(default_factory=list)
    """Grippers of the robot (or its attachments) that grasp with a set force
    (`GripperDrive.franka_hand()` for the Panda's hand); empty keeps the models' servos."""
    impedance: JointImpedanceDrive | None = None
    """The arm's joints driven by a joint impedance with gravity compensated
    (`JointImpedanceDrive.franka()` for the Panda); None keeps the model's servos."""


@dataclass
class SceneObject:
    """A primitive (`shape`, `size`, `mass`, `rgba`, `friction`, `condim`) or an MJCF file
    (whose own geoms keep their properties); placed at `pos`/`euler` (degrees); free unless
    `fixed`. A `marker` is a primitive that only shows (a goal): no collisions, no mass, moved
    by `Scene.set_body_pose` and never by physics (a MuJoCo mocap body)."""

    name: str = ""
    """Unique body name of the object (MJCF objects' inner names get `name/` in front). Required."""
    mjcf_path: str | Path = ""
    """An MJCF file for the object; "" for a primitive (then `shape` is required)."""
    shape: Shape | None = None
    """The primitive's shape; required when there is no `mjcf_path`."""
    size: list[float] = field(default_factory=list)
    """The primitive's size in MuJoCo's geom convention (half-sizes for a box, radius for a sphere,
    ...), metres."""
    rgba: list[float] = field(default_factory=lambda: [0.5, 0.5, 0.5, 1.0])
    """The primitive's colour, red, green, blue, alpha in [0, 1]."""
    mass: float = 0.0
    """The primitive's mass in kg; required (> 0) unless `fixed` or `marker`."""
    friction: list[float] = field(default_factory=lambda: [1.0, 0.005, 0.0001])
    """The primitive's sliding, torsional and rolling friction (MuJoCo's default)."""
    condim: Condim = Condim.Sliding
    """The primitive's contact dimensionality."""
    pos: list[float] = field(default_factory=_zeros3)
    """Position in the world, metres."""
    euler: list[float] = field(default_factory=_zeros3)
    """Orientation: intrinsic xyz Euler angles, degrees."""
    fixed: bool = False
    """Welded to the world; otherwise the object gets a free joint."""
    marker: bool = False
    """Only shows: no collisions, no mass, placed by `Scene.set_body_pose` (a mocap body)."""


@dataclass
class CameraSpec:
    """A camera; `pos` and `fovy` (degrees) are required.

    With `attach_to` (a body or site) the camera rides on it, `pos`/`euler` relative to it —
    a wrist camera; without, it is fixed in the world.
    """

    name: str = ""
    """Unique camera name (`Scene.camera_names()`, `use_camera`). Required."""
    pos: list[float] = REQUIRED
    """Position in the world (or in `attach_to`), metres. Required."""
    euler: list[float] = field(default_factory=_zeros3)
    """Orientation: intrinsic xyz Euler angles, degrees; all zero looks along -z (down) with +y up
    in the image."""
    fovy: float = REQUIRED
    """Vertical field of view, degrees. Required."""
    attach_to: AttachTarget | None = None
    """A body or site the camera moves with (a wrist camera); None: fixed in the world."""


@dataclass
class ForceTorqueSensorSpec:
    """A force/torque sensor pair (MuJoCo `force` and `torque` sensor names)."""

    name: str = ""
    """The name `Robot.ft_sensor(name)` takes. Required."""
    force_sensor: str = ""
    """MuJoCo `force` sensor name (without the robot's prefix). Required."""
    torque_sensor: str = ""
    """MuJoCo `torque` sensor name (without the robot's prefix). Required."""


@dataclass
class ToolFrameSpec:
    """The tool mounted below a robot's tip: its root body, TCP and F/T sensors.

    The TCP is `tcp_site` (or the tip body when empty) offset by `tcp_pos`/`tcp_euler` in
    that frame: Panda's hand has no TCP site, its fingertip centre is `tcp_pos=[0, 0, 0.1034]`.
    """

    tool_body: str = ""
    """Root body of the tool subtree below the tip (its inertia and joints join the robot's model);
    "": none."""
    tcp_site: str = ""
    """Site of the tool centre point; "": the tip body's frame."""
    tcp_pos: list[float] = field(default_factory=_zeros3)
    """Offset of the TCP from `tcp_site` (or the tip body), metres."""
    tcp_euler: list[float] = field(default_factory=_zeros3)
    """Rotation of the TCP from `tcp_site` (or the tip body): xyz Euler angles, degrees."""
    ft_sensors: list[ForceTorqueSensorSpec] = field(default_factory=list)
    """Force/torque sensors of the tool, read with `Robot.ft_sensor(name)`."""


@dataclass
class PhysicsOptions:
    """MuJoCo solver options for contacts, applied after the robots' own `<option>`s; None
    keeps what the models set (MuJoCo's defaults otherwise).

    For grasping, `PhysicsOptions.grasping()`: MuJoCo's documentation recommends elliptic
    friction cones with `impratio` > 1 (friction constraints stiffer than the normal ones)
    against objects creeping out of a grip. The registered tasks use it (docs/physics.md
    gives the measurements and the cost).
    """

    cone: str | None = None
    """Friction cone: "pyramidal" (MuJoCo's default, faster) or "elliptic"."""
    impratio: float | None = None
    """Ratio of frictional to normal constraint impedance (elliptic cones only), >= 1."""
    noslip_iterations: int | None = None
    """Iterations of MuJoCo's no-slip post-processing (0 off)."""
    iterations: int | None = None
    """Iterations of the main constraint solver (MuJoCo's default 100)."""

    @classmethod
    def grasping(cls) -> PhysicsOptions:
        """Elliptic cones and `impratio=10`: a grasped object moved at an arm's twist limit
        stays in the grip (docs/physics.md)."""
        return cls(cone="elliptic", impratio=10.0)


@dataclass
class SceneSpec:
    """A whole scene. `timestep`, `add_floor` and `add_skybox` must be set explicitly."""

    timestep: float = REQUIRED
    """Physics timestep in seconds. Required: building without it raises, naming it."""
    add_floor: bool = REQUIRED
    """Add a floor plane at z = 0. Required: building without it raises, naming it."""
    add_skybox: bool = REQUIRED
    """Add a sky texture (rendering only). Required: building without it raises, naming it."""
    gravity_z: float = -9.81
    """Gravity along world z, m/s²."""
    robots: list[RobotSpec] = field(default_factory=list)
    """Robots, built after the objects in this order (a robot may mount on an object or an earlier
    robot)."""
    objects: list[SceneObject] = field(default_factory=list)
    """Objects, built first, in this order."""
    cameras: list[CameraSpec] = field(default_factory=list)
    """Cameras, added last."""
    physics: PhysicsOptions = field(default_factory=PhysicsOptions)
    """Contact and solver options over the models' own (`PhysicsOptions.grasping()` for
    grasping); the default keeps the models' own."""
    userdata: int = 0
    """Entries of MuJoCo's `data.userdata` (`nuserdata`): values of the user's that
    `mj_getState`/`mj_setState` save and restore with the physics (`mjSTATE_USERDATA`, part
    of `mjSTATE_INTEGRATION`). A `TaskEnv` adds its own after them."""


@dataclass
class ResetOptions:
    """How `Env.reset` starts: from MuJoCo's defaults or from a keyframe (index or name)."""

    keyframe: int | str = 0
    """The keyframe to reset to, by index or name (only with `use_keyframe`)."""
    use_keyframe: bool = False
    """Reset to `keyframe` instead of MuJoCo's defaults (`qpos0`, zero velocities)."""


@dataclass
class ResetContext:
    """What a reset hook receives."""

    env: Any
    """The `Env` being reset."""
    model: mujoco.MjModel
    """Its MuJoCo model (edits to it last until the next rebuild)."""
    data: mujoco.MjData
    """Its MuJoCo data, already reset; the hook may write qpos, qvel, ctrl."""
    options: ResetOptions
    """The options `reset` was called with."""


class CtrlMode(enum.Enum):
    """How `Robot.update()` drives the joints."""

    POSITION = "position"
    """Position servos track `jnt_pos_cmd` (gravity feed-forward added)."""
    VELOCITY = "velocity"
    """Velocity servos track `jnt_vel_cmd` (gravity feed-forward added)."""
    TORQUE = "torque"
    """Motors apply `jnt_trq_cmd` (plus gravity with `gravity_compensation`)."""


def scene_object_site_name(obj: SceneObject, site: str) -> str:
    """The compiled name of `site` authored inside the MJCF-backed object `obj`."""
    return f"{obj.name}/{site}"
