"""Runtime owners: `Scene` compiles a `SceneSpec` and owns MuJoCo's model and data."""

from __future__ import annotations

import copy
import inspect
import os
import tempfile
from collections import defaultdict
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import mujoco
import numpy as np
import pinocchio as pin

from .closable import Closable
from .compile import compile_scene, vector
from .describe import describe, summary, tree_for
from .errors import (
    MjkdlError,
    SimulationError,
    SpecError,
    SpecTypeError,
    UnknownNameError,
    unknown_name,
)
from .names import COUNT_FIELD, find_id, model_id
from .spec import ResetContext, ResetOptions, SceneObject, SceneSpec, ToolFrameSpec
from .validate import flag, text

if TYPE_CHECKING:
    from typing_extensions import Self

    from .robot import Robot


class RobotHandle(Protocol):
    """What a Scene needs of the robot handles registered with it (`mjkdl.robot.Robot`)."""

    _pending: bool  # commands assigned since they were last written to MuJoCo

    def _apply(self) -> None: ...  # write the commands into MuJoCo's controls
    def _bind(self, model: mujoco.MjModel, data: mujoco.MjData) -> None: ...  # after a rebuild
    def _release(self, why: str = ...) -> None: ...  # the scene closes or drops the handle
    def sync_commands(self) -> None: ...
    def _after_reset(self) -> None: ...  # re-read what the model and the reset changed
    def _read_state(self) -> None: ...


class ArmLinkHandle(Protocol):
    """What a Scene needs of a link to a real arm (`mjkdl.hw.in_the_loop.ArmLink`)."""

    def step(self, n: int) -> None: ...  # n timesteps, the arm mirrored into the simulation
    def close(self) -> None: ...


# The Robot class registers itself here, so this module never imports the robot layer above it.
_robot_factory: Callable[..., RobotHandle] | None = None


def register_robot_factory(factory: Callable[..., RobotHandle]) -> None:
    """Set what `Scene.create_robot` builds (`mjkdl.robot` does, on import)."""
    global _robot_factory
    _robot_factory = factory


# The hardware-in-the-loop layer (mjkdl.hw.in_the_loop) registers how a robot is linked to a
# real arm, so this module never imports that layer above it.
_arm_linker: Callable[..., ArmLinkHandle] | None = None


def register_arm_linker(linker: Callable[..., ArmLinkHandle]) -> None:
    """Called by mjkdl.hw.in_the_loop: `linker(scene, robot, robot_ip)` links a robot to an arm."""
    global _arm_linker
    _arm_linker = linker


@dataclass(frozen=True)
class AuthoredActuators:
    """The actuator parameters as compiled, before any Robot turned them into its mode."""

    gaintype: np.ndarray
    biastype: np.ndarray
    gainprm: np.ndarray
    biasprm: np.ndarray
    ctrllimited: np.ndarray

    @classmethod
    def of(cls, model: mujoco.MjModel) -> AuthoredActuators:
        return cls(
            model.actuator_gaintype.copy(),
            model.actuator_biastype.copy(),
            model.actuator_gainprm.copy(),
            model.actuator_biasprm.copy(),
            model.actuator_ctrllimited.copy(),
        )

    def restore(self, model: mujoco.MjModel, ids: np.ndarray) -> None:
        """Give actuators `ids` of `model` their compiled parameters back."""
        model.actuator_gaintype[ids] = self.gaintype[ids]
        model.actuator_biastype[ids] = self.biastype[ids]
        model.actuator_gainprm[ids] = self.gainprm[ids]
        model.actuator_biasprm[ids] = self.biasprm[ids]
        model.actuator_ctrllimited[ids] = self.ctrllimited[ids]


def joint_sizes(jtype: int) -> tuple[int, int]:
    """(nq, nv) of a MuJoCo joint type."""
    return {int(mujoco.mjtJoint.mjJNT_FREE): (7, 6), int(mujoco.mjtJoint.mjJNT_BALL): (4, 3)}.get(
        int(jtype), (1, 1)
    )


def mujoco_version() -> str:
    """MuJoCo's version string."""
    return mujoco.__version__


# ----------------------------------------------------------------------------- MuJoCo's log

