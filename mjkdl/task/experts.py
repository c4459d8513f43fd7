"""Scripted experts for the registered tasks: closed-loop policies on the observation.

`expert_for(env)` gives the expert of a registered task (`mjkdl/PandaReach-v0`, ...): call
`reset()` at each episode's start, then `expert(obs)` for the action of each step. They see
only what the policy sees (positions, orientations, the gripper's opening, finger contacts),
so a learner could match them; the tests hold them to >= 95 % success over 100 seeds, and
demonstration collection records them.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Mapping
from typing import Any, Protocol

import gymnasium as gym
import numpy as np

from ..errors import SpecError, UnknownNameError
from .env import TaskEnv
from .goal import GoalTaskEnv
from .registry import CUBE_HALF, LIFT, TASKS
from .spec import Actuation

_DOWN = np.array([0.0, 0.0, -1.0])
GRASP_RAISE = 0.004  # m: the TCP over a floor cube's centre at the grasp (fingertips clear)
# The pick experts' approach gain (1/s) for an arm that moves as a Franka arm does
# (`arm_drive="franka_impedance"`, or the arm in the loop): it lags its target by about a
# control period and the rate limiter's 50 ms, so at the servos' 5/s it runs past the grasp
# height into the table.
FRANKA_GAIN = 3.0
# The carry's gain (1/s) on such an arm: at the servos' 10/s, a gain over a control period and
# the arm's lag is past what stays stable: the carried cube swings over the goal and down.
FRANKA_LIFT_GAIN = 4.0
# The push's speed (m/s) on such an arm: pressing on a cube that resists, the lagging arm
# builds up a lead on its target, which it makes up in one leap when the cube gives way: at
# 0.2 m/s that shoved a cube 4 cm past the goal after it had arrived (Push seed 28).
FRANKA_PUSH_SPEED = 0.15


class Expert(Protocol):
    """A scripted policy: `reset()` at an episode's start, `expert(obs)` -> action."""

    def reset(self) -> None: ...

    def __call__(self, obs: Mapping[str, np.ndarray]) -> np.ndarray: ...


class _Cartesian:
    """Turns a TCP velocity (world, m/s and rad/s) and a gripper command into the normalised
    action of a registered task: each entry divided by the arm's bound, clipped to [-1, 1]."""

    def __init__(self, env: TaskEnv) -> None:
        arm = env.task_spec.arms[0]
        self.scale = np.array(
            [arm.max_linear_velocity] * 3 + [arm.max_angular_velocity] * 3, dtype=float
        )
        self.axes = env.effectors[0].axes
        self.gripper = env.effectors[0].grip_index >= 0  # False: held, no entry
        self.period = env.control_timestep
        self.goal_keys: list[tuple[str, int]] = []
        if isinstance(env, GoalTaskEnv):
            self.goal_keys = env.observation_layout

    def action(self, twist: np.ndarray, close: bool) -> np.ndarray:
        """The twist's entries the arm's action holds (`cartesian_axes`), then the gripper
        unless it is held (`GripperSpec.held`)."""
        n = len(self.axes)
        out = np.empty(n + self.gripper, dtype=np.float32)
        out[:n] = np.clip(twist / self.scale, -1.0, 1.0)[self.axes]
        if self.gripper:
            out[n] = 1.0 if close else -1.0
        return out

    def named(self, obs: Mapping[str, np.ndarray]) -> Mapping[str, np.ndarray]:
        """A goal-conditioned observation split back into its named parts."""
        if not self.goal_keys:
            return obs
        out: dict[str, np.ndarray] = {}
        start = 0
        for key, size in self.goal_keys:
            out[key] = obs["observation"][start : start + size]
            start += size
        out["desired_goal"] = obs["desired_goal"]
        return out


def _upright(
    quat: np.ndarray, yaw_gain: float, target_yaw: float | None, period: float = math.pi / 2
) -> np.ndarray:
    """Angular velocity turning the TCP's z axis to point down and, when `target_yaw` is
    given, its x axis to that yaw modulo `period` (90 degrees: the finger axis (y) square
    to a cube side)."""
    w, x, y, z = quat
    # Columns of the rotation matrix of quaternion [w, x, y, z].
    x_axis = np.array([1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)])
    z_axis = np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])
    omega = 4.0 * np.cross(z_axis, _DOWN)
    if target_yaw is not None:
        yaw = math.atan2(x_axis[1], x_axis[0])
        err = (target_yaw - yaw + period / 2) % period - period / 2
        omega[2] += yaw_gain * err
    return omega


