"""Plain dataclasses that describe a task: arms and how they are actuated, sensors, episode."""

from __future__ import annotations

import enum
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from ..spec import SceneSpec, ToolFrameSpec
from .randomization import Randomization

if TYPE_CHECKING:
    import numpy as np

Observation = Mapping[str, "np.ndarray"]
Initializer = Callable[[Any, "np.random.Generator"], None]


CARTESIAN_AXES = ("vx", "vy", "vz", "wx", "wy", "wz")
"""The entries of a TCP twist, in the order a Cartesian action holds them."""


class Actuation(enum.Enum):
    """What an arm's part of the action commands."""

    JOINT_POSITION = "joint_position"
    """One joint position per joint (POSITION mode), within the joint limits."""
    JOINT_VELOCITY = "joint_velocity"
    """One joint velocity per joint (VELOCITY mode), within the model's velocity limits."""
    JOINT_TORQUE = "joint_torque"
    """One torque per joint on top of gravity compensation (TORQUE mode)."""
    CARTESIAN_VELOCITY = "cartesian_velocity"
    """A TCP twist `[vx, vy, vz, wx, wy, wz]` along the control frame, bounded by the arm's
    maximum velocities (`ArmSpec.cartesian_axes` keeps some of its entries)."""


@dataclass
class GripperSpec:
    """A gripper driven by one actuator: `open`/`closed` are its ctrl values.

    `actuator` is named without the arm's prefix. The action entry is in [0, 1] (0 open,
    1 closed); `binary` grippers open below 0.5 and close from 0.5 on. With `held` the
    gripper stays at that command and takes no action entry (panda-gym's `block_gripper`).
    """

    actuator: str
    """The gripper's actuator, without the arm's prefix. Required."""
    open: float
    """The actuator's ctrl value that opens the gripper (action 0). Required."""
    closed: float
    """The actuator's ctrl value that closes the gripper (action 1). Required."""
    binary: bool = True
    """Open below 0.5, close from 0.5 on; False: ctrl linear in the action."""
    held: float | None = None
    """None: the action's entry commands the gripper; else the command (0 open, 1 closed)
    it holds from every reset on, with no action entry (a pusher's closed fingers)."""


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
    """Prefix of the arm's observations and action labels (`{name}_joint_pos`). Required."""
    base_body: str
    """First body of the chain, without `prefix` (as in `Scene.create_robot`). Required."""
    tip_body: str
    """Last body of the chain, without `prefix`. Required."""
    prefix: str = ""
    """The robot's prefix in the scene (`RobotSpec.prefix`)."""
    tool: ToolFrameSpec | None = None
    """The tool and TCP below the tip; None: the TCP is the tip body."""
    actuation: Actuation = Actuation.CARTESIAN_VELOCITY
    """What the arm's part of the action commands."""
    control_frame: str = ""
    """Site or body (full name) whose axes the Cartesian action is along; "": the world."""
    gripper: GripperSpec | None = None
    """The gripper, which adds one action entry unless `held`; None: no gripper."""
    home: list[float] | None = None
    """Joint positions (chain order) at every reset; None keeps the model's `qpos0`."""
    cartesian_axes: tuple[str, ...] = CARTESIAN_AXES
    """The twist entries the Cartesian action holds, in `CARTESIAN_AXES` order; the others
    are zero. ("vx", "vy", "vz", "wz"): a top-down gripper's translation and yaw, as pick
    benchmarks act; ("vx", "vy", "vz"): translation alone."""
    max_linear_velocity: float = 0.5
    """Bound of the Cartesian action's linear part, m/s."""
    max_angular_velocity: float = 1.0
    """Bound of the Cartesian action's angular part, rad/s (and of the joint velocity
    action where the model has no velocity limit)."""


@dataclass
class CameraSensor:
    """RGB (and depth) images from a scene camera, with its intrinsic matrix.

    Observations `{name}_rgb` (H×W×3 uint8), `{name}_depth` (H×W float32, metres along the
    optical axis) when `depth`, and `{name}_intrinsics` (3×3); `name` defaults to the camera's.
    Shadows and reflections are off unless asked for: with software OpenGL (EGL on a machine
    without a GPU) they make a 128x128 image about 9x slower.
    """

    camera: str
    """The scene camera's name. Required."""
    width: int = 128
    """Image width, pixels."""
    height: int = 128
    """Image height, pixels."""
    depth: bool = False
    """Also observe `{name}_depth` (metres along the optical axis)."""
    name: str = ""
    """Observation prefix; "": the camera's name."""
    shadows: bool = False
    """Render shadows (much slower on software OpenGL)."""
    reflections: bool = False
    """Render reflections (much slower on software OpenGL)."""


@dataclass
class BodyPoseSensor:
    """World pose of a body: `{name}_pose` = [x, y, z, qw, qx, qy, qz]; `name` defaults to it."""

    body: str
    """The body's full name. Required."""
    name: str = ""
    """Observation prefix; "": the body's name."""


@dataclass
class RelativePositionSensor:
    """Where `body` is seen from arm `arm`'s TCP: `{name}_rel` = body position minus TCP
    position, world axes (the goal or the cube relative to the hand); `name` defaults to
    `body`."""

    body: str
    """The body's full name. Required."""
    arm: str
    """The arm (`ArmSpec.name`) whose TCP it is seen from. Required."""
    name: str = ""
    """Observation prefix; "": the body's name."""


@dataclass
class ContactSensor:
    """Which of `others` `body` touches: `{name}_contacts`, 1.0 per touching body, else 0.0
    (the cube between two fingers: `ContactSensor("cube", ["left_finger", "right_finger"])`);
    `name` defaults to `body`."""

    body: str
    """The body whose contacts count. Required."""
    others: Sequence[str]
    """The bodies it may touch, one observation entry each. Required."""
    name: str = ""
    """Observation prefix; "": the body's name."""


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
    """The scene the task runs in. Required."""
    arms: list[ArmSpec]
    """The controlled arms, in action order. Required."""
    control_timestep: float = 0.1
    """Seconds each action is held: a whole number of physics timesteps."""
    time_limit: float | None = 10.0
    """Episode length in seconds; reaching it sets `truncated`. None: no limit of its own."""
    sensors: Sequence[Any] = field(default_factory=list)
    """`CameraSensor`, `BodyPoseSensor`, `ContactSensor`, `RelativePositionSensor` or any
    `mjkdl.task.Sensor`."""
    initializers: Sequence[Initializer] = field(default_factory=list)
    """Callables `(env, rng)` run in order at every reset, after `home`."""
    reward: Callable[[Observation], float] | None = None
    """`reward(obs)` -> a finite real number; None: reward 0."""
    terminated: Callable[[Observation], bool] | None = None
    """`terminated(obs)` -> True/False; None: never terminated."""
    success: Callable[[Observation], bool] | None = None
    """`success(obs)` -> True/False, reported as `info["is_success"]`; None: never."""
    terminate_on_success: bool = False
    """End the episode once success has held for `success_hold` seconds."""
    success_hold: float = 0.0
    """Seconds success must hold before `terminate_on_success` ends the episode."""
    normalize_actions: bool = False
    """Every action entry in [-1, 1], mapped linearly onto the arm's bounds."""
    hide: Sequence[str] = ()
    """Observation keys left out of what `reset` and `step` return (rewards, success and
    termination still see them), e.g. joint torques in N·m that swamp a learner's inputs."""
    randomization: Randomization | None = None
    """What varies per episode (`mjkdl.task.randomization`): drawn at every reset from the
    env's generator; None: the nominal model every episode."""
