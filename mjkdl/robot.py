"""The Robot handle: joint ports, control modes and Pinocchio kinematics/dynamics."""

from __future__ import annotations

import copy
import math
import os
import sys
import warnings
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from types import FrameType

import mujoco
import numpy as np
import pinocchio as pin

from .chain import Chain
from .compile import euler_quat, vector
from .errors import SpecError, unknown_name
from .ik import IKResult, IKSolver
from .names import model_id
from .scene import AuthoredActuators, Scene, register_robot_factory
from .spec import CtrlMode, ForceTorqueSensorSpec, SceneSpec, ToolFrameSpec
from .validate import check_tool, flag, real, real_array

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
# Default servo bandwidth for joints whose actuators are plain motors (URDF robots).
_SERVO_HZ = 10.0
# MuJoCo zeroes (with a warning) any control above this magnitude (mjMAXVAL).
_MAX_CTRL = 1e10
_FLOAT_MAX = sys.float_info.max
_F64 = np.dtype(np.float64)
_gravity = pin.computeGeneralizedGravity
_hypot = math.hypot
# The per-step ufuncs, called with a positional output (faster than out=).
_add, _mul = np.add, np.multiply
# The command port each control mode applies; the others it ignores.
_MODE_PORT = {
    CtrlMode.POSITION: "jnt_pos_cmd",
    CtrlMode.VELOCITY: "jnt_vel_cmd",
    CtrlMode.TORQUE: "jnt_trq_cmd",
}
_PORT_MODE = {port: mode for mode, port in _MODE_PORT.items()}
_PACKAGE = str(Path(__file__).resolve().parent) + os.sep  # frames inside mjkdl


@dataclass
class _Actuation:
    """How one chain joint is driven: its actuator and the gains each mode uses."""

    actuator: int
    gear: float
    kp: float
    kv: float


class _Command:
    """A command port of a Robot: reads as a read-only view, assignment is checked and copied.

    A descriptor rather than a property so the per-step assignment of a float64 array is
    one Python call: its checks (type, length, finite and within MuJoCo's control range) are
    inlined here, anything else goes through `Robot._assign`.
    """

    def __init__(self, doc: str) -> None:
        self.__doc__ = doc

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name  # jnt_trq_cmd
        self.attr = "_" + name[4:]  # _trq_cmd

    def __get__(self, robot: Robot | None, owner: type | None = None) -> np.ndarray:
        if robot is None:
            return self  # type: ignore[return-value]  # the descriptor itself, for help()
        robot._check_open()
        return robot._ro[self.attr]

    def __set__(self, robot: Robot, value: object) -> None:
        port = robot.__dict__[self.attr]
        # |v| <= bound holds when every entry is within the bound; NaN compares false and inf
        # wins over NaN in hypot. On Python floats hypot costs half of a NumPy dot.
        if (
            type(value) is np.ndarray
            and value.dtype is _F64
            and value.shape == robot._shape
            and robot._active  # an active handle is open
            and _hypot(*value.tolist()) <= _MAX_CTRL
        ):
            port[...] = value
            fast = robot._fast
            if not fast or port is not robot._driven:
                robot._pending = True
                if port is not robot._acting and self.name not in robot._warned:
                    robot._stray_write(self.name)
            # On update()'s fast paths the port the mode drives goes to MuJoCo at once, with
            # what the last update() added to it (_apply would do the same at step()).
            elif fast == 1:
                robot._ctrl[...] = value
            elif fast == 2:
                _add(value, robot._g_arm, robot._ctrl)
            elif robot._gravity_ff:
                _add(value, robot._ff, robot._ctrl)
            else:
                robot._ctrl[...] = value
        else:
            robot._assign(port, value, self.name)


class IgnoredCommandWarning(UserWarning):
    """A command port was written that the robot's control mode does not apply."""