def _yaw(quat: np.ndarray) -> float:
    """Heading of a body that stands upright (rotation about the world z)."""
    w, x, y, z = quat
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


class ReachExpert:
    """Moves the TCP straight at the goal, slowing down as it closes in; gripper open."""

    def __init__(self, env: TaskEnv, gain: float = 4.0) -> None:
        self._out = _Cartesian(env)
        self._gain = gain

    def reset(self) -> None:
        """Nothing to forget between episodes."""

    def __call__(self, obs: Mapping[str, np.ndarray]) -> np.ndarray:
        o = self._out.named(obs)
        tcp = o["panda_tcp_pos"]
        goal = o["desired_goal"] if "desired_goal" in o else o["goal_pose"][:3]
        twist = np.zeros(6)
        twist[:3] = self._gain * (goal - tcp)
        twist[3:] = _upright(o["panda_tcp_quat"], 0.0, None)
        return self._out.action(twist, close=False)


class _Phase(enum.Enum):
    ABOVE = "above"  # over the cube, turning square to it
    DESCEND = "descend"
    CLOSE = "close"
    LIFT = "lift"
    RELEASE = "release"  # Stack: open over the base, then back up


class PickCubeExpert:
    """Over the cube, square to its sides; down; close; lift 8 cm (or carry it to the goal
    of PickAndPlace and the goal-conditioned variants) at the twist limit until 5 cm out
    (`lift_gain`, 1/s). Starts over when the cube slips out. `gain` (1/s): the approach's;
    by default 5, or `FRANKA_GAIN` where the arm moves as a Franka arm does."""

    def __init__(
        self,
        env: TaskEnv,
        gain: float | None = None,
        hover: float = 0.08,
        lift_gain: float | None = None,
    ) -> None:
        self._out = _Cartesian(env)
        franka = env.drive is not None or env.hardware is not None
        if gain is None:  # 5/s, or FRANKA_GAIN for an arm that moves as a Franka arm does
            gain = FRANKA_GAIN if franka else 5.0
        if lift_gain is None:
            lift_gain = FRANKA_LIFT_GAIN if franka else 10.0
        self._gain, self._hover, self._lift_gain = gain, hover, lift_gain
        # The Panda's fingertips reach 21 mm below its TCP: grasping a cube on the floor at
        # its centre would press them into the floor (a real table), so grasp above it.
        self._grasp_offset = np.array([0.0, 0.0, GRASP_RAISE])
        names = env.observation_space.spaces
        self._goal = "desired_goal" if "desired_goal" in names else "target_pose"
        self.reset()

    def reset(self) -> None:
        """Start from the approach."""
        self.phase = _Phase.ABOVE
        self._closing = 0
        self._lift_from = np.zeros(3)

    def __call__(self, obs: Mapping[str, np.ndarray]) -> np.ndarray:
        o = self._out.named(obs)
        tcp, quat = o["panda_tcp_pos"], o["panda_tcp_quat"]
        cube = o["cube_pose"][:3]
        held = bool(np.all(o["cube_contacts"] > 0.5))
        square, period = self._grasp_yaw(o)
        if self.phase is _Phase.LIFT and not held and cube[2] < CUBE_HALF + 0.01:
            self.phase = _Phase.ABOVE  # dropped: try again
        target = cube + np.array([0.0, 0.0, self._hover])
        close = False
        if self.phase is _Phase.ABOVE:
            err = target - tcp
            yaw_err = _upright(quat, 1.0, square, period)[2]
            if math.hypot(err[0], err[1]) < 0.01 and abs(err[2]) < 0.02 and abs(yaw_err) < 0.05:
                self.phase = _Phase.DESCEND
        if self.phase is _Phase.DESCEND:
            target = cube + self._grasp_offset
            if np.linalg.norm(target - tcp) < 0.01:
                self.phase, self._closing = _Phase.CLOSE, 0
        if self.phase is _Phase.CLOSE:
            target, close = cube + self._grasp_offset, True
            self._closing += 1
            if self._closing >= 4 and held:
                self.phase = _Phase.LIFT
                self._lift_from = tcp.copy()  # straight up from here: the cube moves with us
            elif self._closing >= 10:
                self.phase = _Phase.ABOVE  # closed on nothing: reopen
        if self.phase is _Phase.LIFT:
            close = True
            target = self._carry(o, tcp, cube)
        if self.phase is _Phase.RELEASE:
            target = tcp + np.array([0.0, 0.0, 0.05 if self._closing > 3 else 0.0])
            self._closing += 1
        twist = np.zeros(6)
        # Carry at the twist limit until 5 cm out (`lift_gain`): the grasp holds at full
        # speed with the tasks' contact options (PhysicsOptions.grasping(), docs/physics.md).
        gain = self._gain if self.phase is not _Phase.LIFT else self._lift_gain
        twist[:3] = gain * (target - tcp)
        # Square to the cube until the fingers close on it; then only keep the hand upright.
        carrying = self.phase in (_Phase.LIFT, _Phase.RELEASE)
        twist[3:] = _upright(quat, 4.0, None if carrying else square, period)
        return self._out.action(twist, close=close)

    def _grasp_yaw(self, o: Mapping[str, np.ndarray]) -> tuple[float, float]:
        """The hand's yaw for the grasp and its period: square to the cube's sides."""
        return _yaw(o["cube_pose"][3:]), math.pi / 2

    def _carry(self, o: Mapping[str, np.ndarray], tcp: np.ndarray, cube: np.ndarray) -> np.ndarray:
        """Where the TCP heads once the cube is held: straight to the goal with the cube
        (goal tasks), else straight up."""
        if self._goal in o:
            return o[self._goal][:3] + (tcp - cube)
        return self._lift_from + np.array([0.0, 0.0, LIFT + 0.03])