MUJOCO_LOG_ENV = "MJKDL_MUJOCO_LOG"


def mujoco_log_path() -> str:
    """Where MuJoCo's default handler appends its warnings (MuJoCo's MUJOCO_LOG.TXT).

    Importing mjkdl moves it out of the working directory: to ``$MJKDL_MUJOCO_LOG`` when set,
    else ``<tempdir>/mjkdl-<uid>/MUJOCO_LOG.TXT``. A file the user configured through
    `mujoco.MjLogConfig` before importing mjkdl is kept.
    """
    return str(mujoco.MjLogConfig.get().logfile)


def _route_mujoco_log() -> None:
    config = mujoco.MjLogConfig.get()
    if config.logfile != "MUJOCO_LOG.TXT":  # not MuJoCo's default: the user chose a file
        return
    user = f"-{os.getuid()}" if hasattr(os, "getuid") else ""
    default = os.path.join(tempfile.gettempdir(), f"mjkdl{user}", "MUJOCO_LOG.TXT")
    path = os.path.abspath(os.environ.get(MUJOCO_LOG_ENV) or default)
    try:
        os.makedirs(os.path.dirname(path), exist_ok=True)
    except OSError:  # nowhere to write: keep MuJoCo's console output only
        config.logto_file = False
    config.logfile = path
    config.set()


_route_mujoco_log()

# MuJoCo warnings that mean the simulation is no longer trustworthy (mjWARN_INERTIA, a
# compile-time notice, is not one). Checked after every step through a memoryview of
# mjData.warning[:].number: no Python object is created while all counts are zero.
_FAULTS = tuple(
    int(w)
    for w in (
        mujoco.mjtWarning.mjWARN_BADQPOS,  # causes first: a bad qpos or qvel makes a bad qacc
        mujoco.mjtWarning.mjWARN_BADQVEL,
        mujoco.mjtWarning.mjWARN_BADCTRL,
        mujoco.mjtWarning.mjWARN_BADQACC,
        mujoco.mjtWarning.mjWARN_CONTACTFULL,
        mujoco.mjtWarning.mjWARN_CNSTRFULL,
    )
)
if sorted(_FAULTS) != [1, 2, 3, 4, 5, 6]:  # `_fault_counters` slices them directly
    raise ImportError(f"mjkdl does not know this MuJoCo's warning numbering: {_FAULTS}")
_AUTORESET = int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
MAX_STEPS = 2**31 - 1  # mj_step's nstep is a C int
# Scene.step compares MuJoCo's fault counters (warning numbers 1-6) with zeros in one go.
_NO_FAULTS = np.zeros(len(_FAULTS), dtype=np.int32).data


def _fault_counters(data: mujoco.MjData) -> memoryview:
    """A live view of `data.warning[1:7].number`: the counts of the `_FAULTS` warnings."""
    return data.warning.number.data[1:]