class Robot:
    """A controllable serial chain of a `Scene`, modelled in Pinocchio.

    Ports are NumPy arrays in chain order (base to tip). Measured ports are read-only arrays
    that `update()` refreshes in place; copy them to keep a snapshot. Commands are assigned as a
    whole (`robot.jnt_trq_cmd = tau`) and checked for length, finiteness and magnitude (at most
    1e10, beyond which MuJoCo would zero the control); they reach MuJoCo by the next `step()`.
    Only the mode's port acts (`jnt_pos_cmd` in POSITION, `jnt_vel_cmd` in VELOCITY,
    `jnt_trq_cmd` in TORQUE): a step that follows a write to another port warns once per robot
    and port (`IgnoredCommandWarning`). Measured ports change only on `update()`:
    `last_update_time` is the simulation time they were read at.

    `model` is one Pinocchio model of everything that moves the arm: the joints from the world
    to the base (a turning torso, a free or mocap base), the arm, and the tool and branches
    below the base with their own joints (fingers), all read from MuJoCo's qpos/qvel on every
    `update()`. The arm's entries of its q and v are `arm_q`/`arm_v`. Every quantity the handle
    returns is the arm's rows/columns of the whole model's, at the measured state of all joints
    (explicit `q`/`v` arguments replace the arm's entries only). Gravity leaves out the share
    MuJoCo's `gravcomp` already cancels, so it is not compensated twice.

    Control modes reconfigure the chain's own MuJoCo actuators (gain/bias parameters):
    TORQUE turns them into motors (force limited by the actuator's `forcerange`), POSITION
    into position servos and VELOCITY into velocity servos. Servo gains are the actuator's own
    when it is a MuJoCo position servo; for motor actuators (URDF robots) a critically damped
    servo of about 10 Hz is synthesised from the mass matrix. POSITION and VELOCITY add
    Pinocchio's gravity torques as feed-forward (`gravity_feedforward`), so a held pose does
    not sag under gravity; in TORQUE mode `gravity_compensation = True` adds them to the torque
    command. The servos ignore the actuators' authored `ctrlrange` (commands are in joint units
    in every mode); `forcerange` still limits the force.

    A handle starts driving its actuators once it is used for control — `update()`, a command
    assignment or a `ctrl_mode` change; until then it only reads, so several handles may look
    at the same joints, but only one may drive them. `close()` (or `Env.remove_robot`) releases
    a handle and gives its actuators back as authored.
    """

    def __init__(
        self,
        scene: Scene,
        base_body: str,
        tip_body: str,
        prefix: str = "",
        tool: ToolFrameSpec | None = None,
    ) -> None:
        for field, value in (("base_body", base_body), ("tip_body", tip_body), ("prefix", prefix)):
            if not isinstance(value, str):
                raise SpecError(f"create_robot: {field} must be a string, got {value!r}")
        if tool is not None:
            check_tool(tool)
        self._scene = scene
        self._open = True
        self._closed_why = ""
        self._prefix = prefix
        self._base_name = prefix + base_body
        self._tip_name = prefix + tip_body
        self._tool = copy.deepcopy(tool) if tool is not None else ToolFrameSpec()
        self._tcp_offset = _tcp_offset(self._tool)
        self._mode = CtrlMode.POSITION
        self._applied_mode: CtrlMode | None = None
        self._active = False
        self._gravcomp = False
        self._fast = 0  # which fast path update() takes, see _choose_path
        self._driven: np.ndarray | None = None  # the command port that path writes through
        self._gravity_ff = True
        self._stamp = 0.0  # data.time when the measured ports were last read
        self._stray: set[str] = set()  # ports written since the last apply that may be ignored
        self._warned: set[str] = set()  # ports already warned about (once per robot and port)
        self._bind(scene.model, scene.data)
        self._hold_commands()
        self._pending = False

    # ------------------------------------------------------------------ binding

    def _bind(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """(Re)build everything that depends on the compiled model and its data."""
        tcp = self._prefixed(self._tool.tcp_site)
        chain = Chain(model, self._base_name, self._tip_name, tcp, self._tcp_offset)
        self._check_tool_body(model, chain)
        self._ft = {s.name: self._ft_ids(model, s) for s in self._tool.ft_sensors}
        chain.set_velocity_limits(_urdf_velocity_limits(self._scene.spec))
        self._chain = chain
        self._model, self._data = model, data
        pm = chain.model
        self._pin = pm
        self._gc_model = chain.gravcomp_model
        self._pdata = pm.createData()
        # Gravity for the control path lives in a Data of its own, so user queries (another
        # gravity_z, FK at another q) never overwrite what the next step() applies.
        self._gdata = pm.createData()
        self._gfull = self._gdata.g  # a view of Pinocchio's buffer, fetched once
        n = len(chain.joint_ids)
        self._n = n
        self._shape = (n,)
        self._qadr = chain.qpos_adr
        self._dadr = chain.dof_adr
        self._arm_q, self._arm_v = chain.arm_q, chain.arm_v
        # No other joints in the model: gravity is the arm's as it is.
        self._arm_only = isinstance(self._arm_v, slice) and self._arm_v == slice(0, pm.nv)
        # The whole model's measured q and v; kept over a rebuild of the same model, so views
        # taken before (the measured ports) stay live.
        self._q = self._kept("_q", pm.nq)
        self._v = self._kept("_v", pm.nv)
        self._qx = np.zeros(pm.nq)  # scratch for calls at an explicit arm q
        self._vx = np.zeros(pm.nv)
        self._ax = np.zeros(pm.nv)
        # Measured ports are views of the model's q and v when the arm is contiguous in them
        # (the usual case), else gathered on every update.
        self._gather_ports = not (isinstance(self._arm_q, slice) and isinstance(self._arm_v, slice))
        self._arm_q_idx = np.arange(pm.nq)[self._arm_q]  # index arrays for the gather path
        self._arm_v_idx = np.arange(pm.nv)[self._arm_v]
        if self._gather_ports:
            self._pos_msr, self._vel_msr = np.zeros(n), np.zeros(n)
            self._g_arm = np.zeros(n)
        else:
            self._pos_msr, self._vel_msr = self._q[self._arm_q], self._v[self._arm_v]
            self._g_arm = self._gfull[self._arm_v]
        self._qsrc = None if chain.q_span is None else data.qpos[chain.q_span]
        self._vsrc = None if chain.v_span is None else data.qvel[chain.v_span]
        self._trq_src = _view(data.qfrc_actuator, self._dadr)
        # Commands survive a rebind (a rebuild) when the chain keeps its length.
        self._trq_msr: np.ndarray = self._kept("_trq_msr", n)
        self._pos_cmd: np.ndarray = self._kept("_pos_cmd", n)
        self._vel_cmd: np.ndarray = self._kept("_vel_cmd", n)
        self._trq_cmd: np.ndarray = self._kept("_trq_cmd", n)
        self._ff = np.zeros(n)
        self._ctrl_buf = np.zeros(n)
        ports = ("_pos_msr", "_vel_msr", "_trq_msr", "_pos_cmd", "_vel_cmd", "_trq_cmd")
        self._ro = {k: _readonly(getattr(self, k)) for k in ports}
        self._solver: IKSolver | None = None
        self._gravity_z = float(model.opt.gravity[2])
        self._unactuated: list[str] = []
        self._read_state()  # the mass matrix below is taken at the measured state
        self._actuation = self._find_actuation(model)
        # update() copies q, v and the measured torque as plain views when it can.
        self._plain_read = (
            self._qsrc is not None
            and self._trq_src is not None
            and not self._gather_ports
            and not self._unactuated
        )
        self._gather()
        ids = np.array([a.actuator for a in self._actuation], dtype=int)
        self._actuator_ids = ids
        self._ctrl_view = _view(data.ctrl, ids)
        self._ctrl = self._ctrl_buf if self._ctrl_view is None else self._ctrl_view
        self._motors = False  # TORQUE mode through contiguous actuators: the fast path
        self._servos = False  # POSITION/VELOCITY through contiguous actuators
        self._servo_cmd = self._pos_cmd  # that mode's command port
        self._acting = self._mode_port()
        self._fast = 0
        if self._applied_mode is not None:
            self._configure(self._applied_mode)
            self._prepare()

    def _kept(self, name: str, n: int) -> np.ndarray:
        old = getattr(self, name, None)
        return old if old is not None and old.shape == (n,) else np.zeros(n)

    def _prefixed(self, name: str) -> str:
        return self._prefix + name if name else ""

    def _check_tool_body(self, model: mujoco.MjModel, chain: Chain) -> None:
        if not self._tool.tool_body:
            return
        name = self._prefixed(self._tool.tool_body)
        body = model_id(model, mujoco.mjtObj.mjOBJ_BODY, "body", name, "the model (tool.tool_body)")
        b = body
        while b not in (chain.tip, 0):
            b = int(model.body_parentid[b])
        if b != chain.tip or body == chain.tip:
            raise SpecError(
                f"tool.tool_body {name!r} is not mounted below the tip {self._tip_name!r}"
            )

    def _ft_ids(self, model: mujoco.MjModel, sensor: ForceTorqueSensorSpec) -> tuple[slice, slice]:
        out = []
        for field, kind, want in (
            ("force_sensor", "force", mujoco.mjtSensor.mjSENS_FORCE),
            ("torque_sensor", "torque", mujoco.mjtSensor.mjSENS_TORQUE),
        ):
            name = self._prefixed(getattr(sensor, field))
            where = f"ft_sensors {sensor.name!r}"
            i = model_id(model, mujoco.mjtObj.mjOBJ_SENSOR, "sensor", name, where)
            if int(model.sensor_type[i]) != int(want):
                raise SpecError(
                    f"ft_sensors {sensor.name!r}: sensor {name!r} is not a {kind} sensor"
                )
            adr = int(model.sensor_adr[i])
            out.append(slice(adr, adr + 3))
        return out[0], out[1]

    def _find_actuation(self, model: mujoco.MjModel) -> list[_Actuation]:
        """One joint-transmission actuator per chain joint, with the servo gains to use."""
        by_joint: dict[int, list[int]] = {}
        for a in range(model.nu):
            if int(model.actuator_trntype[a]) == int(mujoco.mjtTrn.mjTRN_JOINT):
                by_joint.setdefault(int(model.actuator_trnid[a, 0]), []).append(a)
        missing = [model.joint(j).name for j in self._chain.joint_ids if j not in by_joint]
        self._unactuated = missing
        self._partly_actuated = 0 < len(missing) < len(self._chain.joint_ids)
        if missing:
            return []
        mass = np.diag(self.mass_matrix())
        out = []
        for i, j in enumerate(self._chain.joint_ids):
            acts = by_joint[j]
            if len(acts) > 1:
                names = ", ".join(model.actuator(a).name for a in acts)
                raise SpecError(
                    f"joint {model.joint(j).name!r} is driven by several actuators ({names}); "
                    "a Robot drives each joint through exactly one"
                )
            a = acts[0]
            if int(model.actuator_dyntype[a]) != int(mujoco.mjtDyn.mjDYN_NONE):
                raise SpecError(
                    f"actuator {model.actuator(a).name!r} has activation dynamics; control "
                    "modes need direct (dyntype none) actuators"
                )
            gear = float(model.actuator_gear[a, 0])
            if gear == 0:
                raise SpecError(f"actuator {model.actuator(a).name!r} has zero gear")
            kp, kv = _servo_gains(self._scene._authored_actuators, a)
            if kp <= 0:
                omega = 2 * math.pi * _SERVO_HZ
                kp = mass[i] * omega**2 / gear**2
                kv = 2 * mass[i] * omega / gear**2
            elif kv <= 0:
                kv = 2 * math.sqrt(kp * mass[i]) / abs(gear)
            out.append(_Actuation(a, gear, kp, kv))
        return out

    # ------------------------------------------------------------------ description

    @property
    def scene(self) -> Scene:
        """The Scene (or Env) this robot belongs to."""
        return self._scene

    @property
    def n_joints(self) -> int:
        """Number of joints in the chain."""
        self._check_open()
        return self._n

    @property
    def joint_names(self) -> list[str]:
        """MuJoCo joint names in chain order (with prefix)."""
        self._check_open()
        return list(self._chain.joint_names)

    @property
    def actuator_ids(self) -> np.ndarray:
        """MuJoCo ids of the actuators driving the chain's joints, in chain order (a copy)."""
        self._check_open()
        return self._actuator_ids.copy()

    @property
    def gravity_feedforward_scale(self) -> np.ndarray:
        """Per joint, the factor that turns a gravity torque into the offset of the servo's
        setpoint in the current control mode (POSITION: 1/(gear² kp), VELOCITY: 1/(gear² kv);
        1 where the command is a torque): what `gravity_feedforward` adds, over the torque."""
        self._check_open()
        if self.ctrl_mode is CtrlMode.TORQUE or not hasattr(self, "_ff_scale"):
            return np.ones(self._n)
        return np.broadcast_to(np.asarray(self._ff_scale, dtype=float), (self._n,)).copy()

    @property
    def joint_limits(self) -> np.ndarray:
        """n×2 [lower, upper] positions; unlimited joints have ±inf."""
        self._check_open()
        return np.column_stack(
            [self._pin.lowerPositionLimit[self._arm_q], self._pin.upperPositionLimit[self._arm_q]]
        )

    @property
    def has_tcp_frame(self) -> bool:
        """Whether FK refers to a TCP (a site or an offset), else to the tip body."""
        self._check_open()
        return self._chain.tcp_frame != self._chain.tip_frame

    @property
    def model(self) -> pin.Model:
        """The whole Pinocchio model: base joints, arm (`arm_q`/`arm_v`), tool and branches."""
        self._check_open()
        return self._pin

    def kdl_chain(self) -> pin.Model:
        """The Pinocchio model; named after the C++ original's KDL accessor for porting."""
        return self.model

    @property
    def arm_q(self) -> slice | np.ndarray:
        """Where the arm's joints sit in `model`'s q (a slice when contiguous)."""
        self._check_open()
        return self._arm_q

    @property
    def arm_v(self) -> slice | np.ndarray:
        """Where the arm's joints sit in `model`'s v (a slice when contiguous)."""
        self._check_open()
        return self._arm_v

    @property
    def q(self) -> np.ndarray:
        """The whole model's configuration as of the last `update()` (read-only)."""
        self._check_open()
        return _readonly(self._q)

    @property
    def v(self) -> np.ndarray:
        """The whole model's velocity as of the last `update()` (read-only)."""
        self._check_open()
        return _readonly(self._v)

    @property
    def tcp_frame_id(self) -> int:
        """Pinocchio frame id of the TCP (or of the tip body)."""
        self._check_open()
        return self._chain.tcp_frame

    # ------------------------------------------------------------------ ports

    @property
    def jnt_pos_msr(self) -> np.ndarray:
        """Measured joint positions (MuJoCo qpos), as of the last `update()`."""
        if not self._open:
            self._check_open()
        return self._ro["_pos_msr"]

    @property
    def jnt_vel_msr(self) -> np.ndarray:
        """Measured joint velocities, as of the last `update()`."""
        if not self._open:
            self._check_open()
        return self._ro["_vel_msr"]

    @property
    def jnt_trq_msr(self) -> np.ndarray:
        """Torque the actuation applies at each joint (`qfrc_actuator`), after force limits."""
        if not self._open:
            self._check_open()
        return self._ro["_trq_msr"]

    @property
    def last_update_time(self) -> float:
        """Simulation time (`data.time`) at which the measured ports were last read.

        Measured ports change only on `update()` (and on a reset), as on hardware: when this
        is behind `scene.time()`, they are stale by the difference.
        """
        self._check_open()
        return self._stamp

    jnt_pos_cmd = _Command("Joint position command (POSITION mode).")
    """Joint position command, radians or metres in chain order: what POSITION mode's servos
    track (plus gravity feed-forward). Reads as a read-only array; assign a whole vector
    (`robot.jnt_pos_cmd = q`), checked for length, finiteness and magnitude (at most 1e10);
    it applies at the next `step()`. Other modes ignore it (and warn once,
    `IgnoredCommandWarning`)."""
    jnt_vel_cmd = _Command("Joint velocity command (VELOCITY mode).")
    """Joint velocity command in chain order: what VELOCITY mode's servos track (plus gravity
    feed-forward). Assigned and checked like `jnt_pos_cmd`; other modes ignore it (and warn
    once)."""
    jnt_trq_cmd = _Command(
        "Joint torque command (TORQUE mode; on top of gravity with gravity_compensation)."
    )
    """Joint torque command (N·m or N) in chain order: TORQUE mode applies it as it is, or on
    top of the gravity torques with `gravity_compensation`; the actuators' `forcerange` still
    limits it. Assigned and checked like `jnt_pos_cmd`; other modes ignore it (and warn once)."""

    def _vector(self, value: object, name: str, bound: float = math.inf) -> np.ndarray:
        """`value` checked to be n finite numbers, as a float64 array (no copy if it is one).

        `bound`: the largest magnitude accepted (commands: what MuJoCo takes as a control).
        """
        if not self._open:
            self._check_open()
        if type(value) is not np.ndarray or value.dtype != np.float64:
            value = real_array(value, name)
        if value.shape != (self._n,):
            raise SpecError(
                f"{name} needs {self._n} values (one per joint), got shape {value.shape}"
            )
        # v.v <= bound² holds when every entry is within bound (NaN compares false); only when
        # it does not is the exact, slower check needed: one BLAS call on the fast path.
        with np.errstate(over="ignore", invalid="ignore"):
            small = value.dot(value) <= min(bound * bound, _FLOAT_MAX)  # inf is never small
        if not small:
            if not np.isfinite(value).all():
                raise SpecError(f"{name} must be finite, got {value!r}")
            if np.abs(value).max() > bound:
                raise SpecError(
                    f"{name} must be within ±{bound:g} (MuJoCo zeroes larger controls), "
                    f"got {value!r}"
                )
        return value

    def _assign(self, port: np.ndarray, value: object, name: str) -> None:
        """Check `value` as command `name` and copy it into `port` (the slow path of _Command)."""
        port[...] = self._vector(value, name, _MAX_CTRL)
        if not self._active:
            self._activate()
        self._pending = True
        if port is not self._acting and name not in self._warned:
            self._stray_write(name)

    def _mode_port(self) -> np.ndarray:
        """The command port the current mode applies."""
        return getattr(self, "_" + _MODE_PORT[self._mode][4:])

    def _stray_write(self, name: str) -> None:
        """Port `name`, which the current mode ignores, was written: the next apply decides
        (the mode may still change before it) and warns; update() takes its general path
        until then."""
        self._stray.add(name)
        self._pending = True
        self._fast = 0

    def _warn_ignored(self) -> None:
        """Warn, once per port, about ports written since the last apply that the mode ignores."""
        acting = _MODE_PORT[self._mode]
        for name in sorted(self._stray - self._warned - {acting}):
            self._warned.add(name)
            warnings.warn(
                f"{name} was written, but the Robot {self._base_name!r} -> {self._tip_name!r} "
                f"is in {self._mode.name} mode, which applies {acting} only: {name} has no "
                f"effect. Write {acting}, or set robot.ctrl_mode = "
                f"mjk.CtrlMode.{_PORT_MODE[name].name} to use {name} (warned once per robot "
                "and port)",
                IgnoredCommandWarning,
                stacklevel=_caller_stacklevel(),
            )
        self._stray.clear()
        self._choose_path()

    def sync_commands(self) -> None:
        """Set the command ports to the measured state and apply them in the current mode.

        Position commands take the measured positions, velocity and torque commands zero, so
        the next step holds (POSITION) or applies nothing stale. `Env.reset` calls this.
        """
        self._check_open()
        self._hold_commands()
        self._prepare()
        self._apply()

    def _hold_commands(self) -> None:
        self._read_state()
        np.copyto(self._pos_cmd, self._pos_msr)
        self._vel_cmd.fill(0.0)
        self._trq_cmd.fill(0.0)
        self._stray.clear()  # what was written is overwritten: nothing stray can act
        self._pending = True

    def _after_reset(self) -> None:
        """MuJoCo's data was reset: re-read the model's dynamic parameters and the state."""
        self.reload_inertias()

    def reload_inertias(self) -> None:
        """Re-read body masses and inertias, `gravcomp`, armature and gravity from the MjModel.

        The Pinocchio model copies them when the handle is built; call this after editing them
        at run time (e.g. `model.body_mass`). `Env.reset` does it for every robot.
        """
        self._check_open()
        self._chain.load_parameters(self._model)
        self._gc_model = self._chain.gravcomp_model
        self._choose_path()
        self._gravity_z = float(self._model.opt.gravity[2])
        self._read_state()

    def _activate(self) -> None:
        """Start driving the actuators, unless another handle already drives these joints."""
        mine = set(self._chain.joint_ids)
        for other in self._scene._robots:
            if other is self or not isinstance(other, Robot):
                continue
            both = mine & set(other._chain.joint_ids)
            if other._active and both:
                shared = sorted(self._model.joint(j).name for j in both)
                raise SpecError(
                    f"joints {', '.join(shared)} are already driven by the Robot "
                    f"{other._base_name!r} -> {other._tip_name!r}; one Robot per joint may "
                    "control (any number may read; close() the other to take over)"
                )
        self._active = True
        self._choose_path()

    # ------------------------------------------------------------------ control

    @property
    def ctrl_mode(self) -> CtrlMode:
        """POSITION, VELOCITY or TORQUE; a change takes effect on the next `update()`."""
        self._check_open()
        return self._mode

    @ctrl_mode.setter
    def ctrl_mode(self, mode: CtrlMode) -> None:
        self._check_open()
        if not isinstance(mode, CtrlMode):
            raise SpecError(f"ctrl_mode must be a CtrlMode, got {mode!r}")
        if self._gravcomp and mode is not CtrlMode.TORQUE:
            raise SpecError(
                f"ctrl_mode {mode.name}: gravity_compensation is on, which works in TORQUE mode "
                "only; set robot.gravity_compensation = False first"
            )
        if not self._active:
            self._activate()
        self._mode = mode
        self._acting = self._mode_port()
        self._pending = True
        self._choose_path()

    @property
    def gravity_compensation(self) -> bool:
        """TORQUE mode: whether every `update()` applies `jnt_trq_cmd` plus gravity torques.

        The gravity-compensated loop is then `robot.update(); robot.step()`; `jnt_trq_cmd`
        holds only what comes on top of gravity.
        """
        self._check_open()
        return self._gravcomp

    @gravity_compensation.setter
    def gravity_compensation(self, on: bool) -> None:
        self._check_open()
        flag(on, "gravity_compensation")
        if on and self._mode is not CtrlMode.TORQUE:
            raise SpecError(
                f"gravity_compensation works in TORQUE mode only; ctrl_mode is {self._mode.name} "
                "(POSITION and VELOCITY add gravity through gravity_feedforward)"
            )
        if not self._active:
            self._activate()
        self._gravcomp = bool(on)
        self._pending = True
        self._choose_path()

    @property
    def gravity_feedforward(self) -> bool:
        """POSITION and VELOCITY: whether `update()` adds the gravity torques to the servos'
        commands as feed-forward (on by default), so a held pose does not sag."""
        self._check_open()
        return self._gravity_ff

    @gravity_feedforward.setter
    def gravity_feedforward(self, on: bool) -> None:
        self._check_open()
        self._gravity_ff = flag(on, "gravity_feedforward")

    def update(self) -> None:
        """Read the measured state, then apply the command ports for the current mode."""
        fast = self._fast
        if fast:  # contiguous actuators, all checks done beforehand (_choose_path)
            self._stamp = self._data.time
            self._q[...] = self._qsrc
            self._v[...] = self._vsrc
            self._trq_msr[...] = self._trq_src
            if fast == 1:  # TORQUE
                if self._pending:
                    self._pending = False
                    self._ctrl[...] = self._trq_cmd
                return
            self._pending = False
            if fast == 2:  # TORQUE with gravity compensation
                _gravity(self._pin, self._gdata, self._q)
                _add(self._trq_cmd, self._g_arm, self._ctrl)
            elif self._gravity_ff:  # servos
                _gravity(self._pin, self._gdata, self._q)
                _mul(self._g_arm, self._ff_scale, self._ff)
                _add(self._servo_cmd, self._ff, self._ctrl)
            else:
                self._ctrl[...] = self._servo_cmd
            return
        self._check_open()
        self._read_state()
        if not self._active:
            self._activate()
        if self._unactuated and (error := self._control_error()):
            raise SpecError(error)
        self._prepare()
        if self._pending or self._gravcomp or self._mode is not CtrlMode.TORQUE:
            self._apply()

    def _choose_path(self) -> None:
        """Pick update()'s fast path, for an active handle that reads plainly and drives
        contiguous actuators in the mode it asked for: 1 TORQUE, 2 TORQUE with gravity
        compensation, 3 servos; 0 for the general path (also whenever MuJoCo's gravcomp
        share has to come off the gravity)."""
        ready = (
            self._open
            and self._active
            and not self._stray  # the general path applies, and warns about, stray writes
            and self._plain_read
            and self._mode is self._applied_mode
            and (self._motors or self._servos)
        )
        self._driven = self._servo_cmd if self._servos else self._trq_cmd
        if not ready:
            self._fast = 0
        elif not self._motors:
            self._fast = 3 if self._gc_model is None else 0
        elif self._gravcomp:
            self._fast = 2 if self._gc_model is None else 0
        else:
            self._fast = 1

    def step(self) -> None:
        """Advance the scene one timestep; pending commands (of every robot) apply first."""
        if not self._open:
            self._check_open()
        self._scene.step()

    def _finish_gravity(self) -> None:
        """`_gdata.g` less what MuJoCo's gravcomp cancels; the arm's entries gathered."""
        if self._gc_model is not None:
            self._gfull -= _gravity(self._gc_model, self._pdata, self._q)
        if self._gather_ports:
            np.take(self._gfull, self._arm_v_idx, out=self._g_arm)

    def _prepare(self) -> None:
        """What the mode adds to the commands at the measured state: gravity, once per update."""
        if self._applied_mode is not self._mode:
            return  # _apply configures the mode first, then comes back here
        if self._gravcomp or (self._mode is not CtrlMode.TORQUE and self._gravity_ff):
            _gravity(self._pin, self._gdata, self._q)
            self._finish_gravity()
            if not self._gravcomp and self._actuation:
                np.multiply(self._g_arm, self._ff_scale, out=self._ff)

    def _apply(self) -> None:
        """Write the command ports into MuJoCo's controls in the current mode.

        The actuators' gains are set so the control is in joint units: the torque itself
        (TORQUE), the position or velocity setpoint (servos), plus the scaled feed-forward.
        A handle that was never used for control leaves the actuators as authored.
        """
        if self._stray:
            self._warn_ignored()
        if self._mode is not self._applied_mode:
            if not self._active:
                return
            self._configure(self._mode)
            self._prepare()
        self._pending = False
        ctrl = self._ctrl
        if self._motors:  # TORQUE mode through actuators whose controls are contiguous
            if self._gravcomp:
                np.add(self._trq_cmd, self._g_arm, out=ctrl)
            else:
                ctrl[...] = self._trq_cmd
            return
        if self._servos:  # the same for POSITION and VELOCITY
            if self._gravity_ff:
                np.add(self._servo_cmd, self._ff, out=ctrl)
            else:
                ctrl[...] = self._servo_cmd
            return
        if self._unactuated and (error := self._control_error()):
            raise SpecError(error)  # the same error update() gives
        mode = self._mode
        if mode is CtrlMode.TORQUE:
            if self._gravcomp:
                np.add(self._trq_cmd, self._g_arm, out=ctrl)
            else:
                ctrl[...] = self._trq_cmd
            if not self._actuation:
                self._data.qfrc_applied[self._dadr] = ctrl
                return
        else:
            cmd = self._pos_cmd if mode is CtrlMode.POSITION else self._vel_cmd
            if self._gravity_ff:
                np.add(cmd, self._ff, out=ctrl)
            else:
                ctrl[...] = cmd
        if self._ctrl_view is None:
            self._data.ctrl[self._actuator_ids] = ctrl

    def _control_error(self) -> str | None:
        """Why the chain's commands cannot be applied in the current mode, if they cannot."""
        names = ", ".join(self._unactuated)
        if self._partly_actuated:
            return (
                f"joints {names} have no actuator while the rest of the chain has: a Robot "
                "drives all chain joints through actuators, or none (TORQUE mode then applies "
                "the torques as qfrc_applied)"
            )
        if self._unactuated and self._mode is not CtrlMode.TORQUE:
            return (
                f"{self._mode.name} mode needs an actuator on every joint; none drives {names} "
                "(TORQUE mode applies the torques as qfrc_applied)"
            )
        return None

    def _read_state(self) -> None:
        self._stamp = self._data.time
        if self._qsrc is not None:
            self._q[...] = self._qsrc
            self._v[...] = self._vsrc
        else:
            self._chain.read_state(self._data, self._q, self._v)
        self._gather()

    def _gather(self) -> None:
        """The measured ports that are not plain views of MuJoCo's or Pinocchio's arrays."""
        d = self._data
        if self._gather_ports:
            np.take(self._q, self._arm_q_idx, out=self._pos_msr)
            np.take(self._v, self._arm_v_idx, out=self._vel_msr)
        if self._trq_src is not None:
            self._trq_msr[...] = self._trq_src
        else:
            np.take(d.qfrc_actuator, self._dadr, out=self._trq_msr)
        if self._unactuated:
            self._trq_msr += d.qfrc_applied[self._dadr]

    def _configure(self, mode: CtrlMode) -> None:
        """Turn the chain's actuators into motors or servos for `mode`."""
        self._applied_mode = mode
        self._pending = True
        self._motors = False
        self._servos = False
        if not self._actuation:
            return
        m = self._model
        gear = np.array([a.gear for a in self._actuation])
        kp = np.array([a.kp for a in self._actuation])
        kv = np.array([a.kv for a in self._actuation])
        for i, a in enumerate(self._actuation):
            aid = a.actuator
            m.actuator_gaintype[aid] = mujoco.mjtGain.mjGAIN_FIXED
            m.actuator_biastype[aid] = mujoco.mjtBias.mjBIAS_AFFINE
            m.actuator_ctrllimited[aid] = 0
            m.actuator_gainprm[aid, :] = 0.0
            m.actuator_biasprm[aid, :] = 0.0
            # Force f acts as gear*f at the joint, servos act on the length gear*q: a gain of
            # 1/gear (motors) or k*gear (servos) makes the control a joint torque or setpoint.
            if mode is CtrlMode.TORQUE:
                m.actuator_gainprm[aid, 0] = 1.0 / gear[i]
            elif mode is CtrlMode.POSITION:
                m.actuator_gainprm[aid, 0] = kp[i] * gear[i]
                m.actuator_biasprm[aid, 1:3] = (-kp[i], -kv[i])
            else:
                m.actuator_gainprm[aid, 0] = kv[i] * gear[i]
                m.actuator_biasprm[aid, 2] = -kv[i]
        # The servo's joint torque is gear²·k·(setpoint - q): feed-forward enters scaled.
        if mode is not CtrlMode.TORQUE:
            self._ff_scale = 1.0 / (gear * gear * (kp if mode is CtrlMode.POSITION else kv))
        contiguous = self._ctrl_view is not None
        self._motors = mode is CtrlMode.TORQUE and contiguous
        self._servos = contiguous and mode is not CtrlMode.TORQUE
        self._servo_cmd = self._vel_cmd if mode is CtrlMode.VELOCITY else self._pos_cmd
        self._choose_path()

    # ------------------------------------------------------------------ state

    def set_joint_pos(self, q: np.ndarray, call_forward: bool = True) -> None:
        """Write joint positions into MuJoCo's qpos (velocities are left as they are).

        Positions outside a joint's range are refused: MuJoCo would push the joint back.
        """
        q = self._vector(q, "set_joint_pos(q)")
        flag(call_forward, "set_joint_pos: call_forward")
        lo, hi = (
            self._pin.lowerPositionLimit[self._arm_q],
            self._pin.upperPositionLimit[self._arm_q],
        )
        outside = np.flatnonzero((q < lo) | (q > hi))
        if len(outside):
            i = int(outside[0])
            raise SpecError(
                f"set_joint_pos(q): joint {self._chain.joint_names[i]!r} at {q[i]:g} is outside "
                f"its range [{lo[i]:g}, {hi[i]:g}]"
            )
        self._data.qpos[self._qadr] = q
        if self._gather_ports:
            self._pos_msr[...] = q
        self._q[self._arm_q] = q
        if call_forward:
            mujoco.mj_forward(self._model, self._data)

    # ------------------------------------------------------------------ kinematics / dynamics

    def _full_q(self, q: object) -> np.ndarray:
        """The whole model's q: measured, with the arm's entries replaced by `q` if given."""
        if q is None:
            return self._q
        arm = self._vector(q, "q")
        qx = self._qx
        qx[...] = self._q
        qx[self._arm_q] = arm
        return qx

    def _full_v(self, v: object, name: str = "v") -> np.ndarray:
        if v is None:
            return self._v
        arm = self._vector(v, name)
        vx = self._vx
        vx[...] = self._v
        vx[self._arm_v] = arm
        return vx

    def fk_frame(self, q: np.ndarray | None = None) -> pin.SE3:
        """World pose of the TCP (the tip body when there is no TCP site)."""
        self._check_open()
        pin.forwardKinematics(self._pin, self._pdata, self._full_q(q))
        return pin.SE3(pin.updateFramePlacement(self._pin, self._pdata, self._chain.tcp_frame))

    def jacobian(self, q: np.ndarray | None = None) -> np.ndarray:
        """6×n Jacobian at the TCP, world-aligned axes: linear rows first, then angular."""
        self._check_open()
        jac = pin.computeFrameJacobian(
            self._pin, self._pdata, self._full_q(q), self._chain.tcp_frame, _LWA
        )
        return np.ascontiguousarray(jac[:, self._arm_v])

    def gravity_torques(self, gravity_z: float | None = None) -> np.ndarray:
        """Joint torques that hold the arm (with its tool) against gravity at the measured q.

        Bodies with MuJoCo `gravcomp` count only with the share MuJoCo leaves to the
        actuators. `gravity_z` overrides the z component of the scene's gravity for this call.
        """
        if not self._open:
            self._check_open()
        if gravity_z is None or (gravity_z.__class__ is float and gravity_z == self._gravity_z):
            g = _gravity(self._pin, self._pdata, self._q)
            if self._gc_model is not None:
                g -= _gravity(self._gc_model, self._pdata, self._q)
            return g if self._arm_only else g[self._arm_v]
        gz = real(gravity_z, "gravity_torques: gravity_z")
        models = [self._pin] + ([self._gc_model] if self._gc_model is not None else [])
        saved = self._pin.gravity.linear.copy()
        try:
            for model in models:
                model.gravity = pin.Motion(np.array([saved[0], saved[1], gz]), np.zeros(3))
            return self.gravity_torques()
        finally:
            for model in models:
                model.gravity = pin.Motion(saved, np.zeros(3))

    def mass_matrix(self, q: np.ndarray | None = None) -> np.ndarray:
        """n×n joint-space inertia matrix, joint armature included (MuJoCo's `mj_fullM`)."""
        self._check_open()
        upper = pin.crba(self._pin, self._pdata, self._full_q(q))
        arm = self._arm_v if isinstance(self._arm_v, slice) else np.ix_(self._arm_v, self._arm_v)
        block = upper[arm] if isinstance(arm, tuple) else upper[arm, arm]
        return np.triu(block) + np.triu(block, 1).T

    def nonlinear_effects(
        self, q: np.ndarray | None = None, v: np.ndarray | None = None
    ) -> np.ndarray:
        """Coriolis, centrifugal and gravity torques (MuJoCo's `qfrc_bias` for the arm).

        All joints' velocities count: the fingers' and a moving base's too.
        """
        self._check_open()
        return self._rnea(self._full_q(q), self._full_v(v), None)

    def inverse_dynamics(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        """Joint torques that produce arm acceleration `a` at (`q`, `v`) (RNEA, armature in).

        The other joints keep their measured position and velocity and do not accelerate.
        """
        self._check_open()
        return self._rnea(self._full_q(q), self._full_v(v), self._vector(a, "a"))

    def _rnea(self, q: np.ndarray, v: np.ndarray, arm_acc: np.ndarray | None) -> np.ndarray:
        """The arm's rows of RNEA with the arm accelerating by `arm_acc`, the rest at rest.

        "At rest" is MuJoCo's qacc = 0. For a free joint that is a world-frame linear
        acceleration of zero, while Pinocchio's acceleration is the derivative of the
        body-frame velocity: the two differ by ω × v.
        """
        ax = self._ax
        ax.fill(0.0)
        if arm_acc is not None:
            ax[self._arm_v] = arm_acc
        for _, iv in self._chain.free:
            ax[iv : iv + 3] = -np.cross(v[iv + 3 : iv + 6], v[iv : iv + 3])
        tau = pin.rnea(self._pin, self._pdata, q, v, ax)
        if self._gc_model is not None:
            tau -= _gravity(self._gc_model, self._pdata, q)
        return tau[self._arm_v]

    def ik(self, target: pin.SE3, q0: np.ndarray | None = None) -> IKResult:
        """Joint positions that put the TCP at `target`, within the joint limits.

        The base and the tool's joints stay at their measured configuration.
        """
        self._check_open()
        if self._solver is None:
            lim = self.joint_limits
            self._solver = IKSolver(
                self._pin,
                self._chain.tcp_frame,
                lim[:, 0],
                lim[:, 1],
                joints=self._chain.arm_joints,
            )
        seed = self._pos_msr if q0 is None else self._vector(q0, "q0")
        return self._solver.solve(target, seed.copy(), self._q)

    def ft_sensor(self, name: str) -> pin.Force:
        """Force/torque reading of `tool.ft_sensors[name]`, in the sensor's site frame."""
        self._check_open()
        if not isinstance(name, str) or name not in self._ft:
            raise unknown_name("force/torque sensor", str(name), self._ft, where="tool.ft_sensors")
        force, torque = self._ft[name]
        data = self._data.sensordata
        return pin.Force(data[force].copy(), data[torque].copy())

    # ------------------------------------------------------------------ lifecycle

    def close(self) -> None:
        """Release the handle: its actuators go back to as authored, later calls raise."""
        if not self._open:
            return
        self._scene._unregister(self)
        self._release("this Robot is closed")

    def _release(self, why: str = "this Robot's scene is closed") -> None:
        """Stop driving the actuators (when the model is still there) and refuse later calls."""
        if self._active and self._actuation and self._scene._model is not None:
            self._scene._authored_actuators.restore(self._model, self._actuator_ids)
        self._active = False
        self._applied_mode = None
        self._motors = False
        self._servos = False
        self._plain_read = False
        self._fast = 0
        self._open = False
        self._closed_why = why

    def _check_open(self) -> None:
        if self._scene._model is None:
            raise RuntimeError("this Robot's scene is closed")
        if not self._open:
            raise RuntimeError(self._closed_why)


def _servo_gains(authored: AuthoredActuators, a: int) -> tuple[float, float]:
    """(kp, kv) of a MuJoCo position servo (`<position>`); (0, 0) for anything else."""
    gain = authored.gainprm[a]
    bias = authored.biasprm[a]
    is_servo = (
        int(authored.gaintype[a]) == int(mujoco.mjtGain.mjGAIN_FIXED)
        and int(authored.biastype[a]) == int(mujoco.mjtBias.mjBIAS_AFFINE)
        and gain[0] > 0
        and bias[0] == 0
        and bias[1] == -gain[0]
    )
    return (float(gain[0]), float(-bias[2])) if is_servo else (0.0, 0.0)


def _tcp_offset(tool: ToolFrameSpec) -> pin.SE3 | None:
    """The TCP's placement in `tcp_site` (or the tip body), None when there is no offset."""
    pos = vector(tool.tcp_pos, 3, "tool.tcp_pos")
    quat = euler_quat(tool.tcp_euler, "tool.tcp_euler")
    if not np.any(pos) and np.array_equal(quat, [1.0, 0.0, 0.0, 0.0]):
        return None
    return pin.SE3(pin.Quaternion(*quat).matrix(), pos)


def _urdf_velocity_limits(spec: SceneSpec) -> dict[str, float]:
    """`<limit velocity>` of every URDF robot's joints, by compiled (prefixed) joint name."""
    limits = {}
    for robot in spec.robots:
        path = Path(robot.path)
        if path.suffix.lower() != ".urdf" or not path.is_file():
            continue
        for joint in ET.parse(path).iter("joint"):
            limit = joint.find("limit")
            try:
                velocity = float(limit.get("velocity", "")) if limit is not None else math.nan
            except ValueError:
                continue
            if velocity > 0:
                limits[robot.prefix + joint.get("name", "")] = velocity
    return limits


def _view(arr: np.ndarray, idx: np.ndarray) -> np.ndarray | None:
    """A slice view of `arr` when `idx` is contiguous (no copy per read), else None."""
    if len(idx) and np.all(np.diff(idx) == 1):
        return arr[idx[0] : idx[-1] + 1]
    return None


def _caller_stacklevel() -> int:
    """The `warnings.warn` stacklevel of the first frame outside mjkdl (the user's call)."""
    frame: FrameType | None = sys._getframe(1)
    level = 1
    while frame is not None and frame.f_code.co_filename.startswith(_PACKAGE):
        frame = frame.f_back
        level += 1
    return level


def _readonly(arr: np.ndarray) -> np.ndarray:
    view = arr.view()
    view.flags.writeable = False
    return view


register_robot_factory(Robot)
