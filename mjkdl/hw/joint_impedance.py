"""The Franka robot's joint-impedance control, one law for the simulated arm behind the
protocol (`mjkdl.hw.franka_sim`) and for a task env's Franka arm
(`arm_drive="franka_impedance"`), so that the same commands give the same motion in both.

The law's gains, damping rule and torque limits are `JointImpedanceDrive.franka()`'s. The
server's arm evaluates it tick by tick (`JointImpedance.torque`: it switches controllers and
reports the torques); a task env's arm has it built into its actuators (`RobotSpec.impedance`),
where MuJoCo evaluates it, its weight cancelled by MuJoCo's `gravcomp`.

The chain a position command takes to an arm in the loop: the control period's target is
reached along its 1 ms ticks (`ArmLink`), each tick's position goes through the connection's
rate limiter (`RateLimiter.position`), and the robot tracks it with its joint impedance.
`FrankaImpedanceDrive` runs that chain in a simulation.
"""

from __future__ import annotations

import mujoco
import numpy as np

from ..errors import SpecError
from ..impedance_drive import critical_damping
from ..robot import Robot
from ..scene import Env
from ..spec import JointImpedanceDrive
from .rate_limit import DT, RateLimiter, limits_for

FRANKA = JointImpedanceDrive.franka()
# The robot's defaults (Franka's documentation; libfranka's examples set the same).
JOINT_STIFFNESS = np.array(FRANKA.stiffness)
# The arms' joint torque limits (N·m), the same for the Panda and the FR3.
TAU_MAX = np.array(FRANKA.torque_limit)
# libfranka's examples start from this pose ("move to start"); the simulated arm boots in it,
# and its joint-space inertia there sets the impedance's damping.
START_Q = np.array(FRANKA.damping_pose)
# What `FrankaImpedanceDrive` carries between control periods (`bind_state`): five 7-vectors
# (target, previous target, the rate limiter's q, dq, ddq), then the limiter's start ticks.
_TICKS = 5 * 7
STATE_SIZE = _TICKS + 1


class JointImpedance:
    """The robot's joint-impedance law: tau = K (q_d - q) + D (dq_d - dq), clipped to the
    torque limits, with D = 2 sqrt(K m) per joint (critical damping of each joint's own
    inertia m, the mass matrix's diagonal at `START_Q`). Gravity is not in it: the robot
    compensates it on its own. `stiffness` (N·m/rad) is the robot's setting, changeable."""

    def __init__(self, mass_diag: np.ndarray, tau_max: np.ndarray = TAU_MAX) -> None:
        self._mass = np.array(mass_diag, dtype=float)
        self._tau_max = np.array(tau_max, dtype=float)
        self._tau_min = -self._tau_max
        self.stiffness = JOINT_STIFFNESS.copy()
        self._out = np.zeros(7)
        self._damp = np.zeros(7)
        self._rate = np.zeros(7)

    def damping(self) -> np.ndarray:
        """D = 2 sqrt(K m) at the current `stiffness`; an array owned here."""
        return critical_damping(self.stiffness, self._mass, out=self._damp)

    def torque(
        self,
        q_d: np.ndarray,
        dq_d: np.ndarray,
        q: np.ndarray,
        dq: np.ndarray,
        damping: np.ndarray | None = None,
    ) -> np.ndarray:
        """The joint torques for the setpoint (`q_d`, `dq_d`) at the state (`q`, `dq`); an
        array owned here, overwritten by the next call. `damping`: `damping()`'s result when
        the stiffness has not changed since (a loop of many ticks), else it is computed."""
        out, rate = self._out, self._rate
        np.subtract(dq_d, dq, out=rate)
        rate *= self.damping() if damping is None else damping
        np.subtract(q_d, q, out=out)
        out *= self.stiffness
        out += rate
        np.maximum(out, self._tau_min, out=out)
        np.minimum(out, self._tau_max, out=out)
        return out