def refresh_poses(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """Poses of bodies, geoms, sites, cameras and lights from the current `qpos`.

    `mj_step` computes every derived quantity from the state it starts with and then
    integrates, so after it poses lag the joints by one timestep, and a camera on a moving
    body (a wrist camera: `mj_camlight`) renders the arm where it was. A fifth of an
    `mj_forward`'s cost on a Panda scene.
    """
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    mujoco.mj_camlight(model, data)


def _compiled_options(model: mujoco.MjModel) -> mujoco.MjOption:
    """Switch MuJoCo's auto-reset off (see `Scene.auto_reset`); a copy of the options as
    compiled, against which `_transfer_model` finds the user's run-time edits."""
    model.opt.disableflags |= _AUTORESET
    return copy.copy(model.opt)


class Scene(Closable):
    """A compiled scene: MuJoCo's `MjModel`/`MjData` plus name-based helpers."""

    def __init__(self, spec: SceneSpec, model: mujoco.MjModel) -> None:
        self._spec = spec
        self._model: mujoco.MjModel | None = model
        self._data: mujoco.MjData | None = mujoco.MjData(model)
        self._robots: list[RobotHandle] = []
        self._link: ArmLinkHandle | None = None  # a real arm mirrored in (robot_ip)
        self._authored_actuators = AuthoredActuators.of(model)
        self._compiled_opt = _compiled_options(model)
        self._faults = _fault_counters(self._data)
        mujoco.mj_forward(model, self._data)
        self._poses_stale = False  # whether `step` left the poses behind the state

    @classmethod
    def build(cls, spec: SceneSpec) -> Self:
        """Compile `spec` (a private copy of it is kept) and return the scene."""
        if not isinstance(spec, SceneSpec):
            raise SpecError(f"build() takes a SceneSpec, got {type(spec).__name__}")
        own = copy.deepcopy(spec)
        return cls(own, compile_scene(own))

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
        if self._link is not None:  # bring a linked arm to rest first
            self._link.close()
            self._link = None
        for robot in self._robots:
            robot._release()
        self._model = None
        self._data = None
        self._faults = _NO_FAULTS  # no view into freed memory
        self._robots = []

    def _check_open(self) -> None:  # the same check as Closable's, without a property call
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
        """Advance the simulation `n` timesteps, applying robots' pending commands first.

        As after MuJoCo's `mj_step`, `data`'s derived quantities (poses, contacts, forces,
        `sensordata`) are those of the last timestep's start: `refresh_poses()` brings the
        poses up to the new state (mjkdl's renderers, recorder, viewer, `body_frame` and
        `site_frame` call it), `forward()` everything.
        """
        # The closed check and the fault check are inlined: this runs once per control step.
        if self._model is None:
            self._check_open()
        for robot in self._robots:
            if robot._pending:
                robot._apply()
        # A plain int passes after two cheap tests; bool and float (1.0) are refused.
        if (n.__class__ is not int and not isinstance(n, np.integer)) or n < 0:
            raise SpecError(f"step(n): n must be a non-negative integer, got {n!r}")
        try:
            if self._link is not None:
                self._link.step(n)
            elif n > MAX_STEPS:  # the binding takes a C int
                raise SpecError(
                    f"step(n): n must be at most {MAX_STEPS} (MuJoCo counts steps in a C int), "
                    f"got {n!r}; step in several calls"
                )
            else:
                mujoco.mj_step(self._model, self._data, n)
        except mujoco.FatalError as err:
            raise self._fatal(err) from None
        self._poses_stale = True
        if self._faults != _NO_FAULTS:
            self._raise_faults()

    @property
    def auto_reset(self) -> bool:
        """Whether MuJoCo silently resets a diverging simulation (its own default behaviour).

        False (mjkdl's default): MuJoCo's auto-reset is disabled (``mjDSBL_AUTORESET``), the
        diverged state is kept for inspection and `step()` raises `SimulationError`. True:
        MuJoCo resets the data to the model defaults and carries on; `step()` does not raise
        and `data.warning` counts what happened. Stored in ``model.opt.disableflags``.
        """
        return not self.model.opt.disableflags & _AUTORESET

    @auto_reset.setter
    def auto_reset(self, value: bool) -> None:
        if not isinstance(value, (bool, np.bool_)):
            raise SpecError(f"auto_reset must be True or False, got {value!r}")
        if value:
            self.model.opt.disableflags &= ~_AUTORESET
        else:
            self.model.opt.disableflags |= _AUTORESET

    def _fatal(self, err: mujoco.FatalError) -> SimulationError:
        """MuJoCo's own fatal error inside a step (its memory arena overflowed)."""
        t = float(self.data.time)
        first = str(err).strip().splitlines()[0] if str(err).strip() else "fatal error"
        return SimulationError(
            f"MuJoCo stopped the simulation at t = {t:.6g} s: {first}. The data is left "
            "half-computed; Env.reset() starts over (a model's <size memory=...> sets the arena)",
            t,
            {},
        )

    def _raise_faults(self) -> None:
        model, data = self.model, self.data
        if not model.opt.disableflags & _AUTORESET:  # the user chose MuJoCo's silent reset
            return
        found: dict[str, tuple[int, int]] = {}
        text: list[str] = []
        for w in _FAULTS:
            stat = data.warning[w]
            if stat.number:
                name = mujoco.mjtWarning(w).name
                found[name] = (int(stat.number), int(stat.lastinfo))
                text.append(f"{mujoco.mju_warningText(w, stat.lastinfo)} ({name} x{stat.number})")
                stat.number = 0  # reported: a later step raises again if it persists
        raise SimulationError(
            f"the simulation failed by t = {data.time:.6g} s: {'; '.join(text)}. The state is "
            "kept as it was for inspection; Env.reset() starts over (set scene.auto_reset = "
            "True for MuJoCo's silent reset instead).",
            float(data.time),
            found,
        )

    def forward(self) -> None:
        """Recompute derived quantities (poses, forces) from the current state."""
        self._check_open()
        mujoco.mj_forward(self._model, self._data)
        self._poses_stale = False

    def refresh_poses(self) -> None:
        """Poses of bodies, geoms, sites, cameras and lights of the current state, when a
        `step` left them one timestep behind (a wrist camera would render the arm where it
        was); nothing to do otherwise. A fifth of a Panda `mj_step`, paid only when read."""
        self._check_open()
        if self._poses_stale:
            refresh_poses(self._model, self._data)
            self._poses_stale = False

    # ------------------------------------------------------------------ names

    def _id(self, obj: mujoco.mjtObj, kind: str, name: str) -> int:
        return model_id(self.model, obj, kind, name, "the scene")

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
        text(name, "has_actuator(name)")
        return find_id(self.model, mujoco.mjtObj.mjOBJ_ACTUATOR, name) >= 0

    def set_actuator_ctrl(self, name: str, value: float) -> None:
        """Set the control input of actuator `name` (clamped by MuJoCo to its ctrlrange)."""
        i = self.actuator_id(name)
        try:
            v = float(value)
        except (TypeError, ValueError):
            v = float("nan")
        if not np.isfinite(v):
            raise SpecError(
                f"set_actuator_ctrl({name!r}): value must be a finite number, got {value!r}"
            )
        self.data.ctrl[i] = v

    # ------------------------------------------------------------------ poses

    def body_frame(self, name: str) -> pin.SE3:
        """World pose of body `name` as of the last forward computation or `step`."""
        i = self.body_id(name)
        self.refresh_poses()
        data = self.data
        return pin.SE3(data.xmat[i].reshape(3, 3).copy(), data.xpos[i].copy())

    def site_frame(self, name: str) -> pin.SE3:
        """World pose of site `name` as of the last forward computation or `step`."""
        i = self.site_id(name)
        self.refresh_poses()
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
        robot_ip: str | None = None,
    ) -> Robot:
        """A `Robot` handle on the chain from `base_body` to `tip_body` (names without prefix).

        With `robot_ip`, the chain mirrors the real arm at that address and commands it
        (hardware in the loop, `mjkdl.hw.in_the_loop`; needs the `[franka]` extra)."""
        self._check_open()
        if _robot_factory is None:
            raise RuntimeError("import mjkdl (or mjkdl.robot) to create robots")
        try:
            robot = _robot_factory(self, base_body, tip_body, prefix=prefix, tool=tool)
        except UnknownNameError as err:  # show the names there are, as a tree
            tree = tree_for(self._model, self._spec, prefix)
            raise UnknownNameError(f"{err}\nthe names there are:\n{tree}") from None
        self._robots.append(robot)
        if robot_ip is not None:
            if _arm_linker is None:
                raise RuntimeError("import mjkdl (or mjkdl.hw.in_the_loop) to link real arms")
            try:
                _arm_linker(self, robot, robot_ip)
            except BaseException:
                robot.close()  # type: ignore[attr-defined]
                raise
        return robot  # type: ignore[return-value]

    def remove_robot(self, robot: Robot) -> None:
        """Release `robot` (as `robot.close()`): another handle may then drive its joints."""
        self._check_open()
        if not any(r is robot for r in self._robots):
            raise SpecError("remove_robot: this Robot is not registered with this scene")
        robot.close()

    def _unregister(self, robot: RobotHandle) -> None:
        self._robots = [r for r in self._robots if r is not robot]

    # ------------------------------------------------------------------ description

    def describe(self) -> str:
        """The kinematic tree with body, joint, site, actuator and camera names, and a
        suggested `create_robot(...)` call per robot (see `mjkdl.describe`)."""
        return describe(self.model, self._spec)

    def __str__(self) -> str:
        """Counts, objects and one suggested `create_robot(...)` call per robot."""
        if self._model is None:
            return f"{type(self).__name__} (closed)"
        return summary(self._model, self._spec)

    # ------------------------------------------------------------------ rebuild

    def add_object(self, obj: SceneObject) -> None:
        """Add `obj` and recompile; all surviving state and Robot handles carry over."""
        self._check_open()
        if not isinstance(obj, SceneObject):
            raise SpecError(f"add_object() takes a SceneObject, got {type(obj).__name__}")
        spec = copy.deepcopy(self._spec)
        spec.objects.append(copy.deepcopy(obj))
        self._rebuild(spec)

    def remove_object(self, name: str) -> None:
        """Remove the object called `name` and recompile, keeping all surviving state."""
        self._check_open()
        names = [o.name for o in self._spec.objects]
        if text(name, "remove_object(name)") not in names:
            raise unknown_name("object", name, names, where="the scene spec")
        spec = copy.deepcopy(self._spec)
        spec.objects = [o for o in spec.objects if o.name != name]
        self._rebuild(spec)

    def _rebuild(self, spec: SceneSpec) -> None:
        """Compile `spec`, carry the state over by name, rebind robots; on error keep all."""
        model = compile_scene(spec)
        data = mujoco.MjData(model)
        authored = AuthoredActuators.of(model)
        compiled_opt = _compiled_options(model)
        _transfer_model(self._model, self._compiled_opt, model)
        _transfer_state(self._model, self._data, model, data)
        mujoco.mj_forward(model, data)
        old = (self._spec, self._model, self._data, self._authored_actuators, self._compiled_opt)
        self._spec, self._model, self._data = spec, model, data
        self._authored_actuators, self._compiled_opt = authored, compiled_opt
        self._faults = _fault_counters(data)
        try:
            for robot in self._robots:
                robot._bind(model, data)
        except Exception:
            # A handle that cannot live on the new model (its chain was removed): put every
            # handle and the scene back on the previous model, which they were bound to.
            self._spec, self._model, self._data, self._authored_actuators, self._compiled_opt = old
            self._faults = _fault_counters(self.data)
            for robot in self._robots:
                robot._bind(self._model, self._data)
            raise