class StackExpert(PickCubeExpert):
    """PickCube's grasp, the fingers closing across the line to the base cube so neither
    touches it; up to a clearance over the target, across, down onto it, open, back up."""

    CLEARANCE = 0.03

    def _grasp_yaw(self, o: Mapping[str, np.ndarray]) -> tuple[float, float]:
        cube, base = o["cube_pose"], o[self._goal]
        away = math.atan2(base[1] - cube[1], base[0] - cube[0])
        square = _yaw(cube[3:])
        # Of the cube's four sides, the hand's x axis (between the fingers' faces) along
        # the line to the base: the fingers close across it.
        best = min(
            (square + k * math.pi / 2 for k in range(4)),
            key=lambda y: abs((y - away + math.pi / 2) % math.pi - math.pi / 2),
        )
        return best, math.pi

    def _carry(self, o: Mapping[str, np.ndarray], tcp: np.ndarray, cube: np.ndarray) -> np.ndarray:
        goal = o[self._goal][:3]
        aim = goal.copy()
        if math.hypot(*(goal - cube)[:2]) > 0.006:
            aim[2] += self.CLEARANCE  # across at a clearance over the base
            if cube[2] < goal[2] + 0.6 * self.CLEARANCE:
                aim[:2] = cube[:2]  # up first
        elif np.linalg.norm(goal - cube) < 0.006:
            self.phase, self._closing = _Phase.RELEASE, 0
        return aim + (tcp - cube)