class FrankaImpedanceDrive:
    """A simulated 7-joint Franka arm driven as the arm in the loop is: each control period
    the robot's position target (`jnt_pos_cmd`) is reached along the period's 1 ms physics
    steps, rate-limited as the connection limits it, and tracked by the joint impedance its
    actuators carry (the scene built with `RobotSpec(impedance=JointImpedanceDrive.franka())`),
    gravity cancelled by MuJoCo. The scene's timestep must be 1 ms, the robot's tick.
    `latency`: ticks each period's target comes late (a command delayed on its way to the
    robot): the last period's ramp goes on that long, below one period."""

    def __init__(self, scene: Env, robot: Robot, model: str = "panda") -> None:
        if robot.n_joints != 7:
            raise SpecError(
                f"arm_drive: a Franka arm has 7 joints, the robot {robot.joint_names} has "
                f"{robot.n_joints}"
            )
        if abs(scene.timestep() - DT) > 1e-12:
            raise SpecError(
                f"arm_drive: the Franka impedance runs at the robot's 1 kHz; the scene's "
                f"timestep is {scene.timestep():g} s, it must be {DT:g} s"
            )
        self.scene, self.robot = scene, robot
        self._ids = robot.actuator_ids
        _check_impedance(scene, robot, self._ids)
        lo = int(self._ids[0])
        contiguous = np.array_equal(self._ids, np.arange(lo, lo + 7))
        # the arm's controls: a slice (a plain copy per tick) where they are contiguous
        self._controls: slice | np.ndarray = slice(lo, lo + 7) if contiguous else self._ids
        self.limiter = RateLimiter(limits_for(model))
        self.latency = 0
        self.bind_state(np.zeros(STATE_SIZE))
        self._goal = np.zeros(7)
        self._scratch = np.zeros(7)
        self._ratio = np.zeros(7)
        self._ticks: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._late = 0
        self._shares = (np.zeros((0, 1)), np.zeros((0, 1)))

    def bind_state(self, state: np.ndarray) -> None:
        """Keep what the drive carries from one control period to the next in `state`
        (`STATE_SIZE` entries, a view of MuJoCo's userdata in a task env, so that
        `mjSTATE_INTEGRATION` holds it): the last period's target, where this one's ramp
        starts, the one before (where the last ramp started, for `latency`), and the rate
        limiter's position, velocity, acceleration and start ticks."""
        limiter = self.limiter
        self._state = state
        self._target, self._previous = state[0:7], state[7:14]
        views = [state[7 * i : 7 * i + 7] for i in (2, 3, 4)]
        for view, now in zip(views, (limiter.q, limiter.dq, limiter.ddq), strict=True):
            np.copyto(view, now)
        limiter.bind(*views)  # the limiter works in place: on userdata now
        state[_TICKS] = limiter.start_ticks

    def start(self) -> None:
        """An episode's start: the arm at rest where it is, the target there."""
        robot = self.robot
        robot.update()
        self._target[:] = robot.jnt_pos_msr
        self._previous[:] = self._target
        self.limiter.reset(self._target)
        self._state[_TICKS] = self.limiter.start_ticks

    def _ramp(self, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The n ticks' targets of this period, from the last period's target to this one's
        (`latency` ticks late: the last period's ramp first), and room for the rate limiter's
        positions and velocities."""
        if self._ticks is None or len(self._ticks[0]) != n or self._late != self.latency:
            late = self._late = self.latency
            k = np.arange(n)
            # the share of the way each tick is at: this period's ramp, the last one's
            this = ((k - late + 1) / n)[:, None]
            last = ((n + k - late + 1) / n)[:, None]
            self._shares = (this[late:], last[:late])
            self._ticks = (np.zeros((n, 7)), np.zeros((n, 7)), np.zeros((n, 7)))
        path = self._ticks[0]
        this, last = self._shares
        late = self._late
        np.subtract(self._goal, self._target, out=self._scratch)
        np.multiply(self._scratch, this, out=path[late:])
        path[late:] += self._target
        np.subtract(self._target, self._previous, out=self._scratch)
        np.multiply(self._scratch, last, out=path[:late])
        path[:late] += self._previous
        return self._ticks

    def run(self, n: int) -> None:
        """`n` physics steps that bring the arm to the robot's `jnt_pos_cmd`; the robot is left
        in POSITION mode with that command (what the Cartesian controller integrates)."""
        robot, limiter, scene = self.robot, self.limiter, self.scene
        goal, target, ratio = self._goal, self._target, self._ratio
        goal[:] = robot.jnt_pos_cmd
        limiter.start_ticks = int(self._state[_TICKS])
        # The limiter's ticks depend on the commands only, not on the arm: all of them first.
        path, q_d, dq_d = self._ramp(n)
        limiter.positions(path, q_d, dq_d)
        # Each tick's setpoint q_d + (D / K) dq_d, at the gains the actuators hold now (an
        # episode's draw scales K and D together): the ramp's rows are free for them.
        bias = scene.model.actuator_biasprm
        np.take(bias[:, 2], self._ids, out=ratio)
        np.take(bias[:, 1], self._ids, out=self._scratch)
        ratio /= self._scratch
        np.multiply(dq_d, ratio, out=path)
        path += q_d
        robot.update()  # the robot's pending command goes out; the setpoints replace it
        ctrl, controls, step = scene.data.ctrl, self._controls, scene.step
        for k in range(n):
            ctrl[controls] = path[k]
            step(1)
        self._previous[:] = target
        target[:] = goal
        self._state[_TICKS] = limiter.start_ticks
        robot.jnt_pos_cmd = goal


def _check_impedance(scene: Env, robot: Robot, ids: np.ndarray) -> None:
    """The arm's actuators are a joint impedance (gear 1, torque-limited) and MuJoCo
    cancels its weight through them: what `RobotSpec.impedance` builds."""
    m = scene.model
    joints = [m.joint(name).id for name in robot.joint_names]
    fixed, affine = int(mujoco.mjtGain.mjGAIN_FIXED), int(mujoco.mjtBias.mjBIAS_AFFINE)
    odd = [
        m.actuator(a).name
        for a, j in zip(ids, joints, strict=True)
        if int(m.actuator_gaintype[a]) != fixed
        or int(m.actuator_biastype[a]) != affine
        or m.actuator_gear[a, 0] != 1.0
        or m.actuator_biasprm[a, 1] != -m.actuator_gainprm[a, 0]
        or not m.actuator_forcelimited[a]
        or not m.jnt_actgravcomp[j]
    ]
    if odd:
        raise SpecError(
            f"arm_drive: the arm's actuators {odd} are not a joint impedance with gravity "
            "compensated; build the scene with "
            "RobotSpec(impedance=JointImpedanceDrive.franka())"
        )
