"""`TaskEnv`: a `TaskSpec` as a `gymnasium.Env` — arms, effectors, sensors and episodes."""

from __future__ import annotations

import copy
import dataclasses
import math
import os
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces
from numpy.typing import ArrayLike

from ..control import CartesianVelocityController, Gripper
from ..errors import SimulationError, SpecError, SpecTypeError, UnknownNameError, unknown_name
from ..names import model_id
from ..record import check_offscreen_size, offscreen_renderer
from ..robot import Robot
from ..scene import MAX_STEPS, Env
from ..spec import CtrlMode, JointImpedanceDrive, SceneSpec
from ..validate import flag, real, real_array, text, vector
from ._check import integer, names
from .randomization import Draw, Randomizer
from .rewards import check_positions, success_bonus

if TYPE_CHECKING:
    from ..hw.in_the_loop import ArmLink
    from ..hw.joint_impedance import FrankaImpedanceDrive
from .sensors import (
    ArmReader,
    CameraReader,
    ContactReader,
    PoseReader,
    Reader,
    RelativeReader,
)
from .spec import (
    CARTESIAN_AXES,
    Actuation,
    ArmSpec,
    BodyPoseSensor,
    CameraSensor,
    ContactSensor,
    GripperSpec,
    RelativePositionSensor,
    TaskSpec,
)

# How a simulated arm moves: "servo", Menagerie's position actuators; "franka_impedance", the
# Franka robot's joint impedance as the arm in the loop runs it (`FrankaImpedanceDrive`).
ARM_DRIVES = ("servo", "franka_impedance")
IMPEDANCE_TIMESTEP = 0.001  # s: the robot's control tick, which the impedance drive needs
# `lockstep=True`: the arm's ticks wait for the env's commands, and a loaded machine's stall of
# the env's process is a wait, not the end of the motion (the watchdog's), for up to 5 s (the
# simulator then needs `--command-timeout` above that: its default waits 1 s); the connection
# waits up to 2 min for the simulator's first answer (its client process starting on a
# loaded machine).
LOCKSTEP_LINK: dict[str, Any] = {"lockstep": True, "watchdog": 5.0, "connect_timeout": 120.0}
MAX_VELOCITY = 1e3  # m/s and rad/s: an arm's Cartesian (and default joint) velocity bound
_MODES = {
    Actuation.JOINT_POSITION: CtrlMode.POSITION,
    Actuation.JOINT_VELOCITY: CtrlMode.VELOCITY,
    Actuation.JOINT_TORQUE: CtrlMode.TORQUE,
    # The controller integrates its joint velocities into the position command, which the
    # arm's servos track: the TCP holds still under gravity and contact at a zero twist.
    Actuation.CARTESIAN_VELOCITY: CtrlMode.POSITION,
}


@runtime_checkable
class Sensor(Protocol):
    """A user observation source for `TaskSpec.sensors`.

    `space(env)` is called once, when the env is built: the observations it adds, by name.
    `read(env)` is called at every reset and step and returns a mapping with a value for each
    of them, of the declared shape, that the declared dtype holds exactly (real numbers for a
    float Box, integers in range for an integer one); it is copied into the observation.
    """

    def space(self, env: TaskEnv) -> Mapping[str, spaces.Box]: ...

    def read(self, env: TaskEnv) -> Mapping[str, ArrayLike]: ...


class UserReader(Reader):
    """Adapts a `Sensor`: its values are checked and copied into the observation."""

    def __init__(self, sensor: Sensor, env: TaskEnv, where: str) -> None:
        boxes = sensor.space(env)
        if not isinstance(boxes, Mapping) or not all(
            isinstance(k, str) and isinstance(b, spaces.Box) for k, b in boxes.items()
        ):
            raise SpecError(f"{where}.space(env) must return a mapping of names to Box spaces")
        super().__init__(dict(boxes))
        self._sensor, self._env, self._where = sensor, env, where

    def read(self) -> None:
        values = self._sensor.read(self._env)
        where = f"{self._where}.read(env)"
        if not isinstance(values, Mapping):
            raise SpecTypeError(f"{where} must return a mapping of names to values, got {values!r}")
        for key, buf in self.buffers.items():
            if key not in values:
                raise SpecError(f"{where} returned no {key!r}")
            value = _fitting(values[key], buf.dtype, f"{where}[{key!r}]")
            if value.shape != buf.shape:
                raise SpecError(
                    f"{where}[{key!r}] has shape {value.shape}, its space says {buf.shape}"
                )
            np.copyto(buf, value, casting="unsafe")  # checked: a kind and range it takes


def _fitting(value: object, dtype: np.dtype, field: str) -> np.ndarray:
    """`value` as an array whose values `dtype` holds exactly as numbers of its kind: reals
    for a float space, integers in range for an integer one, bools for a bool one."""
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError):  # ragged nesting
        raise SpecTypeError(f"{field} must be an array of numbers, got {value!r}") from None
    kinds = "b" if dtype.kind == "b" else "iu" if dtype.kind in "iu" else "iuf"
    if arr.dtype.kind not in kinds:
        raise SpecTypeError(
            f"{field} holds {arr.dtype} values, which its space's {dtype} cannot take: {value!r}"
        )
    if dtype.kind in "iu" and arr.size:
        info = np.iinfo(dtype)
        if arr.min() < info.min or arr.max() > info.max:
            raise SpecError(f"{field} holds values outside {dtype}'s range: {value!r}")
    return arr