@dataclass(frozen=True)
class ResetInfo:
    """What `Env.reset` did: the time it left and the keyframe it used (None: defaults)."""

    time: float
    keyframe: int | None
    keyframe_name: str | None


class ResetHookError(MjkdlError, RuntimeError):
    """The user's `on_reset` hook raised; the original exception is the `__cause__`."""


class Env(Scene):
    """A Scene with a reset hook; its robots stay in sync across resets and rebuilds."""

    def __init__(self, spec: SceneSpec, model: mujoco.MjModel) -> None:
        super().__init__(spec, model)
        self._on_reset: Callable[[ResetContext], None] | None = None

    @property
    def on_reset(self) -> Callable[[ResetContext], None] | None:
        """Called by `reset()` with a `ResetContext`, after MuJoCo's reset and before the
        robots sync (place objects, randomise); None for no hook."""
        return self._on_reset

    @on_reset.setter
    def on_reset(self, hook: Callable[[ResetContext], None] | None) -> None:
        if hook is not None and not callable(hook):
            raise SpecTypeError(
                f"on_reset must be a function of a ResetContext, or None; got {hook!r}"
            )
        self._on_reset = hook

    def keyframe_id(self, key: int | str) -> int:
        """Index of keyframe `key` (an index or a name)."""
        model = self.model
        names = [model.key(k).name or f"#{k}" for k in range(model.nkey)]
        if isinstance(key, str):
            return self._id(mujoco.mjtObj.mjOBJ_KEY, "keyframe", key)
        if not isinstance(key, (int, np.integer)) or isinstance(key, bool):
            raise SpecTypeError(f"keyframe must be an index or a name, got {key!r}")
        if 0 <= key < model.nkey:
            return int(key)
        raise unknown_name("keyframe", str(key), names, where=f"the scene ({model.nkey} keyframes)")

    def reset(self, opts: ResetOptions | None = None) -> ResetInfo:
        """Reset MuJoCo (to a keyframe if asked), run `on_reset`, forward, sync robots.

        Keyframe resets restore qpos, qvel, act, ctrl, mocap poses and time. After the hook
        every registered robot's command ports are set to its measured state and applied,
        so the first step after a reset carries no stale command.
        """
        self._check_open()
        opts = ResetOptions() if opts is None else opts
        if not isinstance(opts, ResetOptions):
            raise SpecError(f"reset() takes ResetOptions, got {type(opts).__name__}")
        model, data = self.model, self.data
        use = flag(opts.use_keyframe, "ResetOptions.use_keyframe")
        key = self.keyframe_id(opts.keyframe) if use else None
        if key is None:
            mujoco.mj_resetData(model, data)
        else:
            mujoco.mj_resetDataKeyframe(model, data, key)
        try:
            if self.on_reset is not None:
                self._run_hook(opts)
        finally:
            mujoco.mj_forward(self.model, self.data)  # a hook may have rebuilt the scene
            self._poses_stale = False
            for robot in self._robots:
                robot._after_reset()  # the model's parameters may have been edited
                robot.sync_commands()
            if self._robots:  # measured torques under the synced commands
                mujoco.mj_forward(self.model, self.data)
                for robot in self._robots:
                    robot._read_state()
        name = model.key(key).name if key is not None else None
        return ResetInfo(float(self.data.time), key, name or None)

    def _run_hook(self, opts: ResetOptions) -> None:
        hook = self.on_reset
        assert hook is not None
        try:
            hook(ResetContext(self, self._model, self._data, opts))
        except Exception as err:
            where = getattr(hook, "__qualname__", repr(hook))
            module = inspect.getmodule(hook)
            origin = f"{module.__name__}.{where}" if module else where
            raise ResetHookError(f"reset hook {origin} raised {type(err).__name__}: {err}") from err

    def close(self) -> None:
        """Release MuJoCo's model and data and drop the reset hook."""
        self.on_reset = None
        super().close()


