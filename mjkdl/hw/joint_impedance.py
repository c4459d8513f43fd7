"""The Franka robot's joint-impedance control, one implementation for the simulated arm behind
the protocol (`mjkdl.hw.franka_sim`) and for a task env's Franka arm
(`arm_drive="franka_impedance"`), so that the same commands give the same motion in both.

The chain a position command takes to an arm in the loop: the control period's target is
reached along its 1 ms ticks (`ArmLink`), each tick's position goes through the connection's
rate limiter (`RateLimiter.position`), and the robot tracks it with its joint impedance.
`FrankaImpedanceDrive` runs that chain in a simulation.
"""

from __future__ import annotations

import numpy as np

from ..errors import SpecError
from ..robot import Robot
from ..scene import Env
from ..spec import CtrlMode
from .rate_limit import DT, RateLimiter, limits_for

# The robot's defaults (Franka's documentation; libfranka's examples set the same).
JOINT_STIFFNESS = np.array([3000.0, 3000.0, 3000.0, 2500.0, 2500.0, 2000.0, 2000.0])
# The arms' joint torque limits (N·m), the same for the Panda and the FR3.
TAU_MAX = np.array([87.0] * 4 + [12.0] * 3)
# libfranka's examples start from this pose ("move to start"); the simulated arm boots in it,
# and its joint-space inertia there sets the impedance's damping.
START_Q = np.array([0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4])
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
        damp = self._damp
        np.multiply(self.stiffness, self._mass, out=damp)
        np.sqrt(damp, out=damp)
        damp *= 2.0
        return damp

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
    steps, rate-limited as the connection limits it, and tracked by `JointImpedance` with
    gravity compensated. The scene's timestep must be 1 ms, the robot's tick. `latency`: ticks
    each period's target comes late (a command delayed on its way to the robot): the last
    period's ramp goes on that long, below one period."""

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
        self.limiter = RateLimiter(limits_for(model))
        self.impedance = JointImpedance(np.diag(robot.mass_matrix(START_Q)))
        self.latency = 0
        self.bind_state(np.zeros(STATE_SIZE))
        self._goal = np.zeros(7)
        self._tau = np.zeros(7)
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
        np.subtract(self._goal, self._target, out=self._tau)
        np.multiply(self._tau, this, out=path[late:])
        path[late:] += self._target
        np.subtract(self._target, self._previous, out=self._tau)
        np.multiply(self._tau, last, out=path[:late])
        path[:late] += self._previous
        return self._ticks

    def run(self, n: int) -> None:
        """`n` physics steps that bring the arm to the robot's `jnt_pos_cmd`; the robot is left
        in POSITION mode with that command (what the Cartesian controller integrates)."""
        robot, limiter, impedance, tau = self.robot, self.limiter, self.impedance, self._tau
        goal, target = self._goal, self._target
        goal[:] = robot.jnt_pos_cmd
        limiter.start_ticks = int(self._state[_TICKS])
        # The limiter's ticks depend on the commands only, not on the arm: all of them first.
        path, q_d, dq_d = self._ramp(n)
        limiter.positions(path, q_d, dq_d)
        robot.ctrl_mode = CtrlMode.TORQUE
        step, update, gravity = self.scene.step, robot.update, robot.gravity_torques
        q, dq = robot.jnt_pos_msr, robot.jnt_vel_msr  # refreshed in place by update()
        damping, torque = impedance.damping(), impedance.torque
        for k in range(n):
            update()
            np.add(torque(q_d[k], dq_d[k], q, dq, damping), gravity(), out=tau)
            robot.jnt_trq_cmd = tau
            step(1)
        self._previous[:] = target
        target[:] = goal
        self._state[_TICKS] = limiter.start_ticks
        robot.ctrl_mode = CtrlMode.POSITION
        robot.jnt_pos_cmd = goal