class ArmEffector:
    """One arm's slice of the action: written to its robot (and gripper) every step.

    `arm` is its `ArmSpec`, `robot` and `gripper` its handles, `controller` the Cartesian
    controller (None in the joint modes), `slice` its entries of the action and `grip_index`
    the gripper's entry (-1 without one)."""

    def __init__(
        self,
        arm: ArmSpec,
        robot: Robot,
        gripper: Gripper | None,
        controller: CartesianVelocityController | None,
        start: int,
    ) -> None:
        self.arm, self.robot, self.gripper, self.controller = arm, robot, gripper, controller
        self.axes = np.array([CARTESIAN_AXES.index(a) for a in arm.cartesian_axes], np.intp)
        self._twist = np.zeros(6)  # the action's entries, zeros for the axes it omits
        n = len(self.axes) if controller is not None else robot.n_joints
        self.slice = slice(start, start + n)
        # A held gripper takes no entry: its command is set at reset and never changes.
        self.held = None if gripper is None or arm.gripper is None else arm.gripper.held
        self.grip_index = start + n if gripper is not None and self.held is None else -1
        self.home = None if arm.home is None else np.asarray(arm.home, dtype=float)
        self._command = self._previous = np.zeros(0)  # views of the scene's userdata

    def bind_state(self, userdata: np.ndarray, at: int) -> int:
        """Keep what the controller carries between steps (the integrated joint command, the
        last solution) in `userdata[at:]`; the index after it."""
        if self.controller is None:
            return at
        n = self.robot.n_joints
        self._command, self._previous = userdata[at : at + n], userdata[at + n : at + 2 * n]
        return at + 2 * n

    @property
    def state_size(self) -> int:
        """Entries of userdata `bind_state` takes."""
        return 0 if self.controller is None else 2 * self.robot.n_joints

    def start_state(self) -> None:
        """The controller's state at an episode's start, once the commands hold the arm:
        the measured positions and velocities (a fresh controller's)."""
        if self.controller is not None:
            np.copyto(self._command, self.robot.jnt_pos_cmd)
            np.copyto(self._previous, self.robot.jnt_vel_msr)

    def new_episode(self, scene: Env) -> None:
        """Arm at home, gripper open (or as `held`), and a fresh controller: the QP's
        acceleration bounds start from the state, not from the last episode's motion (its own
        reset detection goes by a clock that an episode of one step does not advance)."""
        if self.home is not None:
            self.robot.set_joint_pos(self.home, call_forward=False)
        if self.gripper is not None:
            self.gripper.command(0.0 if self.held is None else self.held)
            _settle_tool(scene, self.arm.prefix + self.arm.tip_body)
        if self.controller is not None:
            self.controller = _controller(self.robot, self.arm)

    def apply(self, action: np.ndarray, period: float) -> None:
        """Write this arm's slice of the (physical, clipped) action to its robot and gripper."""
        robot, arm = self.robot, self.arm.actuation
        robot.update()
        a: Any = action[self.slice]
        if self.controller is not None:  # from the state in userdata, which a restore sets
            robot.jnt_pos_cmd = self._command
            self.controller.resume(self._previous)
            self._twist[self.axes] = a
            np.copyto(self._previous, self.controller.command(self._twist, period))
            np.copyto(self._command, robot.jnt_pos_cmd)
        elif arm is Actuation.JOINT_POSITION:
            robot.jnt_pos_cmd = a
        elif arm is Actuation.JOINT_VELOCITY:
            robot.jnt_vel_cmd = a
        else:  # torque on top of gravity compensation, as a torque-controlled arm takes it
            robot.jnt_trq_cmd = a + robot.gravity_torques()
        if self.grip_index >= 0:
            self.gripper.command(action[self.grip_index])  # type: ignore[union-attr]