def _transfer_state(
    old_m: mujoco.MjModel, old_d: mujoco.MjData, new_m: mujoco.MjModel, new_d: mujoco.MjData
) -> None:
    """Copy state from an old model's data into a new one, element by element (by name;
    unnamed elements by their place, see `_element_keys`)."""
    new_d.time = old_d.time
    for j, k in _pairs(old_m, new_m, mujoco.mjtObj.mjOBJ_JOINT):
        if old_m.jnt_type[k] != new_m.jnt_type[j]:
            continue
        nq, nv = joint_sizes(int(new_m.jnt_type[j]))
        qa, qb = new_m.jnt_qposadr[j], old_m.jnt_qposadr[k]
        va, vb = new_m.jnt_dofadr[j], old_m.jnt_dofadr[k]
        new_d.qpos[qa : qa + nq] = old_d.qpos[qb : qb + nq]
        for field in ("qvel", "qacc_warmstart", "qfrc_applied"):
            getattr(new_d, field)[va : va + nv] = getattr(old_d, field)[vb : vb + nv]
    for a, k in _pairs(old_m, new_m, mujoco.mjtObj.mjOBJ_ACTUATOR):
        new_d.ctrl[a] = old_d.ctrl[k]
        n = min(new_m.actuator_actnum[a], old_m.actuator_actnum[k])
        if n:
            a0, k0 = new_m.actuator_actadr[a], old_m.actuator_actadr[k]
            new_d.act[a0 : a0 + n] = old_d.act[k0 : k0 + n]
    for b, k in _pairs(old_m, new_m, mujoco.mjtObj.mjOBJ_BODY):
        new_d.xfrc_applied[b] = old_d.xfrc_applied[k]
        mocap, old_mocap = new_m.body_mocapid[b], old_m.body_mocapid[k]
        if mocap >= 0 and old_mocap >= 0:
            new_d.mocap_pos[mocap] = old_d.mocap_pos[old_mocap]
            new_d.mocap_quat[mocap] = old_d.mocap_quat[old_mocap]
    for e, k in _pairs(old_m, new_m, mujoco.mjtObj.mjOBJ_EQUALITY):
        new_d.eq_active[e] = old_d.eq_active[k]
    n = min(old_m.nuserdata, new_m.nuserdata)
    new_d.userdata[:n] = old_d.userdata[:n]


