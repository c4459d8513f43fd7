"""Hardware in the loop: a real arm moves, the rest of the scene is simulated.

`attach(scene, robot, robot_ip)` (what `Scene.create_robot(..., robot_ip=...)` and
`TaskEnv(..., robot_ip=...)` call) links a `Robot` of a scene to the arm at an address. From then
on every `scene.step()` sends the robot's command port for its mode to the arm (rate-limited,
see `connection`), waits for the arm's clock to advance by the scene's timestep, and writes the
measured joint positions and velocities into the simulated arm before and after MuJoCo's step:
the simulated arm follows the real one exactly, its contacts push the simulated objects, and
`robot.jnt_trq_msr` reads the arm's measured joint torques. Within a step its actuators only
cancel its bias forces, so it goes on at the measured velocity (the command is the arm's to
follow) and what it holds moves with it. The arm's clock is the master:
against a real arm a step takes its timestep of wall-clock time; where the arm runs ahead
(a slow loop), the simulation mirrors its latest state. In POSITION mode a `step(n)` leads
the arm from the last target to the new `jnt_pos_cmd` along its n timesteps (a policy's
command held for a control period), not in one jump: linearly, one target per 1 ms tick of the
arm (`rate_limit.DT`), whatever the scene's timestep.

HAPTIC (`haptic=True`, as the Panda environment's `Actuation.HAPTIC`): the arm is torque
controlled with what the simulated contacts do to the simulated arm — the constraint torques
on its joints (`qfrc_constraint`) times `haptic_gain`, less `haptic_damping` times the measured
joint velocities — so a person guiding the arm feels the simulated objects.
"""

from __future__ import annotations

import mujoco
import numpy as np
from gymnasium import spaces

from ..errors import SpecError
from ..robot import Robot
from ..scene import Scene, register_arm_linker
from ..spec import CtrlMode
from .connection import (
    _S_DQ,
    _S_EXT,
    _S_F,
    _S_Q,
    _S_TAU,
    _S_TIME,
    POSITION,
    TORQUE,
    VELOCITY,
    ArmConnection,
)
from .faults import ArmConnectionError, ReflexError
from .rate_limit import DT

# What a reflex in the loop most often means: the arm touched something of the arm's world
# that this scene does not simulate (the simulator's default scene has a floor, table, cube).
_LOOP_REFLEX = (
    "In the loop the arm may touch only what this scene simulates: against "
    "`python -m mjkdl.hw.franka_sim`, serve `--scene empty` (its default `--scene pick` has a "
    "floor, a table and a cube of its own that push the arm where this scene has nothing)"
)
_AFFINE = int(mujoco.mjtBias.mjBIAS_AFFINE)
_RESYNC = 0.05  # s: how far the arm may run ahead before the simulation skips to its state
_MOVE_POLL = 0.01  # s of the arm's clock between two looks at a `move_to` under way
# s: how long `move_to` holds the arm once within 2 mrad at rest: the rate limiter's last
# approach (a 50 ms time constant) has then closed all but e^-6 of the gap
_SETTLE = 0.3