class TaskEnv(gym.Env[dict[str, Any], np.ndarray]):
    """A task as a Gymnasium environment (see `TaskSpec`; the env keeps a deep copy of it).

    `.scene` is the `mjk.Env` that owns MuJoCo's model and data, `.robots[name]` and
    `.grippers[name]` the arms' handles, `.task_spec` the description, `.action_labels` one
    name per action entry (`"panda.vx"`, ..., `"panda.gripper"`).

    The action concatenates, per arm in order, a twist `[vx, vy, vz, wx, wy, wz]` of the TCP
    along the control frame (Cartesian velocity; the entries of `ArmSpec.cartesian_axes`,
    the others zero) or one value per joint (joint modes), then the gripper's entry in
    [0, 1] when it has one (none when `GripperSpec.held`); with `TaskSpec.normalize_actions`
    every entry is in [-1, 1] instead, scaled onto those bounds. Actions are clipped into
    `action_space` (a policy's exploration noise past a bound acts at the bound); NaN or
    infinite entries are an error naming them. Each `step` holds the action for
    `control_timestep`, i.e. `control_timestep / scene.timestep` physics steps. An episode
    starts with each gripper open (a held one as held): its fingers are moved there before the
    first observation.

    Observations are fresh arrays every step (the agent may keep them); see `ArmReader`,
    `CameraSensor`, `BodyPoseSensor` and `ContactSensor` for their meaning. `info` holds
    `is_success` and `diverged` at every reset and step. `truncated` becomes true once
    `time_limit` seconds have passed since `reset`. A diverging simulation ends the episode
    (`terminated=True`, `info["diverged"]`, the previous observation), and `step` then
    raises until `reset`.

    Rendering: `"rgb_array"` (H×W×3 uint8), `"depth_array"` (H×W float32 metres) of
    `render_camera` at `render_width`×`render_height`, without shadows and reflections unless
    `render_shadows`; `"human"` opens the viewer. `gymnasium.make` adds `"rgb_array_list"`.
    OpenGL contexts are made in the process that renders, at its first frame, so an env built
    before a `fork` (Gymnasium's async vector envs) renders in the child.

    Hardware in the loop (one arm, `[franka]` extra): with `robot_ip` the arm is the real one
    at that address (`.hardware`, `mjkdl.hw.in_the_loop`), mirrored into the scene at every
    physics step while the rest is simulated; each `reset` brings it home; its estimated
    external torques and wrench are the observations `{arm}_ext_torques`/`{arm}_ext_wrench`.
    `haptic=True` renders the simulated contacts on it as joint torques instead. `lockstep=True`
    (against `python -m mjkdl.hw.franka_sim --lockstep` only) makes each of the arm's 1 ms
    ticks wait for the env's command for it (up to 5 s: serve with `--command-timeout 10`),
    so the same actions give the same motion whatever the machine's load.

    `arm_drive="franka_impedance"` (one arm taking position targets) moves the simulated arm
    as a Franka arm in the loop moves: the robot's joint impedance, built into the arm's
    actuators (`JointImpedanceDrive.franka()`), at 1 kHz behind the connection's rate limiter
    (`mjkdl.hw.joint_impedance.FrankaImpedanceDrive`, `.drive`), on a 1 ms physics timestep;
    the default `"servo"` keeps the model's own actuators.
    """

    metadata: dict[str, Any] = {  # noqa: RUF012
        "render_modes": ["rgb_array", "depth_array", "human"],
        "render_fps": 10,
    }
    observation_space: spaces.Dict
    action_space: spaces.Box

    def __init__(
        self,
        spec: TaskSpec,
        render_mode: str | None = None,
        *,
        render_camera: str = "",
        render_width: int = 640,
        render_height: int = 480,
        render_shadows: bool = False,
        robot_ip: str | None = None,
        haptic: bool = False,
        lockstep: bool = False,
        arm_drive: str = "servo",
    ) -> None:
        if not isinstance(spec, TaskSpec):
            raise SpecError(f"TaskEnv takes a TaskSpec, got {type(spec).__name__}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            modes = ", ".join(repr(m) for m in self.metadata["render_modes"])
            hint = (
                " (gymnasium.make adds it around 'rgb_array')"
                if render_mode == "rgb_array_list"
                else ""
            )
            raise SpecError(
                f"render_mode must be None or one of {modes}, got {render_mode!r}{hint}"
            )
        render_width = integer(render_width, "render_width")
        render_height = integer(render_height, "render_height")
        if not isinstance(render_camera, str):
            raise SpecTypeError(f"render_camera must be a camera name, got {render_camera!r}")
        self._render_shadows = flag(render_shadows, "render_shadows")
        self.task_spec = copy.deepcopy(spec)
        self.render_mode = render_mode
        self._closed = True  # until built: close() must work on a half-built env
        self._renderers: dict[tuple[int, int], mujoco.Renderer] = {}
        self._renderer_pid = os.getpid()
        self._readers: list[Reader] = []
        self._viewer: Any = None
        self._stepper: Callable[[], bool] | None = None
        self._check_spec(self.task_spec)
        self.hardware: ArmLink | None = None
        self.drive: FrankaImpedanceDrive | None = None
        if arm_drive not in ARM_DRIVES:
            raise SpecError(
                f"arm_drive must be one of {', '.join(map(repr, ARM_DRIVES))}, got {arm_drive!r}"
            )
        if arm_drive == "franka_impedance":
            self._check_impedance_drive(robot_ip)
        self._arm_drive = arm_drive
        if robot_ip is not None:
            from ..hw.in_the_loop import ExternalForces, attach  # the [franka] extra's layer

            _check_one_arm(self.task_spec, "robot_ip mirrors one arm")
            arm = self.task_spec.arms[0].name
            self.task_spec.sensors = [*self.task_spec.sensors, ExternalForces(arm)]
        self.scene = Env.build(self.task_spec.scene)
        self._closed = False
        try:
            self._build(render_camera, render_width, render_height)
            if robot_ip is not None:
                self.hardware = attach(
                    self.scene,
                    self.robots[arm],
                    robot_ip,
                    haptic=haptic,
                    **(LOCKSTEP_LINK if flag(lockstep, "lockstep") else {}),
                )
            if arm_drive == "franka_impedance":
                from ..hw.joint_impedance import FrankaImpedanceDrive

                self.drive = FrankaImpedanceDrive(self.scene, self._effectors[0].robot)
                self.drive.bind_state(self._drive_state)
            self._check_tick_latency()
        except BaseException:
            self.close()
            raise

    # ------------------------------------------------------------------ building

    def _check_impedance_drive(self, robot_ip: str | None) -> None:
        """`arm_drive="franka_impedance"`: one arm that takes position targets, simulated (the
        arm in the loop runs its own impedance), at the robot's 1 ms timestep."""
        if robot_ip is not None:
            raise SpecError(
                "arm_drive='franka_impedance' simulates the arm's own controller; with robot_ip "
                "the arm in the loop runs it: leave arm_drive at 'servo'"
            )
        spec = self.task_spec
        _check_one_arm(spec, "arm_drive='franka_impedance' drives one arm")
        actuation = spec.arms[0].actuation
        if actuation not in (Actuation.CARTESIAN_VELOCITY, Actuation.JOINT_POSITION):
            raise SpecError(
                f"arm_drive='franka_impedance' tracks position targets; the arm's actuation is "
                f"{actuation.value!r} (use 'cartesian_velocity' or 'joint_position')"
            )
        prefix = spec.arms[0].prefix
        robots = spec.scene.robots
        arm = [i for i, robot in enumerate(robots) if robot.prefix == prefix]
        if len(arm) != 1:
            raise SpecError(
                f"arm_drive='franka_impedance': the scene has {len(arm)} robots with the arm's "
                f"prefix {prefix!r}; it needs one"
            )
        robots = list(robots)
        if robots[arm[0]].impedance is None:  # the robot's own law, built into its actuators
            robots[arm[0]] = dataclasses.replace(
                robots[arm[0]], impedance=JointImpedanceDrive.franka()
            )
        spec.scene = dataclasses.replace(spec.scene, timestep=IMPEDANCE_TIMESTEP, robots=robots)

    def _check_tick_latency(self) -> None:
        """`randomization.action_latency_ticks` delays the impedance drive's commands, by less
        than a control period (longer ones are whole control steps: `action_latency`)."""
        spec = self.task_spec.randomization
        ticks = None if spec is None else spec.action_latency_ticks
        if ticks is None:
            return
        if self.drive is None:
            raise SpecError(
                "randomization.action_latency_ticks delays the 1 ms ticks of "
                "arm_drive='franka_impedance'; this env's arm is driven by its servos "
                "(arm_drive='servo'): pass arm_drive='franka_impedance', or use action_latency "
                "(whole control steps)"
            )
        if ticks[1] >= self._substeps:
            raise SpecError(
                f"randomization.action_latency_ticks {tuple(ticks)}: a control period is "
                f"{self._substeps} ticks, so at most {self._substeps - 1}; longer latencies are "
                "whole control steps (action_latency)"
            )

    @staticmethod
    def _check_spec(spec: TaskSpec) -> None:
        if not isinstance(spec.scene, SceneSpec):
            raise SpecError(f"TaskSpec.scene must be a SceneSpec, got {type(spec.scene).__name__}")
        if not isinstance(spec.arms, list) or not spec.arms:
            raise SpecError("TaskSpec.arms must be a non-empty list of ArmSpec")
        names = []
        for i, arm in enumerate(spec.arms):
            where = f"TaskSpec.arms[{i}]"
            if not isinstance(arm, ArmSpec):
                raise SpecError(f"{where} must be an ArmSpec, got {type(arm).__name__}")
            if not isinstance(arm.name, str) or not arm.name:
                raise SpecError(f"{where}.name must be a non-empty string, got {arm.name!r}")
            if not isinstance(arm.actuation, Actuation):
                raise SpecError(f"{where}.actuation must be an Actuation, got {arm.actuation!r}")
            text(arm.prefix, f"{where}.prefix")
            if arm.gripper is not None:
                if not isinstance(arm.gripper, GripperSpec):
                    raise SpecError(f"{where}.gripper must be a GripperSpec or None")
                text(arm.gripper.actuator, f"{where}.gripper.actuator")
                flag(arm.gripper.binary, f"{where}.gripper.binary")
                held = arm.gripper.held
                if held is not None and not 0.0 <= real(held, f"{where}.gripper.held") <= 1.0:
                    raise SpecError(
                        f"{where}.gripper.held must be None (the action commands the gripper) "
                        f"or a command in [0, 1] (0 open, 1 closed), got {held!r}"
                    )
            _check_axes(arm, where)
            for field in ("max_linear_velocity", "max_angular_velocity"):
                value = getattr(arm, field)
                if not _positive(value):
                    raise SpecError(f"{where}.{field} must be a positive number, got {value!r}")
                if value > MAX_VELOCITY:
                    raise SpecError(
                        f"{where}.{field} must be at most {MAX_VELOCITY:g}, got {value!r}"
                    )
            names.append(arm.name)
        if len(set(names)) != len(names):
            raise SpecError(f"TaskSpec.arms: names must be unique, got {names}")
        for field in ("control_timestep", "time_limit"):
            value = getattr(spec, field)
            if not _positive(value) and not (field == "time_limit" and value is None):
                what = "or None" if field == "time_limit" else ""
                raise SpecError(
                    f"TaskSpec.{field} must be a positive number of seconds {what}".rstrip()
                    + f", got {value!r}"
                )
        for field in ("reward", "terminated", "success"):
            fn = getattr(spec, field)
            if fn is not None and not callable(fn):
                raise SpecError(f"TaskSpec.{field} must be callable or None, got {fn!r}")
        flag(spec.terminate_on_success, "TaskSpec.terminate_on_success")
        flag(spec.normalize_actions, "TaskSpec.normalize_actions")
        if real(spec.success_hold, "TaskSpec.success_hold") < 0:
            raise SpecError(
                f"TaskSpec.success_hold must be a non-negative number of seconds, "
                f"got {spec.success_hold!r}"
            )
        if spec.terminate_on_success and spec.success is None:
            raise SpecError("TaskSpec.terminate_on_success needs a TaskSpec.success callable")
        for field in ("sensors", "initializers"):
            if not isinstance(getattr(spec, field), (list, tuple)):
                raise SpecError(
                    f"TaskSpec.{field} must be a list, got {type(getattr(spec, field)).__name__}"
                )
        for i, init in enumerate(spec.initializers):
            if not callable(init):
                raise SpecError(f"TaskSpec.initializers[{i}] must be callable (env, rng)")

    def _build(self, render_camera: str, render_width: int, render_height: int) -> None:
        spec, scene = self.task_spec, self.scene
        dt = scene.timestep()
        if spec.control_timestep / dt > MAX_STEPS:
            raise SpecError(
                f"TaskSpec.control_timestep ({spec.control_timestep:g} s) is more than "
                f"{MAX_STEPS} physics timesteps ({dt:g} s), MuJoCo's limit per control step"
            )
        substeps = round(spec.control_timestep / dt)
        if substeps < 1 or abs(substeps * dt - spec.control_timestep) > 1e-9 * max(1.0, substeps):
            raise SpecError(
                f"TaskSpec.control_timestep ({spec.control_timestep:g} s) must be a whole "
                f"number of physics timesteps ({dt:g} s)"
            )
        self._substeps = substeps
        self._period = substeps * dt
        self._max_steps = (
            math.inf
            if spec.time_limit is None
            else math.ceil(spec.time_limit / self._period - 1e-9)
        )
        self._hold_steps = math.ceil(spec.success_hold / self._period - 1e-9)
        self.metadata = {**self.metadata, "render_fps": 1.0 / self._period}

        self.robots: dict[str, Robot] = {}
        self.grippers: dict[str, Gripper] = {}
        self._effectors: list[ArmEffector] = []
        low: list[np.ndarray] = []
        high: list[np.ndarray] = []
        labels: list[str] = []
        for i, arm in enumerate(spec.arms):
            eff = self._add_arm(arm, f"TaskSpec.arms[{i}]", start=sum(len(x) for x in low))
            lo, hi, names = _action_bounds(eff, scene.model)
            low.append(lo)
            high.append(hi)
            labels += [f"{arm.name}.{n}" for n in names]
        self._action_low = np.concatenate(low)
        self._action_high = np.concatenate(high)
        self.action_labels = labels
        if spec.normalize_actions:
            span = self._action_high - self._action_low
            unbounded = [n for n, w in zip(labels, span, strict=True) if not np.isfinite(w)]
            if unbounded:
                raise SpecError(
                    f"TaskSpec.normalize_actions: action entries {unbounded} have no finite "
                    "bounds to scale [-1, 1] onto (give the joints effort limits)"
                )
            self.action_space = spaces.Box(-1.0, 1.0, (len(labels),), dtype=np.float32)
            self._action_mid = 0.5 * (self._action_high + self._action_low)
            self._action_half = 0.5 * (self._action_high - self._action_low)
        else:
            self.action_space = spaces.Box(
                self._action_low.astype(np.float32),
                self._action_high.astype(np.float32),
                dtype=np.float32,
            )
        self._action = np.zeros(len(labels))
        # The episode's counters and what the controllers carry between steps live in
        # MuJoCo's userdata, which mjSTATE_INTEGRATION saves and restores: a restored state
        # steps on exactly as the recorded one did. Sized once the arms' joints are known.
        size = spec.scene.userdata + _COUNTERS + sum(e.state_size for e in self._effectors)
        self._drive_size = 0
        if self._arm_drive == "franka_impedance":  # its ramp and rate limiter
            from ..hw.joint_impedance import STATE_SIZE

            self._drive_size = STATE_SIZE
        size += self._drive_size
        if spec.randomization is not None:  # its actions on their way
            size += spec.randomization.state_size(len(labels))
        if scene.model.nuserdata != size:
            scene._rebuild(dataclasses.replace(scene.spec, userdata=size))
        if scene.model.nuserdata != size:  # a stored model (a file's) made by an older mjkdl
            raise SpecError(
                f"the scene's model has {scene.model.nuserdata} userdata entries; this task "
                f"keeps its state in {size}: the model was made by another mjkdl version"
            )

        self._render_camera_name = render_camera
        self._render_size = (render_width, render_height)
        self._randomizer: Randomizer | None = None
        every = self._bind()
        self._shown = _shown_keys(spec.hide, every.spaces)
        self._task_space = spaces.Dict({k: every.spaces[k] for k in self._shown}, sort_keys=False)
        self.observation_space = self._task_space
        for field in ("reward", "terminated", "success"):
            check_positions(getattr(spec, field), every.spaces, f"TaskSpec.{field}")
        if self.render_mode in ("rgb_array", "depth_array"):
            check_offscreen_size(scene.model, render_width, render_height)  # now, not at render()
        self._needs_reset = True
        self._diverged: str | None = None
        if spec.randomization is not None:  # checked against this model and observations
            bounds = (self._action_low, self._action_high)
            keys = list(self._shown)
            self._randomizer = Randomizer(spec.randomization, scene.model, *bounds, keys)
            self._randomizer.bind_state(self._randomizer_state)

    @property
    def randomization_draw(self) -> Draw | None:
        """This episode's draw of `TaskSpec.randomization` (None without one)."""
        return None if self._randomizer is None else self._randomizer.draw

    @randomization_draw.setter
    def randomization_draw(self, draw: Draw) -> None:
        """Make `draw` (a recorded episode's) this episode's: the nominal model with it applied,
        its latency and noise from now on (`mjkdl.demos.restore` sets it with a state)."""
        if self._randomizer is None:
            raise SpecError("this env has no TaskSpec.randomization: it takes no draw")
        ticks = draw.action_latency_ticks
        if ticks and (self.drive is None or ticks >= self._substeps):
            raise SpecError(
                f"the draw's action_latency_ticks ({ticks}) is beyond this env's "
                f"randomization.action_latency_ticks "
                f"{self._randomizer.description.action_latency_ticks}"
            )
        self._randomizer.use(draw, self.scene.model)
        if self.drive is not None:
            self.drive.latency = ticks

    def _bind(self) -> spaces.Dict:
        """Observation sources and the render camera on the scene's current model; the
        observation space they make. Run again when the scene was rebuilt
        (`scene.add_object`), since MuJoCo's arrays are new then."""
        spec, scene = self.task_spec, self.scene
        self._close_renderers()
        self._readers = []
        model, data = scene.model, scene.data
        self._model = model
        sources: list[str] = []
        for i, (eff, arm) in enumerate(zip(self._effectors, spec.arms, strict=True)):
            sources.append(f"TaskSpec.arms[{i}]")
            self._readers.append(ArmReader(model, data, arm, eff.robot, eff.gripper, sources[-1]))
        for i, sensor in enumerate(spec.sensors):
            sources.append(f"TaskSpec.sensors[{i}]")
            self._readers.append(self._reader(sensor, sources[-1]))
        boxes: dict[str, spaces.Space] = {}
        owner: dict[str, str] = {"time": "the env (seconds since reset)"}
        for where, reader in zip(sources, self._readers, strict=True):
            for key, box in reader.spaces.items():
                if key in owner:
                    raise SpecError(
                        f"observation {key!r} is produced by both {owner[key]} and {where}; "
                        "give the sensors distinct names"
                    )
                boxes[key], owner[key] = box, where
        boxes["time"] = spaces.Box(0.0, np.inf, (1,), np.float64)
        self._time = np.zeros(1)
        userdata = data.userdata[spec.scene.userdata :]
        self._counters = userdata[:_COUNTERS]  # control steps since reset, steps of success
        at = _COUNTERS
        for eff in self._effectors:
            at = eff.bind_state(userdata, at)
        self._drive_state = userdata[at : at + self._drive_size]
        if self.drive is not None:
            self.drive.bind_state(self._drive_state)
        at += self._drive_size
        self._randomizer_state = userdata[at:]  # the Randomizer's: its actions on their way
        if self._randomizer is not None:
            self._randomizer.bind_state(self._randomizer_state)
        self._buffers = [(k, b) for r in self._readers for k, b in r.buffers.items()]
        self._buffers.append(("time", self._time))
        self._render_camera: int | mujoco.MjvCamera
        if self._render_camera_name:
            self._render_camera = self._camera_id(self._render_camera_name, "render_camera")
        else:
            self._render_camera = mujoco.MjvCamera()
            mujoco.mjv_defaultFreeCamera(model, self._render_camera)
        return spaces.Dict(boxes, sort_keys=False)

    def _follow_rebuild(self) -> None:
        """Rebind to a rebuilt scene; its observations must keep their names and shapes."""
        new = {k: v for k, v in self._bind().spaces.items() if k in self._task_space.spaces}
        old = self._task_space.spaces
        changed = sorted(k for k in new.keys() | old.keys() if new.get(k) != old.get(k))
        if changed:
            raise SpecError(
                f"the scene was rebuilt and observations {changed} changed their space; "
                "build a new TaskEnv for the new scene"
            )

    def _add_arm(self, arm: ArmSpec, where: str, start: int) -> ArmEffector:
        scene = self.scene
        try:
            robot = scene.create_robot(arm.base_body, arm.tip_body, arm.prefix, arm.tool)
        except (UnknownNameError, SpecError) as err:
            raise type(err)(f"{where} ({arm.name!r}): {err}") from None
        robot.ctrl_mode = _MODES[arm.actuation]
        gripper = None
        if arm.gripper is not None:
            g = arm.gripper
            try:
                gripper = Gripper(scene, arm.prefix + g.actuator, g.open, g.closed, g.binary)
            except (UnknownNameError, SpecError) as err:
                raise type(err)(f"{where}.gripper: {err}") from None
            self.grippers[arm.name] = gripper
        if arm.home is not None:
            home = vector(arm.home, robot.n_joints, f"{where}.home")
            try:
                robot.set_joint_pos(home, call_forward=False)
            except SpecError as err:
                raise SpecError(f"{where}.home: {err}") from None
        controller = None
        if arm.actuation is Actuation.CARTESIAN_VELOCITY:
            try:
                controller = _controller(robot, arm)
            except (UnknownNameError, SpecError) as err:
                raise type(err)(f"{where}.control_frame: {err}") from None
        self.robots[arm.name] = robot
        eff = ArmEffector(arm, robot, gripper, controller, start)
        self._effectors.append(eff)
        return eff

    def _reader(self, sensor: object, where: str) -> Reader:
        model, data = self.scene.model, self.scene.data
        if isinstance(sensor, CameraSensor):
            return CameraReader(model, data, sensor, self._renderer, where)
        if isinstance(sensor, BodyPoseSensor):
            return PoseReader(model, data, sensor, where)
        if isinstance(sensor, ContactSensor):
            return ContactReader(model, data, sensor, where)
        if isinstance(sensor, RelativePositionSensor):
            arms = {r.arm: r for r in self._readers if isinstance(r, ArmReader)}
            return RelativeReader(model, data, sensor, arms, where)
        if isinstance(sensor, Sensor):
            return UserReader(sensor, self, where)
        raise SpecError(
            f"{where} must be a CameraSensor, BodyPoseSensor, ContactSensor, "
            "RelativePositionSensor or a Sensor (space/read), "
            f"got {type(sensor).__name__}"
        )

    def _renderer(self, width: int, height: int) -> mujoco.Renderer:
        """The one renderer of this size (every camera of that size shares it), made at its
        first use in this process: an OpenGL context does not survive a `fork`, so a child
        process makes its own and leaves the parent's alone."""
        if self._renderer_pid != os.getpid():
            _ORPHANED.extend(self._renderers.values())  # the parent's: never freed here
            self._renderers = {}
            self._renderer_pid = os.getpid()
        r = self._renderers.get((width, height))
        if r is None:
            r = offscreen_renderer(
                self.scene.model, width, height, shadows=False, reflections=False
            )
            self._renderers[(width, height)] = r
        return r

    def _close_renderers(self) -> None:
        if self._renderer_pid == os.getpid():
            for r in self._renderers.values():
                r.close()
        else:
            _ORPHANED.extend(self._renderers.values())
        self._renderers = {}

    def _camera_id(self, name: str, where: str) -> int:
        return model_id(self.scene.model, mujoco.mjtObj.mjOBJ_CAMERA, "camera", name, where)

    # ------------------------------------------------------------------ episodes

    def reset(
        self, *, seed: int | None = None, options: Mapping[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Start an episode: MuJoCo's initial state, each arm at `home` with its gripper
        open, then the initializers in order with the env's generator (seeded by `seed`)."""
        self._check_open()
        if options is not None and not isinstance(options, Mapping):
            raise SpecTypeError(f"reset(options=...) must be a mapping or None, got {options!r}")
        if isinstance(seed, (bool, np.bool_)):
            raise SpecTypeError(f"reset(seed=...) must be an integer or None, got {seed!r}")
        if options:
            raise SpecError(
                f"reset(options=...): TaskEnv takes no options, got {dict(options)}; task "
                "parameters go to the constructor (gymnasium.make(id, **parameters))"
            )
        super().reset(seed=seed)
        self._needs_reset = True  # until this reset completes (an initializer may raise)
        scene = self.scene
        if scene.model is not self._model:
            self._follow_rebuild()
        if self._randomizer is not None:
            self._randomizer.restore(scene.model)
        scene.reset()
        for eff in self._effectors:
            eff.new_episode(scene)
        if self.hardware is not None:  # the real arm goes home, the simulated one follows
            home = self._effectors[0].home
            self.hardware.move_to(self.hardware.robot.jnt_pos_msr if home is None else home)
        for init in self.task_spec.initializers:
            init(self, self.np_random)
        if self._randomizer is not None:  # after the placements: they stay those of the seed
            self._randomizer.reset(scene.model, self.np_random)
        mujoco.mj_forward(scene.model, scene.data)
        for eff in self._effectors:
            eff.robot.sync_commands()
            eff.start_state()
        if self.drive is not None:
            self.drive.latency = (
                0 if self._randomizer is None else self._randomizer.draw.action_latency_ticks
            )
            self.drive.start()
        mujoco.mj_forward(scene.model, scene.data)  # torques under the synced commands
        self._counters.fill(0.0)
        self._needs_reset = False
        self._diverged = None
        obs = self._observe()
        if self.render_mode == "human":
            self.render()
        return self._shown_part(obs), {"is_success": self._success(obs), "diverged": False}

    def step(
        self, action: np.ndarray
    ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        """Apply `action` for one control period; (obs, reward, terminated, truncated, info)."""
        self._check_open()
        if self._needs_reset:
            raise RuntimeError("TaskEnv.step() before reset(): call reset() to start an episode")
        if self._diverged is not None:
            raise RuntimeError(f"the simulation diverged ({self._diverged}); call reset()")
        a = self._checked_action(action)
        if self.scene.model is not self._model:
            self._follow_rebuild()
        if self._randomizer is not None:  # its queue is in the (rebound) userdata
            a = self._randomizer.action(a, int(self._counters[0]))
        for eff in self._effectors:
            eff.apply(a, self._period)
        why = self._advance()
        counters = self._counters
        counters[0] += 1
        if why is not None:
            self._diverged = why
            obs = {k: b.copy() for k, b in self._buffers if k in self._task_space.spaces}
            info = {"is_success": False, "diverged": True, "error": why}  # obs: the last finite
            return obs, 0.0, True, bool(counters[0] >= self._max_steps), info
        # Everything derived (poses, cameras, contacts, forces, sensordata) recomputed from the
        # state reached: each observation, image included, is of the state recorded with it.
        # MuJoCo's next mj_step recomputes the same from the same state (qacc_warmstart is
        # only written by the integrator), so the trajectory is unchanged.
        self.scene.forward()
        obs = self._observe()  # every observation: rewards may read hidden ones
        success = self._success(obs)
        counters[1] = counters[1] + 1 if success else 0
        return self._outcome(obs, success)

    def observe(self) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        """What `step` returned on reaching the state the scene holds now: (obs, reward,
        terminated, truncated, info). For a state set with `mujoco.mj_setState` (a recorded
        `mjSTATE_INTEGRATION` row, which holds the episode's step and success counters and
        the controllers' commands too): the observation, reward and ends recorded with it;
        `step` goes on from it as it did then."""
        self._check_open()
        if self._needs_reset:
            raise RuntimeError("TaskEnv.observe() before reset(): call reset() first")
        if self.scene.model is not self._model:
            self._follow_rebuild()
        self._diverged = None
        self.scene.forward()
        obs = self._observe()
        return self._outcome(obs, self._success(obs))

    def _outcome(
        self, obs: dict[str, np.ndarray], success: bool
    ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        """`step`'s result for `obs` of the state the counters are of: the one place rewards,
        ends and the success bonus are computed."""
        spec = self.task_spec
        steps, held = self._counters
        reward, terminated = 0.0, False
        if spec.reward is not None:
            reward = spec.reward(obs)
            if type(reward) is not float or not math.isfinite(reward):
                reward = real(reward, "TaskSpec.reward(obs)")
        if spec.terminated is not None:
            terminated = spec.terminated(obs)
            if type(terminated) is not bool:
                terminated = flag(terminated, "TaskSpec.terminated(obs)")
        if spec.terminate_on_success and held > self._hold_steps and not terminated:
            terminated = True
            reward = success_bonus(reward, int(steps), self._horizon())
        info = {"is_success": success, "diverged": False}
        return self._shown_part(obs), reward, terminated, bool(steps >= self._max_steps), info

    def _shown_part(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """What the agent gets of an observation: all but `TaskSpec.hide`, in order."""
        shown = obs if len(self._shown) == len(obs) else {k: obs[k] for k in self._shown}
        if self._randomizer is None:
            return shown
        return self._randomizer.observe(shown, int(self._counters[0]))

    def _success(self, obs: dict[str, np.ndarray]) -> bool:
        fn = self.task_spec.success
        if fn is None:
            return False
        value = fn(obs)
        return value if type(value) is bool else flag(value, "TaskSpec.success(obs)")

    def _horizon(self) -> float:
        """Control steps an episode lasts at most: `time_limit`'s, else the `TimeLimit` that
        Gymnasium registered for this env's id (a wrapper is invisible from inside, so a
        `max_episode_steps` given to `make` is not seen), else unbounded."""
        if math.isfinite(self._max_steps):
            return self._max_steps
        registered = gym.registry.get(self.spec.id) if self.spec is not None else None
        steps = getattr(registered, "max_episode_steps", None)
        return math.inf if steps is None else steps

    def _checked_action(self, action: object) -> np.ndarray:
        a: Any = action
        if type(a) is not np.ndarray or (a.dtype != np.float64 and a.dtype != np.float32):
            a = real_array(action, "action")
        shape = self.action_space.shape
        if a.shape != shape:
            layout = ", ".join(self.action_labels)
            raise SpecError(f"action must have shape {shape} ({layout}), got shape {a.shape}")
        if not math.isfinite(a.dot(a)) and not np.isfinite(a).all():
            bad = [f"{self.action_labels[i]}={a[i]}" for i in np.flatnonzero(~np.isfinite(a))]
            raise SpecError(f"action entries must be finite, got {', '.join(bad)}")
        out = self._action
        if self.task_spec.normalize_actions:
            np.clip(a, -1.0, 1.0, out=out)
            out *= self._action_half
            out += self._action_mid
            return out
        np.maximum(a, self._action_low, out=out)
        np.minimum(out, self._action_high, out=out)
        return out

    def _advance(self) -> str | None:
        """Run one control period of physics; why it diverged, or None."""
        scene = self.scene
        try:
            if self.drive is not None:  # ticks of its own (a viewer shows them unpaced)
                self.drive.run(self._substeps)
            elif self._stepper is None:
                scene.step(self._substeps)
            else:
                self._step_through(self._stepper)
        except SimulationError as err:  # Scene.step names MuJoCo's warning and the time
            return str(err)
        data = scene.data
        q, v = data.qpos, data.qvel
        if not (math.isfinite(q.dot(q)) and math.isfinite(v.dot(v))) and not (
            np.isfinite(q).all() and np.isfinite(v).all()
        ):
            return f"the state is not finite at t={data.time:.4f} s"
        return None

    def _step_through(self, stepper: Callable[[], bool]) -> None:
        """Physics steps through a viewer's `step` (paced, shown); headless once it closes."""
        for k in range(self._substeps):
            if not stepper():
                self._stepper = None
                self.scene.step(self._substeps - k)
                return

    def _observe(self) -> dict[str, np.ndarray]:
        for reader in self._readers:
            reader.read()
        self._time[0] = self.scene.data.time
        return {k: b.copy() for k, b in self._buffers}

    @property
    def control_timestep(self) -> float:
        """Seconds of simulation per `step` (a whole number of physics timesteps)."""
        return self._period

    @property
    def elapsed_steps(self) -> int:
        """Control steps since the last reset (of the state the scene holds)."""
        return int(self._counters[0])

    @property
    def control_substeps(self) -> int:
        """Physics steps per `step` (`control_timestep / scene.timestep()`)."""
        return self._substeps

    @property
    def time_limit_steps(self) -> int | None:
        """Control steps `TaskSpec.time_limit` allows an episode; None without a limit."""
        return None if math.isinf(self._max_steps) else int(self._max_steps)

    @property
    def success_hold_steps(self) -> int:
        """Control steps success must hold, after the first, before `terminate_on_success`
        ends the episode (`TaskSpec.success_hold` in steps)."""
        return self._hold_steps

    @property
    def action_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) of each action entry in physical units (m/s, rad/s, rad, N·m; the
        gripper's [0, 1]) before `normalize_actions` scales them onto [-1, 1] (copies)."""
        return self._action_low.copy(), self._action_high.copy()

    @property
    def effectors(self) -> list[ArmEffector]:
        """Per arm, in action order, what turns its slice of the action into commands."""
        return list(self._effectors)

    @property
    def readers(self) -> list[Reader]:
        """The observation sources: one `ArmReader` per arm, then one per `TaskSpec.sensors`
        entry, in order."""
        return list(self._readers)

    # ------------------------------------------------------------------ rendering

    def render(self) -> np.ndarray | None:
        """`rgb_array`/`depth_array`: an image of `render_camera` (the free camera when "");
        `human`: the interactive viewer, which then shows every physics step in real time."""
        self._check_open()
        if self.render_mode in ("rgb_array", "depth_array"):
            self.scene.refresh_poses()  # the user may have stepped the scene itself
            r = self._renderer(*self._render_size)
            flags = r.scene.flags  # shared with camera sensors of this size, which may differ
            flags[mujoco.mjtRndFlag.mjRND_SHADOW] = flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = (
                self._render_shadows
            )
            r.update_scene(self.scene.data, camera=self._render_camera)
            if self.render_mode == "rgb_array":
                return r.render()
            r.enable_depth_rendering()
            try:
                return r.render()
            finally:
                r.disable_depth_rendering()
        if self.render_mode == "human":
            if self._viewer is None:
                from ..viewer import SimulateViewer  # the viewer needs a display: open on use

                self._viewer = SimulateViewer.open(self.scene, "mjkdl task")
                if isinstance(self._render_camera, int):
                    self._viewer.use_camera(self.scene.model.camera(self._render_camera).name)
                self._stepper = self._viewer.step
            return None
        gym.logger.warn(
            "TaskEnv.render() without a render_mode does nothing; build the env with "
            'render_mode="rgb_array" or "human"'
        )
        return None

    # ------------------------------------------------------------------ lifecycle

    @property
    def closed(self) -> bool:
        """Whether `close()` was called."""
        return self._closed

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("this TaskEnv is closed")

    def close(self) -> None:
        """Release renderers, the viewer and the scene; later calls raise RuntimeError."""
        self._readers = []
        self._close_renderers()
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None
        self._stepper = None
        scene = getattr(self, "scene", None)
        if scene is not None:
            scene.close()
        self._closed = True


# Renderers inherited through a fork: their OpenGL contexts belong to the parent, and
# freeing them here can hang (software EGL) or fail, so they are kept until exit.
_ORPHANED: list[mujoco.Renderer] = []
_COUNTERS = 2  # userdata entries of the episode's own: control steps, steps of success
_SETTLE_STEPS = 500  # physics steps a gripper gets to open at reset (1 s at 2 ms)
_SETTLE_DAMPING = 0.1  # of the tool joints' own damping, while they settle at reset


def _check_one_arm(spec: TaskSpec, what: str) -> None:
    if len(spec.arms) != 1:
        raise SpecError(
            f"{what}; this task has {len(spec.arms)} "
            f"({', '.join(a.name for a in spec.arms)}): give a task with one arm"
        )


def _settle_tool(scene: Env, tip_body: str) -> None:
    """Let the joints below `tip_body` (the fingers) move to where their actuators hold
    them, everything else pinned in place, then restore the clock: the episode starts with
    the gripper as commanded instead of MuJoCo's `qpos0` (the Panda's fingers closed)."""
    model, data = scene.model, scene.data
    tip = model.body(tip_body).id
    below = [b for b in range(model.nbody) if _descends(model, b, tip) and b != tip]
    joints = [j for j in range(model.njnt) if model.jnt_bodyid[j] in below]
    if not joints:
        return
    free_q = np.zeros(model.nq, dtype=bool)
    free_v = np.zeros(model.nv, dtype=bool)
    for j in joints:
        n_q, n_v = _JOINT_SIZES[int(model.jnt_type[j])]
        free_q[model.jnt_qposadr[j] : model.jnt_qposadr[j] + n_q] = True
        free_v[model.jnt_dofadr[j] : model.jnt_dofadr[j] + n_v] = True
    pinned_q, pinned_v = ~free_q, ~free_v
    qpos, time = data.qpos.copy(), data.time
    # A GripperDrive sets the fingers' speed through their damping (the Franka Hand's 0.8 s
    # to open); placing them before the episode need not take the real hand's time.
    damping = model.dof_damping[free_v].copy()
    model.dof_damping[free_v] = damping * _SETTLE_DAMPING
    try:
        for k in range(_SETTLE_STEPS):
            mujoco.mj_step(model, data)
            data.qpos[pinned_q] = qpos[pinned_q]
            data.qvel[pinned_v] = 0.0
            if k > 10 and np.abs(data.qvel[free_v]).max() < 1e-4:
                break
    finally:
        model.dof_damping[free_v] = damping
    data.qvel[:] = 0.0
    data.qacc_warmstart[:] = 0.0
    data.time = time
    mujoco.mj_forward(model, data)


_JOINT_SIZES = {
    int(mujoco.mjtJoint.mjJNT_FREE): (7, 6),
    int(mujoco.mjtJoint.mjJNT_BALL): (4, 3),
    int(mujoco.mjtJoint.mjJNT_SLIDE): (1, 1),
    int(mujoco.mjtJoint.mjJNT_HINGE): (1, 1),
}


def _descends(model: mujoco.MjModel, body: int, ancestor: int) -> bool:
    while body > 0:
        if body == ancestor:
            return True
        body = int(model.body_parentid[body])
    return False


def _shown_keys(hide: object, every: Mapping[str, spaces.Space]) -> list[str]:
    """The observation keys left after `TaskSpec.hide`, which must name existing ones."""
    hidden = names(hide, "TaskSpec.hide", "observation")
    for i, key in enumerate(hidden):
        if key not in every:
            raise unknown_name("observation", key, every, where=f"TaskSpec.hide[{i}]")
    return [k for k in every if k not in hidden]


def _check_axes(arm: ArmSpec, where: str) -> None:
    """`cartesian_axes`: a tuple of distinct twist entries in `CARTESIAN_AXES` order, only
    with the Cartesian action."""
    axes = arm.cartesian_axes
    field = f"{where}.cartesian_axes"
    if not isinstance(axes, tuple) or not axes or not all(isinstance(a, str) for a in axes):
        raise SpecTypeError(
            f"{field} must be a non-empty tuple of {CARTESIAN_AXES} entries, got {axes!r}"
        )
    unknown = [a for a in axes if a not in CARTESIAN_AXES]
    if unknown:
        raise SpecError(f"{field}: unknown entries {unknown}; valid: {', '.join(CARTESIAN_AXES)}")
    order = [CARTESIAN_AXES.index(a) for a in axes]
    if order != sorted(set(order)):
        raise SpecError(
            f"{field} must list distinct entries in the order {CARTESIAN_AXES}, got {axes}"
        )
    if axes != CARTESIAN_AXES and arm.actuation is not Actuation.CARTESIAN_VELOCITY:
        raise SpecError(
            f"{field} chooses the Cartesian action's entries; this arm's actuation is "
            f"{arm.actuation.value!r} (use Actuation.CARTESIAN_VELOCITY or leave it unset)"
        )


def _controller(robot: Robot, arm: ArmSpec) -> CartesianVelocityController:
    """The arm's Cartesian controller, its null-space posture at `home` when there is one."""
    return CartesianVelocityController(robot, control_frame=arm.control_frame, posture=arm.home)


def _positive(value: object) -> bool:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        return False
    return math.isfinite(float(value)) and float(value) > 0


def _action_bounds(
    eff: ArmEffector, model: mujoco.MjModel
) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Bounds and entry names of one arm's slice of the action."""
    arm, robot = eff.arm, eff.robot
    if arm.actuation is Actuation.CARTESIAN_VELOCITY:
        lin, ang = arm.max_linear_velocity, arm.max_angular_velocity
        high = np.array([lin] * 3 + [ang] * 3, dtype=float)[eff.axes]
        low, names = -high, list(arm.cartesian_axes)
    else:
        joints = robot.joint_names
        if arm.actuation is Actuation.JOINT_POSITION:
            low, high = robot.joint_limits[:, 0].copy(), robot.joint_limits[:, 1].copy()
        elif arm.actuation is Actuation.JOINT_VELOCITY:
            # Pinocchio marks "no limit" with the largest double; the Box is float32.
            limit = np.asarray(robot.model.velocityLimit, dtype=float)[: robot.n_joints]
            usable = (limit > 0) & (limit < np.finfo(np.float32).max)
            high = np.where(usable, limit, arm.max_angular_velocity)
            low = -high
        else:
            high = _effort_limits(model, joints)
            low = -high
        names = list(joints)
    if eff.grip_index >= 0:
        low, high = np.append(low, 0.0), np.append(high, 1.0)
        names.append("gripper")
    return low, high, names


def _effort_limits(model: mujoco.MjModel, joints: list[str]) -> np.ndarray:
    """Per joint: its actuator force range (times gear), else the joint's own, else inf."""
    out = np.full(len(joints), np.inf)
    for i, name in enumerate(joints):
        j = model.joint(name).id
        if model.jnt_actfrclimited[j]:
            out[i] = np.abs(model.jnt_actfrcrange[j]).min()
        for a in range(model.nu):
            joint_trn = int(model.actuator_trntype[a]) == int(mujoco.mjtTrn.mjTRN_JOINT)
            if joint_trn and model.actuator_trnid[a, 0] == j and model.actuator_forcelimited[a]:
                frc = np.abs(model.actuator_forcerange[a]).min() * abs(model.actuator_gear[a, 0])
                out[i] = min(out[i], frc)
    return out