# Model fields a user may edit at run time, carried over by element (see `_transfer_model`).
_MODEL_FIELDS = {
    mujoco.mjtObj.mjOBJ_BODY: (
        "body_pos",
        "body_quat",
        "body_ipos",
        "body_iquat",
        "body_mass",
        "body_inertia",
        "body_gravcomp",
    ),
    mujoco.mjtObj.mjOBJ_JOINT: (
        "jnt_range",
        "jnt_stiffness",
        "jnt_margin",
        "jnt_solref",
        "jnt_solimp",
    ),
    mujoco.mjtObj.mjOBJ_GEOM: (
        "geom_pos",
        "geom_quat",
        "geom_rgba",
        "geom_friction",
        "geom_solref",
        "geom_solimp",
        "geom_solmix",
        "geom_margin",
        "geom_gap",
        "geom_condim",
        "geom_contype",
        "geom_conaffinity",
        "geom_priority",
    ),
    mujoco.mjtObj.mjOBJ_SITE: ("site_pos", "site_quat", "site_rgba"),
    mujoco.mjtObj.mjOBJ_CAMERA: ("cam_pos", "cam_quat", "cam_fovy"),
    mujoco.mjtObj.mjOBJ_LIGHT: ("light_pos", "light_dir", "light_active"),
    mujoco.mjtObj.mjOBJ_EQUALITY: ("eq_data", "eq_solref", "eq_solimp", "eq_active0"),
}
_DOF_FIELDS = ("dof_damping", "dof_armature", "dof_frictionloss")
_OPTION_FIELDS = tuple(
    name
    for name in dir(mujoco.MjOption)
    if not name.startswith("_") and isinstance(getattr(mujoco.MjOption, name), property)
)
# The body an element hangs on, to key an unnamed one by its place in that body.
_PARENT_FIELD = {
    mujoco.mjtObj.mjOBJ_BODY: "body_parentid",
    mujoco.mjtObj.mjOBJ_JOINT: "jnt_bodyid",
    mujoco.mjtObj.mjOBJ_GEOM: "geom_bodyid",
    mujoco.mjtObj.mjOBJ_SITE: "site_bodyid",
    mujoco.mjtObj.mjOBJ_CAMERA: "cam_bodyid",
    mujoco.mjtObj.mjOBJ_LIGHT: "light_bodyid",
}
# What an actuator's transmission (mjtTrn) acts on.
_TRANSMISSION_TARGET = {
    mujoco.mjtTrn.mjTRN_JOINT: mujoco.mjtObj.mjOBJ_JOINT,
    mujoco.mjtTrn.mjTRN_JOINTINPARENT: mujoco.mjtObj.mjOBJ_JOINT,
    mujoco.mjtTrn.mjTRN_SLIDERCRANK: mujoco.mjtObj.mjOBJ_SITE,
    mujoco.mjtTrn.mjTRN_TENDON: mujoco.mjtObj.mjOBJ_TENDON,
    mujoco.mjtTrn.mjTRN_SITE: mujoco.mjtObj.mjOBJ_SITE,
    mujoco.mjtTrn.mjTRN_BODY: mujoco.mjtObj.mjOBJ_BODY,
}