def _arm_actuators(model: mujoco.MjModel, joints: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """The actuator of each arm joint (ids, gears, in joint order): one each, on the joint,
    with a fixed gain and an affine or no bias (what `ArmLink._coast` sets)."""
    ids = np.zeros(len(joints), dtype=int)
    for k, joint in enumerate(joints):
        mine = [
            a
            for a in range(model.nu)
            if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
            and model.actuator_trnid[a, 0] == joint
        ]
        name = model.joint(joint).name
        if len(mine) != 1:
            raise SpecError(
                f"robot_ip: the arm's joint {name!r} has {len(mine)} actuators; the simulated "
                "arm mirrors the arm through one actuator per joint"
            )
        a = mine[0]
        if (
            model.actuator_dyntype[a] != mujoco.mjtDyn.mjDYN_NONE
            or model.actuator_gaintype[a] != mujoco.mjtGain.mjGAIN_FIXED
            or model.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_MUSCLE
        ):
            raise SpecError(
                f"robot_ip: the actuator {model.actuator(a).name!r} of joint {name!r} must be "
                "a motor or an affine servo (no dynamics, a fixed gain) for the simulated arm "
                "to mirror the arm"
            )
        ids[k] = a
    return ids, model.actuator_gear[ids, 0].copy()


class ArmLink:
    """A `Robot` of a scene mirrored from, and commanding, the arm at an address.

    `collision_thresholds` (torque N·m, force N) are the robot's collision reflexes while
    linked: 100/100 by default, as the Panda environment's hardware in the loop sets them (the
    simulated contacts are not the robot's to stop); None keeps the robot's own. `lockstep`
    (against `python -m mjkdl.hw.franka_sim --lockstep` only: a real arm's tick cannot wait):
    each 1 ms tick of the arm waits for the command of the step it belongs to, so a run
    depends on the commands alone, not on how the processes' timing falls. `connect_timeout`:
    seconds the arm has to answer the connection."""

    def __init__(
        self,
        scene: Scene,
        robot: Robot,
        robot_ip: str,
        *,
        model: str = "panda",
        client: str | None = None,
        haptic: bool = False,
        haptic_gain: float = 0.1,
        haptic_damping: float = 2.0,
        watchdog: float = 0.2,
        realtime: bool = False,
        collision_thresholds: tuple[float, float] | None = (100.0, 100.0),
        lockstep: bool = False,
        connect_timeout: float = 20.0,
    ) -> None:
        if robot.n_joints != 7:
            raise SpecError(
                f"robot_ip: a Franka arm has 7 joints, the robot {robot.joint_names} has "
                f"{robot.n_joints}; create the robot from link0 to the hand"
            )
        if getattr(scene, "_link", None) is not None:
            raise SpecError("robot_ip: this scene already mirrors an arm; one arm per scene")
        m = scene.model
        joints = [m.joint(name) for name in robot.joint_names]
        self._qadr = np.array([int(j.qposadr[0]) for j in joints])
        self._dadr = np.array([int(j.dofadr[0]) for j in joints])
        self._coast_ids, self._coast_gear = _arm_actuators(m, [int(j.id) for j in joints])
        self._coast_f, self._coast_b, self._coast_s = np.zeros(7), np.zeros(7), np.zeros(7)
        self._coast_affine = np.zeros(7)
        self._coast_type = np.zeros(7, dtype=m.actuator_biastype.dtype)
        self.scene, self.robot = scene, robot
        self.haptic = bool(haptic)
        self.haptic_gain, self.haptic_damping = float(haptic_gain), float(haptic_damping)
        self.connection = ArmConnection(
            robot_ip,
            model,
            client=client,
            watchdog=watchdog,
            realtime=realtime,
            collision_thresholds=collision_thresholds,
            lockstep=lockstep,
            connect_timeout=connect_timeout,
        )
        self._torque = np.zeros(7)
        self._target = np.zeros(7)  # the position target sent last
        self._path = np.zeros(7)  # this step's target, on the way from it to the new one
        s = self.connection.read()
        self._arm_time = float(s[_S_TIME])
        self._target[:] = s[_S_Q : _S_Q + 7]
        self._mirror(s)
        robot.sync_commands()  # hold where the arm is
        scene._link = self

    @property
    def address(self) -> str:
        return self.connection.address

    def _mirror(self, s: np.ndarray) -> None:
        d = self.scene.data
        d.qpos[self._qadr] = s[_S_Q : _S_Q + 7]
        d.qvel[self._dadr] = s[_S_DQ : _S_DQ + 7]
        d.qfrc_actuator[self._dadr] = s[_S_TAU : _S_TAU + 7]

    def _coast(self) -> None:
        """Set the simulated arm's actuators to cancel its bias forces (gravity and Coriolis,
        MuJoCo's of the last step) over the coming step: the arm goes on at the measured
        velocity, and a held object moves with the hand as it does on the arm. Left to the
        robot's servos, the arm would lunge toward the command within each step and be pulled
        back by the next mirror, sliding a grasped cube in the fingers."""
        m, d, ids, gear = self.scene.model, self.scene.data, self._coast_ids, self._coast_gear
        force, term, state, affine = self._coast_f, self._coast_b, self._coast_s, self._coast_affine
        np.take(d.qfrc_bias, self._dadr, out=force)
        np.take(d.qfrc_gravcomp, self._dadr, out=term)
        force -= term
        force /= gear
        # an affine actuator's force is gain * ctrl + b0 + b1 * gear * q + b2 * gear * dq
        np.take(m.actuator_biastype, ids, out=self._coast_type)
        np.equal(self._coast_type, _AFFINE, out=affine)
        for col, source, at in ((1, d.qpos, self._qadr), (2, d.qvel, self._dadr)):
            np.take(source, at, out=state)
            np.take(m.actuator_biasprm[:, col], ids, out=term)
            term *= gear
            term *= state
            term *= affine
            force -= term
        np.take(m.actuator_biasprm[:, 0], ids, out=term)
        term *= affine
        force -= term
        np.take(m.actuator_gainprm[:, 0], ids, out=term)
        force /= term
        d.ctrl[ids] = force

    def _send(self, share: float, until: float) -> None:
        """This timestep's command, holding up to the arm time `until`."""
        robot, conn = self.robot, self.connection
        if self.haptic:
            d = self.scene.data
            tau = self._torque
            np.multiply(d.qfrc_constraint[self._dadr], self.haptic_gain, out=tau)
            tau -= self.haptic_damping * d.qvel[self._dadr]
            conn.send(TORQUE, tau, until)
            return
        mode = robot.ctrl_mode
        if mode is CtrlMode.POSITION:
            # A new target is reached along the control period, as the sampled command of a
            # policy means it, not as one jump the arm would take at full acceleration.
            goal, path = robot.jnt_pos_cmd, self._path
            np.subtract(goal, self._target, out=path)
            path *= share
            path += self._target
            conn.send(POSITION, path, until)
            if share == 1.0:
                self._target[:] = goal
        elif mode is CtrlMode.VELOCITY:
            conn.send(VELOCITY, robot.jnt_vel_cmd, until)
        elif robot.gravity_compensation:  # the arm compensates gravity itself
            conn.send(TORQUE, robot.jnt_trq_cmd, until)
        else:  # a torque that holds gravity (the Robot's TORQUE semantics): less the gravity
            np.subtract(robot.jnt_trq_cmd, robot.gravity_torques(), out=self._torque)
            conn.send(TORQUE, self._torque, until)

    def step(self, n: int) -> None:
        """`n` timesteps: each sends the command, steps MuJoCo, then mirrors the arm's state
        one timestep of the arm's clock later. A POSITION target goes along the n timesteps
        one arm tick (1 ms) at a time: a timestep of several ticks sends one target per tick,
        each once the arm's clock reached that tick."""
        model, data = self.scene.model, self.scene.data
        dt = model.opt.timestep
        conn = self.connection
        position = self.robot.ctrl_mode is CtrlMode.POSITION and not self.haptic
        ticks = max(1, round(dt / DT)) if position else 1
        try:
            for k in range(n):
                conn.check()
                for j in range(1, ticks):  # this timestep's ticks before its last
                    tick = self._arm_time + j * dt / ticks
                    self._send((k * ticks + j) / (n * ticks), tick)
                    conn.wait_until(tick)
                self._send((k + 1) / n, self._arm_time + dt)
                self._coast()
                mujoco.mj_step(model, data)
                self._arm_time += dt
                s = conn.wait_until(self._arm_time)
                if s[_S_TIME] > self._arm_time + _RESYNC:
                    self._arm_time = float(s[_S_TIME])
                self._mirror(s)
        except ReflexError as err:
            raise ReflexError(f"{err}. {_LOOP_REFLEX}") from err

    def refresh(self) -> None:
        """Report what the loop said since the last call (a fault raises, a stall warns) and
        mirror the arm's latest state: the measured ports read it whatever the user's loop did
        meanwhile (a stall the watchdog ended leaves the arm at rest elsewhere)."""
        conn = self.connection
        conn.check()
        s = conn.read()
        self._arm_time = float(s[_S_TIME])
        self._mirror(s)

    def move_to(self, q: np.ndarray, timeout: float = 30.0) -> None:
        """Bring the arm to joint positions `q` (rate-limited), let it settle there for
        `_SETTLE` s, and the simulated arm with it; the robot's commands then hold there
        (POSITION mode). Settled, the arm starts what follows from `q` at rest whatever
        motion came before (the last approach ends within a few µrad)."""
        robot, conn = self.robot, self.connection
        robot.ctrl_mode = CtrlMode.POSITION
        target = np.asarray(q, dtype=float)
        s = conn.read()
        conn.send(POSITION, target, s[_S_TIME] + _MOVE_POLL)
        t_end = s[_S_TIME] + timeout
        settled = np.inf  # the arm time it came within reach, at rest
        while True:
            s = conn.wait_until(s[_S_TIME] + _MOVE_POLL)
            err = np.abs(s[_S_Q : _S_Q + 7] - target).max()
            if settled == np.inf and err < 2e-3 and np.abs(s[_S_DQ : _S_DQ + 7]).max() < 1e-2:
                settled = s[_S_TIME]
            if s[_S_TIME] >= settled + _SETTLE - 1e-9:
                break  # the last command held up to now: a lockstep arm waits for the next
            if s[_S_TIME] > t_end:
                raise ArmConnectionError(
                    f"the arm at {self.address} did not reach {target.round(3).tolist()} within "
                    f"{timeout} s of its clock (still {err:.4f} rad away); check its mode"
                )
            conn.send(POSITION, target, s[_S_TIME] + _MOVE_POLL)
        self._arm_time = float(s[_S_TIME])
        self._target[:] = target
        self._mirror(s)
        mujoco.mj_forward(self.scene.model, self.scene.data)
        self._mirror(s)  # mj_forward recomputed qfrc_actuator
        robot.sync_commands()

    def external_forces(self) -> tuple[np.ndarray, np.ndarray]:
        """(tau_ext_hat_filtered (7), O_F_ext_hat_K (6)): what the arm estimates is pushing it."""
        s = self.connection.read()
        return s[_S_EXT : _S_EXT + 7].copy(), s[_S_F : _S_F + 6].copy()

    def close(self) -> None:
        """Bring the arm to rest and close the connection; the scene simulates on its own."""
        if getattr(self.scene, "_link", None) is self:
            self.scene._link = None
        self.connection.close()


def attach(scene: Scene, robot: Robot, robot_ip: str, **options: object) -> ArmLink:
    """Link `robot` of `scene` to the arm at `robot_ip` (see `ArmLink` for the options)."""
    return ArmLink(scene, robot, robot_ip, **options)  # type: ignore[arg-type]


class ExternalForces:
    """A `TaskSpec` sensor: the arm's measured external torques and wrench, as observations
    `{arm}_ext_torques` (7, N·m) and `{arm}_ext_wrench` (6: force N, torque N·m, base frame)."""

    def __init__(self, arm: str) -> None:
        self.arm = arm

    def space(self, env: object) -> dict[str, spaces.Box]:
        return {
            f"{self.arm}_ext_torques": spaces.Box(-np.inf, np.inf, (7,), np.float64),
            f"{self.arm}_ext_wrench": spaces.Box(-np.inf, np.inf, (6,), np.float64),
        }

    def read(self, env: object) -> dict[str, np.ndarray]:
        link = getattr(env, "hardware", None)
        if link is None:
            zero = np.zeros(13)
            return {f"{self.arm}_ext_torques": zero[:7], f"{self.arm}_ext_wrench": zero[7:]}
        tau, wrench = link.external_forces()
        return {f"{self.arm}_ext_torques": tau, f"{self.arm}_ext_wrench": wrench}


register_arm_linker(attach)