class PushExpert:
    """Gripper closed; over a point behind the cube on the line from the goal, down to the
    floor, then pushes the cube along that line; backs up and realigns when it drifts."""

    BEHIND = 0.06  # metres behind the cube's centre to start from
    LOW = 0.022  # TCP height while pushing: the fingertips clear the floor
    # m/s at most: at 0.3 m/s a cube shoved by the Franka Hand's firm closed fingers
    # (GripperDrive) could cross the goal window (`THERE`) within one control step.
    SPEED = 0.2
    THERE = 0.015  # metres from the goal at which the push ends

    def __init__(self, env: TaskEnv, gain: float | None = None) -> None:
        self._out = _Cartesian(env)
        franka = env.drive is not None or env.hardware is not None
        if gain is None:  # 5/s, or FRANKA_GAIN for an arm that moves as a Franka arm does
            gain = FRANKA_GAIN if franka else 5.0
        self._gain = gain
        self._speed = FRANKA_PUSH_SPEED if franka else self.SPEED
        names = env.observation_space.spaces
        self._goal = "desired_goal" if "desired_goal" in names else "goal_pose"
        self.reset()

    def reset(self) -> None:
        """Start from the approach."""
        self.pushing = False
        self.rest: np.ndarray | None = None

    def __call__(self, obs: Mapping[str, np.ndarray]) -> np.ndarray:
        o = self._out.named(obs)
        tcp, quat = o["panda_tcp_pos"], o["panda_tcp_quat"]
        cube, goal = o["cube_pose"][:3], o[self._goal][:3]
        line = (goal - cube)[:2]
        dist = float(np.linalg.norm(line))
        d = np.append(line / max(dist, 1e-9), 0.0)
        rel = (tcp - cube)[:2]
        along = float(rel @ d[:2])
        across = abs(float(rel[0] * d[1] - rel[1] * d[0]))
        start = cube - d * self.BEHIND
        if self.pushing and dist < self.THERE and self.rest is None:
            # there: done, before anything reads as a slip (an arm that lags its target, as a
            # Franka arm does, is still moving on when the cube arrives)
            self.rest = tcp + np.array([0.0, 0.0, 0.08])
        if self.pushing and self.rest is None and (across > 0.012 or along > -CUBE_HALF):
            self.pushing = False  # slipped past or beside the cube: realign
        if not self.pushing:
            target = np.array([start[0], start[1], self.LOW])
            if math.hypot(*(tcp - target)[:2]) > 0.01:
                target[2] = CUBE_HALF * 2 + 0.05  # over the cube's height until behind it
            elif abs(tcp[2] - self.LOW) < 0.008:
                self.pushing = True
        if self.pushing:
            # A point a few centimetres past the cube's near face, on the line to the goal:
            # the TCP follows the cube as it moves and turns; it stops once the cube is there.
            target = cube - d * (CUBE_HALF + 0.012) + d * min(dist, 0.05)
            target[2] = self.LOW
        if self.rest is not None:
            target = self.rest  # back off upwards, clear of the cube
        twist = np.zeros(6)
        v = self._gain * (target - tcp)
        speed = float(np.linalg.norm(v))
        # Scaled as a whole, not clipped per axis: the push keeps its direction.
        twist[:3] = v if speed <= self._speed else v * (self._speed / speed)
        twist[3:] = _upright(quat, 0.0, None)
        return self._out.action(twist, close=True)


_EXPERTS: dict[str, type[Any]] = {
    "mjkdl/PandaReach-v0": ReachExpert,
    "mjkdl/PandaReachGoal-v0": ReachExpert,
    "mjkdl/PandaPickCube-v0": PickCubeExpert,
    "mjkdl/PandaPickCubeGoal-v0": PickCubeExpert,
    "mjkdl/PandaPush-v0": PushExpert,
    "mjkdl/PandaPushGoal-v0": PushExpert,
    "mjkdl/PandaPickAndPlace-v0": PickCubeExpert,
    "mjkdl/PandaPickAndPlaceGoal-v0": PickCubeExpert,
    "mjkdl/PandaStack-v0": StackExpert,
    "mjkdl/PandaStackGoal-v0": StackExpert,
}


def expert_for(env: gym.Env) -> Expert:
    """The scripted expert of a registered task (`env` may be wrapped)."""
    inner = env.unwrapped
    for env_id, cls in TASKS.items():
        if type(inner) is cls:
            mode = inner.task_spec.arms[0].actuation
            if mode is not Actuation.CARTESIAN_VELOCITY:
                raise SpecError(
                    f"the experts act in Cartesian velocity; this {env_id} env has "
                    f"actuation={mode.value!r} (make it without `actuation`)"
                )
            return _EXPERTS[env_id](inner)
    raise UnknownNameError(
        f"no expert for {type(inner).__name__}; experts exist for {', '.join(_EXPERTS)}"
    )
