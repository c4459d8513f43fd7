"""Plain dataclasses that describe a task: arms and how they are actuated, sensors, episode."""

from __future__ import annotations

import enum
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from ..spec import SceneSpec, ToolFrameSpec

if TYPE_CHECKING:
    import numpy as np

Observation = Mapping[str, "np.ndarray"]
Initializer = Callable[[Any, "np.random.Generator"], None]


class Actuation(enum.Enum):
    """What an arm's part of the action commands."""

    JOINT_POSITION = "joint_position"
    JOINT_VELOCITY = "joint_velocity"
    JOINT_TORQUE = "joint_torque"
    CARTESIAN_VELOCITY = "cartesian_velocity"


@dataclass
class GripperSpec:
    """A gripper driven by one actuator: `open`/`closed` are its ctrl values.

    `actuator` is named without the arm's prefix. The action entry is in [0, 1] (0 open,
    1 closed); `binary` grippers open below 0.5 and close from 0.5 on.
    """

    actuator: str
    open: float
    closed: float
    binary: bool = True


@dataclass
class ArmSpec:
    """One arm of the task: its chain, tool, actuation and start pose.

    `name` prefixes the arm's observations (`{name}_joint_pos`, ...). `base_body`, `tip_body`,
    the tool's names and the gripper actuator omit the robot's `prefix`, as in
    `Scene.create_robot`; `control_frame` is a full site or body name ("" = world).
    `home` (joint positions, chain order) is where every episode starts, before initializers;
    None keeps the model's `qpos0`. The velocity limits bound the Cartesian action (positive,
    at most 1000 m/s and rad/s: the action space is float32).
    """

    name: str
    base_body: str
    tip_body: str
    prefix: str = ""
    tool: ToolFrameSpec | None = None
    actuation: Actuation = Actuation.CARTESIAN_VELOCITY
    control_frame: str = ""
    gripper: GripperSpec | None = None
    home: list[float] | None = None
    max_linear_velocity: float = 0.5
    max_angular_velocity: float = 1.0


@dataclass
class CameraSensor:
    """RGB (and depth) images from a scene camera, with its intrinsic matrix.

    Observations `{name}_rgb` (H×W×3 uint8), `{name}_depth` (H×W float32, metres along the
    optical axis) when `depth`, and `{name}_intrinsics` (3×3); `name` defaults to the camera's.
    Shadows and reflections are off unless asked for: with software OpenGL (EGL on a machine
    without a GPU) they make a 128x128 image about 9x slower.
    """

    camera: str
    width: int = 128
    height: int = 128
    depth: bool = False
    name: str = ""
    shadows: bool = False
    reflections: bool = False


@dataclass
class BodyPoseSensor:
    """World pose of a body: `{name}_pose` = [x, y, z, qw, qx, qy, qz]; `name` defaults to it."""

    body: str
    name: str = ""


@dataclass
class RelativePositionSensor:
    """Where `body` is seen from arm `arm`'s TCP: `{name}_rel` = body position minus TCP
    position, world axes (the goal or the cube relative to the hand); `name` defaults to
    `body`."""

    body: str
    arm: str
    name: str = ""


@dataclass
class ContactSensor:
    """Which of `others` `body` touches: `{name}_contacts`, 1.0 per touching body, else 0.0
    (the cube between two fingers: `ContactSensor("cube", ["left_finger", "right_finger"])`);
    `name` defaults to `body`."""

    body: str
    others: Sequence[str]
    name: str = ""


@dataclass
class TaskSpec:
    """A whole task: the scene, its arms, the control period and how an episode goes.

    `control_timestep` must be a whole number of physics timesteps. `time_limit` (seconds)
    sets `truncated`; None leaves episode length to a wrapper (Gymnasium's `TimeLimit`).
    `sensors` are `CameraSensor`, `BodyPoseSensor`, `ContactSensor` or any object following
    `mjkdl.task.Sensor`. `initializers` run in order at every reset with the env's seeded
    generator; any callable `(env, rng)` works.

    `reward(obs)`, `terminated(obs)` and `success(obs)` see the observation of the step and
    return a finite real number and `True`/`False` (NumPy scalars too); anything else raises.
    `success` fills `info["is_success"]` at every reset and step (False without one). With
    `terminate_on_success` the episode ends once success has held for `success_hold` seconds,
    and that last step's reward counts once more for every step the end cuts off (up to
    `time_limit`, or without one the `max_episode_steps` Gymnasium registered for the env),
    so succeeding early never costs reward.
    `normalize_actions` makes every action entry lie in [-1, 1], mapped linearly onto the
    arm's bounds (the gripper: -1 open, +1 closed).
    """

    scene: SceneSpec
    arms: list[ArmSpec]
    control_timestep: float = 0.1
    time_limit: float | None = 10.0
    sensors: Sequence[Any] = field(default_factory=list)
    initializers: Sequence[Initializer] = field(default_factory=list)
    reward: Callable[[Observation], float] | None = None
    terminated: Callable[[Observation], bool] | None = None
    success: Callable[[Observation], bool] | None = None
    terminate_on_success: bool = False
    success_hold: float = 0.0
    normalize_actions: bool = False