# What an equality ties when MuJoCo's eq_objtype does not say (connect and weld set it).
_EQUALITY_TIES = {
    mujoco.mjtEq.mjEQ_JOINT: mujoco.mjtObj.mjOBJ_JOINT,
    mujoco.mjtEq.mjEQ_TENDON: mujoco.mjtObj.mjOBJ_TENDON,
    mujoco.mjtEq.mjEQ_FLEX: mujoco.mjtObj.mjOBJ_FLEX,
    mujoco.mjtEq.mjEQ_FLEXVERT: mujoco.mjtObj.mjOBJ_FLEX,
    mujoco.mjtEq.mjEQ_FLEXSTRAIN: mujoco.mjtObj.mjOBJ_FLEX,
}


def _transfer_model(
    old_m: mujoco.MjModel, compiled_opt: mujoco.MjOption, new_m: mujoco.MjModel
) -> None:
    """Carry run-time edits of the old model into the new one, element by element.

    Copies `_MODEL_FIELDS` and `_DOF_FIELDS` of every element that survives (matched by name;
    unnamed ones by their place, see `_keys`), and every `opt` field that differs from
    what the old model was compiled with. Actuator parameters are the Robot handles' to set.
    """
    for obj, fields in _MODEL_FIELDS.items():
        pairs = _pairs(old_m, new_m, obj)
        if not pairs:
            continue
        new_ids = np.array([i for i, _ in pairs])
        old_ids = np.array([k for _, k in pairs])
        for field in fields:
            getattr(new_m, field)[new_ids] = getattr(old_m, field)[old_ids]
        if obj == mujoco.mjtObj.mjOBJ_JOINT:
            for j, k in pairs:
                nv = joint_sizes(int(new_m.jnt_type[j]))[1]
                va, vb = new_m.jnt_dofadr[j], old_m.jnt_dofadr[k]
                for field in _DOF_FIELDS:
                    getattr(new_m, field)[va : va + nv] = getattr(old_m, field)[vb : vb + nv]
    if old_m.opt == compiled_opt:  # MjOption compares its contents
        return
    for name in _OPTION_FIELDS:
        value = getattr(old_m.opt, name)
        if not np.array_equal(value, getattr(compiled_opt, name)):
            setattr(new_m.opt, name, value)


