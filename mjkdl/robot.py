"""The Robot handle: joint ports, control modes and Pinocchio kinematics/dynamics."""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import mujoco
import numpy as np
import pinocchio as pin

from .chain import Chain
from .compile import euler_quat, vector
from .errors import SpecError, unknown_name
from .ik import IKResult, IKSolver
from .spec import CtrlMode, ToolFrameSpec

if TYPE_CHECKING:
    from .scene import Scene

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
# Default servo bandwidth for joints whose actuators are plain motors (URDF robots).
_SERVO_HZ = 10.0


@dataclass
class _Actuation:
    """How one chain joint is driven: its actuator and the gains each mode uses."""

    actuator: int
    gear: float
    kp: float
    kv: float


class Robot:
    """A controllable serial chain of a `Scene`, modelled in Pinocchio.

    Ports are NumPy arrays in chain order (base to tip). Measured ports are read-only arrays
    that `update()` refreshes in place; copy them to keep a snapshot. Commands are assigned as a
    whole (`robot.jnt_trq_cmd = tau`) and checked for length and finiteness.

    Control modes reconfigure the chain's own MuJoCo actuators (gain/bias parameters):
    TORQUE turns them into motors (force limited by the actuator's `forcerange`), POSITION
    into position servos and VELOCITY into velocity servos. Servo gains are the actuator's own
    when it is a MuJoCo position servo; for motor actuators (URDF robots) a critically damped
    servo of about 10 Hz is synthesised from the mass matrix. POSITION and VELOCITY add
    Pinocchio's gravity torques as feed-forward (`gravity_feedforward`), so a held pose does
    not sag under gravity. The servos ignore the actuators' authored `ctrlrange` (commands are
    in joint units in every mode); `forcerange` still limits the force.

    A handle starts driving its actuators once it is used for control — `update()`, a command
    assignment or a `ctrl_mode` change; until then it only reads, so several handles may look
    at the same joints, but only one may drive them.
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
        if tool is not None and not isinstance(tool, ToolFrameSpec):
            raise SpecError(f"tool must be a ToolFrameSpec, got {type(tool).__name__}")
        self._scene = scene
        self._prefix = prefix
        self._base_name = prefix + base_body
        self._tip_name = prefix + tip_body
        self._tool = copy.deepcopy(tool) if tool is not None else ToolFrameSpec()
        self._tcp_offset = _tcp_offset(self._tool)
        self._mode = CtrlMode.POSITION
        self._applied_mode: CtrlMode | None = None
        self._active = False
        self.gravity_feedforward = True
        self._bind(scene.model, scene.data)
        self._hold_commands()
        self._pending = False

    # ------------------------------------------------------------------ binding

    def _bind(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """(Re)build everything that depends on the compiled model and its data."""
        tcp = self._prefixed(self._tool.tcp_site)
        self._chain = Chain(model, data, self._base_name, self._tip_name, tcp, self._tcp_offset)
        self._check_tool_body(model)
        self._ft = {s.name: self._ft_ids(model, s) for s in self._tool.ft_sensors}
        self._model, self._data = model, data
        self._pin = self._chain.model
        self._pdata = self._pin.createData()
        self._gravity_z = float(model.opt.gravity[2])
        n = len(self._chain.joint_ids)
        self._n = n
        self._qadr = self._chain.qpos_adr
        self._dadr = self._chain.dof_adr
        self._actuation = self._find_actuation(model, data)
        ids = np.array([a.actuator for a in self._actuation], dtype=int)
        self._actuator_ids = ids
        self._ctrl_view = _view(data.ctrl, ids)
        ports = ("_pos_msr", "_vel_msr", "_trq_msr", "_pos_cmd", "_vel_cmd", "_trq_cmd")
        for name in ports:
            old = getattr(self, name, None)
            setattr(self, name, old if old is not None and old.shape == (n,) else np.zeros(n))
        # Measured ports are copied from views of MuJoCo's arrays when the chain's joints are
        # contiguous in qpos/qvel (the usual case), else gathered by index.
        views = (
            _view(data.qpos, self._qadr),
            _view(data.qvel, self._dadr),
            _view(data.qfrc_actuator, self._dadr),
        )
        self._views = None if any(v is None for v in views) else views
        self._ff = np.zeros(n)
        self._ctrl_buf = np.zeros(n)
        self._ro = {k: _readonly(getattr(self, k)) for k in ports}
        self._solver: IKSolver | None = None
        self._read_state()
        if self._applied_mode is not None:
            self._configure(self._applied_mode)

    def _prefixed(self, name: str) -> str:
        return self._prefix + name if name else ""

    def _check_tool_body(self, model: mujoco.MjModel) -> None:
        if not self._tool.tool_body:
            return
        name = self._prefixed(self._tool.tool_body)
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
        if body < 0:
            known = [model.body(k).name for k in range(model.nbody)]
            raise unknown_name("body", name, known, where="the model (tool.tool_body)")
        b = body
        while b not in (self._chain.tip, 0):
            b = int(model.body_parentid[b])
        if b != self._chain.tip or body == self._chain.tip:
            raise SpecError(
                f"tool.tool_body {name!r} is not mounted below the tip {self._tip_name!r}"
            )

    def _ft_ids(self, model: mujoco.MjModel, sensor) -> tuple[slice, slice]:
        out = []
        for field, kind, want in (
            ("force_sensor", "force", mujoco.mjtSensor.mjSENS_FORCE),
            ("torque_sensor", "torque", mujoco.mjtSensor.mjSENS_TORQUE),
        ):
            name = self._prefixed(getattr(sensor, field))
            i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, name)
            if i < 0:
                known = [model.sensor(k).name for k in range(model.nsensor)]
                raise unknown_name("sensor", name, known, where=f"ft_sensors {sensor.name!r}")
            if int(model.sensor_type[i]) != int(want):
                raise SpecError(
                    f"ft_sensors {sensor.name!r}: sensor {name!r} is not a {kind} sensor"
                )
            adr = int(model.sensor_adr[i])
            out.append(slice(adr, adr + 3))
        return out[0], out[1]

    def _find_actuation(self, model: mujoco.MjModel, data: mujoco.MjData) -> list[_Actuation]:
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
        mass = self._mass_diagonal(model, data)
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

    def _mass_diagonal(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
        q = data.qpos[self._chain.qpos_adr]
        self._chain.refresh(model, data)
        pdata = self._chain.model.createData()
        return np.diag(pin.crba(self._chain.model, pdata, q)).copy()

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
    def joint_limits(self) -> np.ndarray:
        """n×2 [lower, upper] positions; unlimited joints have ±inf."""
        self._check_open()
        return np.column_stack([self._pin.lowerPositionLimit, self._pin.upperPositionLimit])

    @property
    def has_tcp_frame(self) -> bool:
        """Whether FK refers to a TCP (a site or an offset), else to the tip body."""
        self._check_open()
        return self._chain.tcp_frame != self._chain.tip_frame

    @property
    def model(self) -> pin.Model:
        """The Pinocchio model of the chain (tool inertia lumped into the last link)."""
        self._check_open()
        return self._pin

    def kdl_chain(self) -> pin.Model:
        """The chain model; named after the C++ original's KDL accessor for porting."""
        return self.model

    @property
    def tcp_frame_id(self) -> int:
        """Pinocchio frame id of the TCP (or of the tip body)."""
        self._check_open()
        return self._chain.tcp_frame

    # ------------------------------------------------------------------ ports

    @property
    def jnt_pos_msr(self) -> np.ndarray:
        """Measured joint positions (MuJoCo qpos), as of the last `update()`."""
        self._check_open()
        return self._ro["_pos_msr"]

    @property
    def jnt_vel_msr(self) -> np.ndarray:
        """Measured joint velocities, as of the last `update()`."""
        self._check_open()
        return self._ro["_vel_msr"]

    @property
    def jnt_trq_msr(self) -> np.ndarray:
        """Torque the actuation applies at each joint (`qfrc_actuator`), after force limits."""
        self._check_open()
        return self._ro["_trq_msr"]

    @property
    def jnt_pos_cmd(self) -> np.ndarray:
        """Joint position command (POSITION mode)."""
        self._check_open()
        return self._ro["_pos_cmd"]

    @jnt_pos_cmd.setter
    def jnt_pos_cmd(self, value: np.ndarray) -> None:
        self._assign(self._pos_cmd, value, "jnt_pos_cmd")

    @property
    def jnt_vel_cmd(self) -> np.ndarray:
        """Joint velocity command (VELOCITY mode)."""
        self._check_open()
        return self._ro["_vel_cmd"]

    @jnt_vel_cmd.setter
    def jnt_vel_cmd(self, value: np.ndarray) -> None:
        self._assign(self._vel_cmd, value, "jnt_vel_cmd")

    @property
    def jnt_trq_cmd(self) -> np.ndarray:
        """Joint torque command (TORQUE mode)."""
        self._check_open()
        return self._ro["_trq_cmd"]

    @jnt_trq_cmd.setter
    def jnt_trq_cmd(self, value: np.ndarray) -> None:
        self._assign(self._trq_cmd, value, "jnt_trq_cmd")

    def _vector(self, value: object, name: str) -> np.ndarray:
        """`value` checked to be n finite numbers, as a float64 array (no copy if it is one)."""
        if self._scene._model is None:
            self._check_open()
        if type(value) is not np.ndarray or value.dtype != np.float64:
            try:
                value = np.asarray(value, dtype=float)
            except (TypeError, ValueError):
                raise SpecError(f"{name} must hold numbers, got {value!r}") from None
        if value.shape != (self._n,):
            raise SpecError(
                f"{name} needs {self._n} values (one per joint), got shape {value.shape}"
            )
        # v.v is finite exactly when every entry is (barring overflow past 1e154, which the
        # exact check below then clears): one BLAS call instead of a ufunc and a reduction.
        if not math.isfinite(value.dot(value)) and not np.isfinite(value).all():
            raise SpecError(f"{name} must be finite, got {value!r}")
        return value

    def _assign(self, port: np.ndarray, value: object, name: str) -> None:
        np.copyto(port, self._vector(value, name))
        self._pending = True
        if not self._active:
            self._activate()

    def sync_commands(self) -> None:
        """Set the command ports to the measured state and apply them in the current mode.

        Position commands take the measured positions, velocity and torque commands zero, so
        the next step holds (POSITION) or applies nothing stale. `Env.reset` calls this.
        """
        self._check_open()
        self._hold_commands()
        self._apply()

    def _hold_commands(self) -> None:
        self._read_state()
        np.copyto(self._pos_cmd, self._pos_msr)
        self._vel_cmd.fill(0.0)
        self._trq_cmd.fill(0.0)
        self._pending = True

    def _after_reset(self) -> None:
        """MuJoCo's data was reset and forwarded: drop what was derived from the old state."""
        self._chain.invalidate()
        self._read_state()

    def _activate(self) -> None:
        """Start driving the actuators, unless another handle already drives these joints."""
        mine = set(self._chain.joint_ids)
        for other in self._scene._robots:
            both = mine & set(other._chain.joint_ids)
            if other is not self and other._active and both:
                shared = sorted(self._model.joint(j).name for j in both)
                raise SpecError(
                    f"joints {', '.join(shared)} are already driven by the Robot "
                    f"{other._base_name!r} -> {other._tip_name!r}; one Robot per joint may "
                    "control (any number may read)"
                )
        self._active = True

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
        if not self._active:
            self._activate()
        self._mode = mode
        self._pending = True

    def update(self) -> None:
        """Read the measured state, then apply the command ports for the current mode."""
        if self._scene._model is None:
            self._check_open()
        self._read_state()
        if not self._active:
            self._activate()
        if self._unactuated and (error := self._control_error()):
            raise SpecError(error)
        if self._pending or self._mode is not CtrlMode.TORQUE:
            self._apply()

    def step(self) -> None:
        """Advance the scene one timestep; pending commands (of every robot) apply first."""
        self._scene.step()

    def _apply(self) -> None:
        """Write the command ports into MuJoCo's controls in the current mode.

        A handle that was never used for control leaves the actuators as authored.
        """
        if not self._active:
            return
        if self._mode is not self._applied_mode:
            self._configure(self._mode)
        mode = self._mode
        self._pending = False
        if not self._actuation:
            if self._control_error() is None:
                self._data.qfrc_applied[self._dadr] = self._trq_cmd
            return
        view = self._ctrl_view
        ctrl = self._ctrl_buf if view is None else view
        if mode is CtrlMode.TORQUE:
            np.multiply(self._trq_cmd, self._cmd_scale, out=ctrl)
        else:
            cmd = self._pos_cmd if mode is CtrlMode.POSITION else self._vel_cmd
            np.multiply(cmd, self._cmd_scale, out=ctrl)
            if self.gravity_feedforward:
                self._refresh()
                ff = pin.computeGeneralizedGravity(self._pin, self._pdata, self._pos_msr)
                np.multiply(ff, self._ff_scale, out=self._ff)
                np.add(ctrl, self._ff, out=ctrl)
        if view is None:
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
        if self._views is not None:
            copyto = np.copyto
            pos, vel, trq = self._views
            copyto(self._pos_msr, pos)
            copyto(self._vel_msr, vel)
            copyto(self._trq_msr, trq)
        else:
            d = self._data
            np.take(d.qpos, self._qadr, out=self._pos_msr)
            np.take(d.qvel, self._dadr, out=self._vel_msr)
            np.take(d.qfrc_actuator, self._dadr, out=self._trq_msr)
        if self._unactuated:
            self._trq_msr += self._data.qfrc_applied[self._dadr]
        self._dirty = True

    def _configure(self, mode: CtrlMode) -> None:
        """Turn the chain's actuators into motors or servos for `mode`."""
        self._applied_mode = mode
        self._pending = True
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
            if mode is CtrlMode.TORQUE:
                m.actuator_gainprm[aid, 0] = 1.0
            elif mode is CtrlMode.POSITION:
                m.actuator_gainprm[aid, 0] = kp[i]
                m.actuator_biasprm[aid, 1:3] = (-kp[i], -kv[i])
            else:
                m.actuator_gainprm[aid, 0] = kv[i]
                m.actuator_biasprm[aid, 2] = -kv[i]
        # Actuator force f acts as gear*f at the joint; servos act on length gear*q.
        if mode is CtrlMode.TORQUE:
            self._cmd_scale = 1.0 / gear
        elif mode is CtrlMode.POSITION:
            self._cmd_scale, self._ff_scale = gear, 1.0 / (gear * kp)
        else:
            self._cmd_scale, self._ff_scale = gear, 1.0 / (gear * kv)

    # ------------------------------------------------------------------ state

    def set_joint_pos(self, q: np.ndarray, call_forward: bool = True) -> None:
        """Write joint positions into MuJoCo's qpos (velocities are left as they are)."""
        q = self._vector(q, "set_joint_pos(q)")
        self._data.qpos[self._qadr] = q
        np.copyto(self._pos_msr, q)
        self._dirty = True
        if call_forward:
            mujoco.mj_forward(self._model, self._data)

    # ------------------------------------------------------------------ kinematics / dynamics

    def _q(self, q: object, name: str = "q") -> np.ndarray:
        return self._pos_msr if q is None else self._vector(q, name)

    def _refresh(self) -> None:
        """Bring lumped tool inertias up to the configuration MuJoCo last computed."""
        if self._dirty:
            self._chain.refresh(self._model, self._data)
            self._dirty = False

    def fk_frame(self, q: np.ndarray | None = None) -> pin.SE3:
        """World pose of the TCP (the tip body when there is no TCP site)."""
        self._check_open()
        self._refresh()
        pin.forwardKinematics(self._pin, self._pdata, self._q(q))
        return pin.SE3(pin.updateFramePlacement(self._pin, self._pdata, self._chain.tcp_frame))

    def jacobian(self, q: np.ndarray | None = None) -> np.ndarray:
        """6×n Jacobian at the TCP, world-aligned axes: linear rows first, then angular."""
        self._check_open()
        self._refresh()
        return pin.computeFrameJacobian(
            self._pin, self._pdata, self._q(q), self._chain.tcp_frame, _LWA
        )

    def gravity_torques(self, gravity_z: float | None = None) -> np.ndarray:
        """Joint torques that hold the chain (with its tool) against gravity at the measured q.

        `gravity_z` overrides the z component of the scene's gravity for this call.
        """
        if self._scene._model is None:
            self._check_open()
        if self._dirty:
            self._refresh()
        if gravity_z is None or gravity_z == self._gravity_z:
            return pin.computeGeneralizedGravity(self._pin, self._pdata, self._pos_msr)
        try:
            gz = float(gravity_z)
        except (TypeError, ValueError):
            gz = math.nan
        if not math.isfinite(gz):
            raise SpecError(
                f"gravity_torques: gravity_z must be a finite number, got {gravity_z!r}"
            )
        g = self._pin.gravity
        saved = g.linear.copy()
        try:
            self._pin.gravity = pin.Motion(np.array([saved[0], saved[1], gz]), np.zeros(3))
            return pin.computeGeneralizedGravity(self._pin, self._pdata, self._pos_msr)
        finally:
            self._pin.gravity = pin.Motion(saved, np.zeros(3))

    def mass_matrix(self, q: np.ndarray | None = None) -> np.ndarray:
        """n×n joint-space inertia matrix, joint armature included (MuJoCo's `mj_fullM`)."""
        self._check_open()
        self._refresh()
        upper = pin.crba(self._pin, self._pdata, self._q(q))
        return np.triu(upper) + np.triu(upper, 1).T

    def nonlinear_effects(
        self, q: np.ndarray | None = None, v: np.ndarray | None = None
    ) -> np.ndarray:
        """Coriolis, centrifugal and gravity torques (MuJoCo's `qfrc_bias` for the chain)."""
        self._check_open()
        self._refresh()
        vel = self._vel_msr if v is None else self._q(v, "v")
        return pin.nonLinearEffects(self._pin, self._pdata, self._q(q), vel)

    def inverse_dynamics(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        """Joint torques that produce acceleration `a` at (`q`, `v`) (RNEA, armature included)."""
        self._check_open()
        self._refresh()
        return pin.rnea(self._pin, self._pdata, self._q(q), self._q(v, "v"), self._q(a, "a"))

    def ik(self, target: pin.SE3, q0: np.ndarray | None = None) -> IKResult:
        """Joint positions that put the TCP at `target`, within the joint limits."""
        self._check_open()
        self._refresh()
        if self._solver is None:
            lim = self.joint_limits
            self._solver = IKSolver(self._pin, self._chain.tcp_frame, lim[:, 0], lim[:, 1])
        return self._solver.solve(target, self._q(q0, "q0").copy())

    def ft_sensor(self, name: str) -> pin.Force:
        """Force/torque reading of `tool.ft_sensors[name]`, in the sensor's site frame."""
        self._check_open()
        if name not in self._ft:
            raise unknown_name("force/torque sensor", name, self._ft, where="tool.ft_sensors")
        force, torque = self._ft[name]
        data = self._data.sensordata
        return pin.Force(data[force].copy(), data[torque].copy())

    # ------------------------------------------------------------------ lifecycle

    def _check_open(self) -> None:
        if self._scene._model is None:
            raise RuntimeError("this Robot's scene is closed")


@dataclass(frozen=True)
class AuthoredActuators:
    """The actuator parameters as compiled, before any Robot turned them into its mode."""

    gaintype: np.ndarray
    biastype: np.ndarray
    gainprm: np.ndarray
    biasprm: np.ndarray

    @classmethod
    def of(cls, model: mujoco.MjModel) -> AuthoredActuators:
        return cls(
            model.actuator_gaintype.copy(),
            model.actuator_biastype.copy(),
            model.actuator_gainprm.copy(),
            model.actuator_biasprm.copy(),
        )


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


def _view(arr: np.ndarray, idx: np.ndarray) -> np.ndarray | None:
    """A slice view of `arr` when `idx` is contiguous (no copy per read), else None."""
    if len(idx) and np.all(np.diff(idx) == 1):
        return arr[idx[0] : idx[-1] + 1]
    return None


def _readonly(arr: np.ndarray) -> np.ndarray:
    view = arr.view()
    view.flags.writeable = False
    return view
