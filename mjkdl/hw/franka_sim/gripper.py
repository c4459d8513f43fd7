"""The Franka Hand on the simulated fingers: homing, move, grasp with the real gripper's
success semantics (the fingers stop within `[width - epsilon_inner, width + epsilon_outer]`),
stop, and the state it streams."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mjkdl.scene import Env

from . import wire

MAX_WIDTH = 0.08  # Franka Hand, between the fingers
MAX_SPEED = 0.1  # m/s (datasheet: 0.05 m/s per finger)
SETTLE_S = 0.05  # the fingers count as stopped after this long without moving


@dataclass
class _Job:
    command: int
    command_id: int
    target: float  # width the fingers are driven to
    speed: float
    grasp: tuple[float, float, float] | None = None  # width, epsilon inner, epsilon outer
    still_s: float = 0.0


class SimulatedHand:
    """Drives Menagerie's hand actuator (`actuator8`, a position servo on the finger tendon)."""

    def __init__(self, env: Env) -> None:
        m = env.model
        self._env = env
        self._act = m.actuator("actuator8").id
        self._fingers = [m.jnt_qposadr[m.joint(n).id] for n in ("finger_joint1", "finger_joint2")]
        self._finger_dofs = [
            m.jnt_dofadr[m.joint(n).id] for n in ("finger_joint1", "finger_joint2")
        ]
        self._ctrl_per_width = m.actuator_ctrlrange[self._act, 1] / MAX_WIDTH
        self._default_force = m.actuator_forcerange[self._act].copy()
        self.setpoint = self.width
        self.job: _Job | None = None
        self.grasped: tuple[float, float, float] | None = None
        self.max_width = MAX_WIDTH

    @property
    def width(self) -> float:
        return float(sum(self._env.data.qpos[self._fingers]))

    def start(self, command: int, command_id: int, payload: bytes) -> int | None:
        """Begin a command; returns a status to reply now, or None when it replies on finishing."""
        if command == wire.GRIPPER_HOMING:
            self._begin(_Job(command, command_id, MAX_WIDTH, MAX_SPEED), self._default_force[1])
        elif command == wire.GRIPPER_MOVE:
            width, speed = wire.GRIPPER_MOVE_REQUEST.unpack_from(payload)
            if not (0.0 <= width <= MAX_WIDTH and 0.0 < speed <= MAX_SPEED):
                return wire.GRIPPER_FAIL
            self._begin(_Job(command, command_id, width, speed), self._default_force[1])
        elif command == wire.GRIPPER_GRASP:
            width, eps_in, eps_out, speed, force = wire.GRASP_REQUEST.unpack_from(payload)
            if not (0.0 <= width <= MAX_WIDTH and 0.0 < speed <= MAX_SPEED and force > 0.0):
                return wire.GRIPPER_FAIL
            # Closing (or opening) past the object: the force limit stops the fingers on it.
            target = 0.0 if width <= self.width else MAX_WIDTH
            self._begin(_Job(command, command_id, target, speed, (width, eps_in, eps_out)), force)
        elif command == wire.GRIPPER_STOP:
            self.setpoint = self.width
            self.grasped = None
            return wire.GRIPPER_SUCCESS
        else:
            return wire.GRIPPER_FAIL
        return None

    def _begin(self, job: _Job, force: float) -> None:
        self.grasped = None
        self.job = job
        # The tendon carries both fingers: each presses with half its force.
        self._env.model.actuator_forcerange[self._act] = [-2.0 * force, 2.0 * force]

    def abort(self) -> _Job | None:
        job, self.job = self.job, None
        self.setpoint = self.width
        return job

    def step(self, dt: float) -> tuple[_Job, int] | None:
        """Advance the setpoint one cycle; a finished job and its status when one ends."""
        d = self._env.data
        job = self.job
        if job is not None:
            delta = job.target - self.setpoint
            self.setpoint += float(np.clip(delta, -job.speed * dt, job.speed * dt))
            speed = float(np.abs(d.qvel[self._finger_dofs]).sum())
            job.still_s = job.still_s + dt if speed < 1e-3 else 0.0
            blocked = job.still_s >= SETTLE_S and abs(self.setpoint - self.width) > 2e-3
            arrived = self.setpoint == job.target and job.still_s >= SETTLE_S
            if blocked or arrived:
                self.job = None
                reached = abs(self.width - job.target) < 1e-3
                return job, self._outcome(job, reached)
        if self.grasped is not None:
            lo = self.grasped[0] - self.grasped[1]
            hi = self.grasped[0] + self.grasped[2]
            if not lo <= self.width <= hi:
                self.grasped = None
        d.ctrl[self._act] = self.setpoint * self._ctrl_per_width
        return None

    def _outcome(self, job: _Job, reached: bool) -> int:
        if job.grasp is None:
            if job.command != wire.GRIPPER_HOMING:
                self._env.model.actuator_forcerange[self._act] = self._default_force
            return wire.GRIPPER_SUCCESS if reached else wire.GRIPPER_UNSUCCESSFUL
        width, eps_in, eps_out = job.grasp
        if width - eps_in <= self.width <= width + eps_out:
            self.grasped = job.grasp
            return wire.GRIPPER_SUCCESS
        self.setpoint = self.width
        return wire.GRIPPER_UNSUCCESSFUL

    def state(self, message_id: int) -> bytes:
        return wire.GRIPPER_STATE.pack(
            message_id, self.width, self.max_width, self.grasped is not None, 30
        )