def _pairs(
    old_m: mujoco.MjModel, new_m: mujoco.MjModel, obj: mujoco.mjtObj
) -> list[tuple[int, int]]:
    """(new id, old id) of every element of kind `obj` that survives a recompile."""
    old = _element_keys(old_m, obj)
    return [(i, old[key]) for key, i in _element_keys(new_m, obj).items() if key in old]


def _element_keys(m: mujoco.MjModel, obj: mujoco.mjtObj) -> dict[Hashable, int]:
    """Element id by a key that survives recompiling; see `_keys`."""
    return {key: i for i, key in enumerate(_keys(m, obj, {}))}


def _keys(
    m: mujoco.MjModel, obj: mujoco.mjtObj, done: dict[mujoco.mjtObj, list[Hashable]]
) -> list[Hashable]:
    """A key per element that survives recompiling: its name; for an unnamed one, what it hangs
    on (its body's key; an actuator's target; an equality's type and the two elements it ties)
    and its rank among the unnamed elements hanging there. Counting unnamed ones only keeps the
    rank when named elements (an added object) come in before it. `done`: keys already made."""
    if obj in done:
        return done[obj]
    keys: list[Hashable] = []
    done[obj] = keys  # bodies key their children while the list grows (parents come first)
    rank: defaultdict[Hashable, int] = defaultdict(int)
    parent_field = _PARENT_FIELD.get(obj)
    for i in range(getattr(m, COUNT_FIELD[obj])):
        name = mujoco.mj_id2name(m, obj, i)
        if name:
            keys.append(name)
            continue
        anchor: Hashable = None
        if parent_field is not None:
            bodies = _keys(m, mujoco.mjtObj.mjOBJ_BODY, done)
            anchor = bodies[int(getattr(m, parent_field)[i])]
        elif obj == mujoco.mjtObj.mjOBJ_ACTUATOR:
            trn = int(m.actuator_trntype[i])
            target = _TRANSMISSION_TARGET.get(mujoco.mjtTrn(trn))
            if target is not None:
                anchor = (trn, _keys(m, target, done)[int(m.actuator_trnid[i, 0])])
        elif obj == mujoco.mjtObj.mjOBJ_EQUALITY:
            kind = mujoco.mjtObj(int(m.eq_objtype[i]))
            if kind == mujoco.mjtObj.mjOBJ_UNKNOWN:  # unset for joint, tendon, flex equalities
                kind = _EQUALITY_TIES[mujoco.mjtEq(int(m.eq_type[i]))]
            tied = _keys(m, kind, done)
            ends = (int(m.eq_obj1id[i]), int(m.eq_obj2id[i]))  # -1: none (a single joint's)
            anchor = (int(m.eq_type[i]), *(tied[e] if e >= 0 else e for e in ends))
        keys.append((anchor, rank[anchor]))
        rank[anchor] += 1
    return keys
