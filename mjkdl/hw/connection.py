"""One connection to a Franka arm, its 1 kHz control loop in a process of its own.

The vendor client (pylibfranka for FR3, panda-py for the Panda) runs in a child process that
does nothing but the control loop: read the state, rate-limit the latest command, write it,
publish the state. The user's process exchanges commands and states with it through shared
memory (a sequence lock: the writer makes the counter odd while it writes, readers retry
until they see an even, unchanged counter), so no lock is ever held across processes and no
Python work in the user's loop, which holds that process's GIL, can delay a tick: the GIL
of the control process is its own. The loop keeps the safety defaults: every command
rate-limited to the arm's limits (`rate_limit`), a watchdog that brings the arm to rest and
finishes the motion when no new command came for `watchdog` seconds of wall-clock time, and
the same when the user's process asks it to stop (`close`, Ctrl+C) or dies.
"""

from __future__ import annotations

import importlib
import json
import math
import mmap
import os
import select
import signal
import subprocess
import sys
import tempfile
import threading
import time
import warnings
import weakref
from dataclasses import dataclass
from types import FrameType
from typing import Any, TextIO

import numpy as np

from ..errors import SpecError
from .faults import ArmConnectionError, HardwareError, WatchdogWarning, translate
from .rate_limit import RateLimiter, limits_for, number_view

# The control process's entry. Not `python -m` this module: importing mjkdl imports it first,
# and runpy then warns that the module runs twice.
_CHILD = (
    "import sys; from mjkdl.hw.connection import _control_process; _control_process(sys.argv[1:])"
)

POSITION, VELOCITY, TORQUE = 0, 1, 2
# The command block: [seq, mode, stop, acknowledged faults, seq when acknowledged, until,
# cmd x7]; until: the arm time up to which the command holds (what a lockstep loop waits on)
_C_SEQ, _C_MODE, _C_STOP, _C_ACK, _C_ACK_SEQ, _C_UNTIL, _C_CMD = 0, 1, 2, 3, 4, 5, 6
_C_LEN = _C_CMD + 7
# The state block: [seq, time, status, success_rate, ticks, late, q, dq, tau_J, tau_ext,
# F_ext(6)]; late counts the ticks that came more than one robot cycle after the previous one.
_S_SEQ, _S_TIME, _S_STATUS, _S_RATE, _S_TICKS, _S_LATE = 0, 1, 2, 3, 4, 5
_S_Q, _S_DQ, _S_TAU, _S_EXT, _S_F = 6, 13, 20, 27, 34
_S_HIST = _S_F + 6
# After the state: how many ticks came how long (wall clock) after the previous tick of their
# motion, in bins of PERIOD_BIN s; the last bin holds every period from PERIOD_BINS - 1 on.
PERIOD_BIN, PERIOD_BINS = 1e-4, 51
_S_LEN = _S_HIST + PERIOD_BINS
IDLE, MOVING, STOPPING, CLOSED = 0.0, 1.0, 2.0, 3.0
# The vendor client each arm is driven through by default: FR3 speaks libfranka >= 0.15
# (pylibfranka), the Panda libfranka 0.9 (panda-py).
_CLIENTS = {"fr3": "pylibfranka", "panda": "panda-py"}
# A motion's first ticks stand still: until the robot answers each command in turn (its first
# states come before it waits for ours), a command can miss its cycle, and one missed while
# moving is a velocity step the robot's discontinuity reflex catches.
_HOLD_TICKS = 20
_REFLEX = 4  # libfranka's RobotMode::kReflex
_REST_SPEED = 0.01  # rad/s: the arm counts as at rest below this joint speed
_DAMPING = 10.0  # Nm s/rad: how a stopping torque motion brakes the arm
_TICK = 1e-3  # s: the robot's control cycle
_LOCKSTEP_POLL = 5e-5  # s: how often a lockstep tick looks for the command it waits on


@dataclass
class ArmState:
    """A snapshot of the arm's measured state (copies, the caller's to keep)."""

    time: float  # the arm's clock (s)
    q: np.ndarray
    dq: np.ndarray
    tau_J: np.ndarray  # measured link-side joint torques
    tau_ext: np.ndarray  # tau_ext_hat_filtered: external torques the arm estimates
    f_ext: np.ndarray  # O_F_ext_hat_K: external wrench at the end effector, base frame
    success_rate: float  # control_command_success_rate of the last tick
    moving: bool  # a motion is running
    ticks: int  # control ticks this connection ran
    late: int  # of which came more than one robot cycle after the previous one


class ArmConnection:
    """A connection to the arm at `address`, with its control loop in a child process."""

    _announced = False  # the limits are printed by the first connection of the process

    def __init__(
        self,
        address: str,
        model: str = "fr3",
        *,
        client: str | None = None,
        watchdog: float = 0.2,
        realtime: bool = False,
        collision_thresholds: tuple[float, float] | None = None,
        connect_timeout: float = 20.0,
        lockstep: bool = False,
    ) -> None:
        if not isinstance(address, str) or not address:
            raise SpecError(f"robot_ip must be a host name or IP address, got {address!r}")
        if not (isinstance(watchdog, (int, float)) and 0.0 < watchdog < 10.0):
            raise SpecError(f"watchdog must be seconds in (0, 10), got {watchdog!r}")
        self.address = address
        self.limits = limits_for(model)
        client = client or _CLIENTS[model]
        if client not in _CLIENTS.values():
            raise SpecError(f"client must be 'pylibfranka' or 'panda-py', got {client!r}")
        self.client = client
        self.watchdog = float(watchdog)
        self._closed = False
        self._fault: HardwareError | None = None
        self._faults = 0  # the faults the loop reported
        self._events = _Events()
        # The blocks live in a memory-mapped file both processes map. The child is a fresh
        # interpreter (not multiprocessing's spawn, which re-runs an unguarded user script).
        fd, self._path = tempfile.mkstemp(prefix="mjkdl-arm-", dir=_shm_dir())
        os.ftruncate(fd, 8 * (_C_LEN + _S_LEN))
        self._map = mmap.mmap(fd, 8 * (_C_LEN + _S_LEN))
        os.close(fd)
        self._cmd, self._state = _blocks(self._map)
        self._snap = np.zeros(_S_LEN)
        if collision_thresholds is not None and not (
            len(collision_thresholds) == 2 and all(t > 0 for t in collision_thresholds)
        ):
            raise SpecError(
                "collision_thresholds must be (torque N·m, force N), both positive, or None "
                f"(the robot's own), got {collision_thresholds!r}"
            )
        self.collision_thresholds = collision_thresholds
        thresholds = json.dumps(collision_thresholds)
        self.lockstep = bool(lockstep)
        args = [address, model, client, str(self.watchdog), str(int(realtime)), self._path]
        args += [thresholds, str(int(self.lockstep))]
        self._proc = subprocess.Popen(
            [sys.executable, "-c", _CHILD, *args, str(os.getpid()), str(self._events.child)],
            pass_fds=(self._events.child,),
        )
        self._events.started()
        try:
            self._wait_ready(connect_timeout)
        except BaseException:
            self.close()
            raise
        self._unlink()  # both processes map it: nothing is left behind whatever happens
        _OPEN.add(self)
        _install_sigint()
        if not ArmConnection._announced:
            ArmConnection._announced = True
            print(self.limits.describe(), flush=True)

    # ------------------------------------------------------------------ events

    def _wait_ready(self, timeout: float) -> None:
        if not self._events.wait(timeout):
            raise ArmConnectionError(
                f"no answer from the arm at {self.address} within {timeout:.0f} s: check that "
                "the arm (or `python -m mjkdl.hw.franka_sim`) runs at this address"
            )
        self._poll()
        if self._fault is not None:
            raise self._fault

    def _poll(self) -> None:
        """Read the child's messages: ["ready"], ["fault", kind, message], ["watchdog", s]."""
        for msg in self._events.read():
            if msg is None:  # the child ended
                if self._fault is None and not self._closed:
                    self._fault = ArmConnectionError(
                        f"the control process of the arm at {self.address} ended "
                        f"(exit code {self._proc.poll()}); reconnect"
                    )
                return
            if msg[0] == "fault":
                self._fault = translate(msg[1], msg[2], self.address)
                self._faults += 1
            elif msg[0] == "watchdog":
                warnings.warn(
                    f"the arm at {self.address} is brought to rest: no command came for "
                    f"{msg[1]:.3f} s (watchdog={self.watchdog} s); send commands more often "
                    "or connect with a longer watchdog; the next command starts a new motion",
                    WatchdogWarning,
                    stacklevel=4,
                )

    def check(self) -> None:
        """Raise the fault the control loop reported, once (the arm is then at rest)."""
        self._poll()
        if self._fault is not None:
            fault, self._fault = self._fault, None
            # Seen: the loop may start motions again, on commands sent from now on only.
            self._cmd[_C_ACK_SEQ] = self._cmd[_C_SEQ]
            self._cmd[_C_ACK] = self._faults
            raise fault

    # ------------------------------------------------------------------ commands and state

    def send(self, mode: int, command: np.ndarray, until: float = math.inf) -> None:
        """Publish the command the loop sends from its next tick on (rate-limited); `until`:
        the arm time up to which it holds, after which a `lockstep` loop waits for the next."""
        self._check_open()
        c = self._cmd
        seq = c[_C_SEQ] + 1.0
        c[_C_SEQ] = seq  # odd: being written
        c[_C_MODE] = mode
        c[_C_UNTIL] = until
        c[_C_CMD:] = command
        c[_C_SEQ] = seq + 1.0

    def read(self) -> np.ndarray:
        """The latest state block, consistent (a copy owned by the connection)."""
        s, snap = self._state, self._snap
        while True:
            seq = s[_S_SEQ]
            if seq % 2.0 == 0.0:
                snap[:] = s
                if s[_S_SEQ] == seq:
                    return snap
            time.sleep(0)

    def state(self) -> ArmState:
        """The latest measured state as an `ArmState` of fresh arrays."""
        s = self.read()
        return ArmState(
            time=float(s[_S_TIME]),
            q=s[_S_Q : _S_Q + 7].copy(),
            dq=s[_S_DQ : _S_DQ + 7].copy(),
            tau_J=s[_S_TAU : _S_TAU + 7].copy(),
            tau_ext=s[_S_EXT : _S_EXT + 7].copy(),
            f_ext=s[_S_F : _S_F + 6].copy(),
            success_rate=float(s[_S_RATE]),
            moving=bool(s[_S_STATUS] == MOVING),
            ticks=int(s[_S_TICKS]),
            late=int(s[_S_LATE]),
        )

    def period_histogram(self) -> np.ndarray:
        """Ticks counted by the wall-clock time since the previous tick of their motion: bin
        i holds the periods in [i, i + 1) × `PERIOD_BIN` s, the last one everything longer
        (what a loop holding 1 kHz looks like: all in the bins around 1 ms)."""
        return self._state[_S_HIST:].copy()

    def wait_until(self, arm_time: float, timeout: float = 5.0) -> np.ndarray:
        """Block until the arm's clock reaches `arm_time`; the state block then."""
        deadline = time.monotonic() + timeout
        while True:
            s = self.read()
            if s[_S_TIME] >= arm_time - 1e-9:
                return s
            self.check()
            if self._proc.poll() is not None:
                self._poll()
                self.check()
                raise ArmConnectionError(f"the connection to the arm at {self.address} ended")
            if time.monotonic() > deadline:
                raise ArmConnectionError(
                    f"the arm at {self.address} sent no state for {timeout} s (its clock stays "
                    f"at {s[_S_TIME]:.3f} s); check the network and the robot's mode"
                )
            time.sleep(0.0002)

    # ------------------------------------------------------------------ closing

    def _check_open(self) -> None:
        if self._closed:
            raise HardwareError(f"the connection to the arm at {self.address} is closed")

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def alive(self) -> bool:
        """Whether the control loop runs (it ends on close, or when the arm is lost)."""
        return self._proc.poll() is None

    def close(self, timeout: float = 5.0) -> None:
        """Bring the arm to rest, finish the motion, wait until the measured arm is at rest
        (up to 2 s) and close the connection (idempotent)."""
        if self._closed:
            return
        self._closed = True
        _OPEN.discard(self)
        self._cmd[_C_STOP] = 1.0
        try:
            self._proc.wait(timeout)
        except subprocess.TimeoutExpired:  # the loop did not end: the robot's timeout stops it
            self._proc.kill()
            self._proc.wait()
        self._events.close()
        self._unlink()

    def _unlink(self) -> None:
        if self._path:
            os.unlink(self._path)
            self._path = ""


_OPEN: weakref.WeakSet[ArmConnection] = weakref.WeakSet()
_previous_sigint: Any = None


def _install_sigint() -> None:
    """Ctrl+C brings every connected arm to rest and closes it, then acts as before."""
    global _previous_sigint
    if _previous_sigint is not None:
        return
    try:
        _previous_sigint = signal.signal(signal.SIGINT, _on_sigint)
    except ValueError:  # not the main thread: the watchdog still stops the arm
        return


def _on_sigint(signum: int, frame: FrameType | None) -> None:
    global _previous_sigint
    for conn in list(_OPEN):
        conn.close()
    previous, _previous_sigint = _previous_sigint, None
    signal.signal(signal.SIGINT, previous)
    if callable(previous):
        previous(signum, frame)
    elif previous == signal.SIG_DFL:
        raise KeyboardInterrupt


# ---------------------------------------------------------------------- the child process


def _control_process(argv: list[str]) -> None:
    """The control loop (the child's main): one motion per command stream, until stopped."""
    address, model, client, watchdog, realtime, path, thresholds, lockstep, parent, fd = argv
    # Ctrl+C reaches the whole process group: the user's process asks this one to stop (and
    # this one brings the arm to rest first), so SIGINT here is ignored.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    with open(path, "r+b") as f:
        shared = mmap.mmap(f.fileno(), 8 * (_C_LEN + _S_LEN))
    cmd, state = _blocks(shared)
    events = os.fdopen(int(fd), "w", buffering=1)
    loop = _Loop(model, float(watchdog), cmd, state, events, int(parent), lockstep == "1")
    threading.Thread(target=loop.watch_parent, daemon=True).start()
    try:
        fr = importlib.import_module(
            "pylibfranka" if client == "pylibfranka" else "panda_py.libfranka"
        )
        loop.fr, loop.client = fr, client
        config = fr.RealtimeConfig.kEnforce if realtime == "1" else fr.RealtimeConfig.kIgnore
        loop.robot = fr.Robot(address, config)
        if json.loads(thresholds) is not None:  # collision reflexes above these
            torque, force = json.loads(thresholds)
            loop.robot.set_collision_behavior([torque] * 7, [torque] * 7, [force] * 6, [force] * 6)
        loop.publish(loop.robot.read_once(), IDLE)
        loop.send("ready")
        loop.run()
    except Exception as err:  # every client exception goes to the user's process, named
        loop.send("fault", type(err).__name__, str(err))
    finally:
        state[_S_STATUS] = CLOSED
        events.close()


class _Loop:
    """The child's state: the robot, the shared blocks, the rate limiter and the motion.

    A tick allocates nothing of its own: the state goes into views of the shared block made
    here, the rate limiter works in its own arrays, single numbers are read through
    memoryviews (Python floats, which come from the interpreter's free list, where indexing a
    NumPy array makes a scalar object) and the counters are floats for the same reason. The
    client's own objects (its state and the command it is handed) are the client's.
    """

    def __init__(
        self,
        model: str,
        watchdog: float,
        cmd: np.ndarray,
        state: np.ndarray,
        events: TextIO,
        parent: int,
        lockstep: bool = False,
    ) -> None:
        self.watchdog = watchdog
        self.lockstep = lockstep
        self.cmd, self.state = cmd, state
        self._c, self._s = number_view(cmd), number_view(state)
        self._cmd_values = cmd[_C_CMD:]
        self._q, self._dq = state[_S_Q : _S_Q + 7], state[_S_DQ : _S_DQ + 7]
        self._tau, self._ext = state[_S_TAU : _S_TAU + 7], state[_S_EXT : _S_EXT + 7]
        self._f = state[_S_F : _S_F + 6]
        self._scratch = np.zeros(7)
        self._still = np.zeros(7, dtype=bool)
        self._still_view = number_view(self._still)
        self.events, self.parent = events, parent
        self.orphaned = False  # the user's process is gone (see watch_parent)
        self.limiter = RateLimiter(limits_for(model))
        self.fr: Any = None
        self.client = "pylibfranka"
        self.robot: Any = None
        self.seen = 0.0  # the command sequence number last acted on
        self.until = math.inf  # the arm time up to which `wanted` holds
        self.wanted = np.zeros(7)
        self.mode = POSITION
        self.ticks = 0.0
        self.late = 0.0
        self.faults = 0.0  # motions ended by a fault, which the user's loop must see first
        # the motion under way
        self.motion_mode = POSITION
        self.started = False
        self.hold = 0
        self.stopping = False
        self.last_new = 0.0
        self.watchdog_fired = 0.0
        self.last_tick = 0.0  # monotonic time of the motion's previous tick

    def watch_parent(self) -> None:
        """Notice the user's process ending (a thread: the tick itself asks nothing)."""
        while os.getppid() == self.parent:
            time.sleep(0.01)
        self.orphaned = True

    def send(self, *message: object) -> None:
        """One message to the user's process (a JSON line)."""
        self.events.write(json.dumps(message) + "\n")

    def publish(self, rs: Any, status: float) -> None:
        s = self._s
        seq = s[_S_SEQ] + 1.0
        s[_S_SEQ] = seq
        s[_S_TIME] = rs.time.to_sec()
        s[_S_STATUS] = status
        s[_S_RATE] = rs.control_command_success_rate
        s[_S_TICKS] = self.ticks
        s[_S_LATE] = self.late
        self._q[...] = rs.q
        self._dq[...] = rs.dq
        self._tau[...] = rs.tau_J
        self._ext[...] = rs.tau_ext_hat_filtered
        self._f[...] = rs.O_F_ext_hat_K
        s[_S_SEQ] = seq + 1.0

    def take_command(self) -> bool:
        """Copy a new, consistent command into `wanted`; whether one came."""
        c = self._c
        seq = c[_C_SEQ]
        if seq == self.seen or seq % 2.0 != 0.0:
            return False
        mode, until = c[_C_MODE], c[_C_UNTIL]
        np.copyto(self.wanted, self._cmd_values)
        if c[_C_SEQ] != seq:
            return False
        self.seen, self.until = seq, until
        self.mode = POSITION if mode == POSITION else VELOCITY if mode == VELOCITY else TORQUE
        return True

    def stop_asked(self) -> bool:
        return self._c[_C_STOP] != 0.0 or self.orphaned

    def run(self) -> None:
        """Idle until a command comes, run its motion, and again, until asked to stop."""
        while not self.stop_asked():
            c = self._c
            if c[_C_ACK] < self.faults:  # the user's loop has not seen the last fault yet
                self.take_command()  # what it sends meanwhile was meant for the stopped motion
                self.publish(self.robot.read_once(), IDLE)
                time.sleep(0.002)
                continue
            if self.seen < c[_C_ACK_SEQ]:  # nor what it had sent before it saw the fault
                self.seen = c[_C_ACK_SEQ]
            if not self.take_command():
                self.publish(self.robot.read_once(), IDLE)
                time.sleep(0.002)
                continue
            try:
                self.motion()
            except Exception as err:  # a reflex ends the motion, not the connection
                if not _motion_fault(err):
                    raise
                self.faults += 1.0
                self.send("fault", type(err).__name__, str(err))
                self.publish(self.robot.read_once(), IDLE)
        self.settle()

    def settle(self, timeout: float = 2.0) -> None:
        """Publish the arm's state until it is at rest (every measured joint speed below
        `_REST_SPEED`) or `timeout` s passed: the stopped motion ends at zero commanded
        velocity, which the measured arm reaches a little later, and the last state a closed
        connection leaves is the arm's at rest."""
        end = time.monotonic() + timeout
        while True:
            self.publish(self.robot.read_once(), IDLE)
            if self._below(self._dq, _REST_SPEEDS) or time.monotonic() > end:
                return
            time.sleep(0.002)

    def motion(self) -> None:
        """One motion in the current mode, 1 kHz, until stopped, switched or the watchdog."""
        fr, robot = self.fr, self.robot
        if int(robot.read_once().robot_mode.value) == _REFLEX:  # a reflex stopped the last one
            robot.automatic_error_recovery()
        mode = self.motion_mode = self.mode
        self.started, self.stopping, self.watchdog_fired = False, False, 0.0
        if self.client == "pylibfranka":
            if mode == TORQUE:
                ctrl = robot.start_torque_control()
            elif mode == VELOCITY:
                ctrl = robot.start_joint_velocity_control(fr.ControllerMode.JointImpedance)
            else:
                ctrl = robot.start_joint_position_control(fr.ControllerMode.JointImpedance)
            rs, period = ctrl.readOnce()
            while True:
                out = self.tick(rs, period)
                ctrl.writeOnce(out)
                if out.motion_finished:
                    break
                rs, period = ctrl.readOnce()
        else:  # panda-py: libfranka's own loop calls back once per tick (our rate limiter)
            tick = self.tick
            if mode == TORQUE:
                robot.control(tick, limit_rate=False, cutoff_frequency=1000.0)
            elif mode == VELOCITY:
                robot.control_joint_velocity(tick, limit_rate=False, cutoff_frequency=1000.0)
            else:
                robot.control_joint_position(tick, limit_rate=False, cutoff_frequency=1000.0)
        self.publish(robot.read_once(), IDLE)

    def tick(self, rs: Any, period: Any) -> Any:
        """The command for this tick of the motion under way, from the state `rs` that came
        `period` after the previous one."""
        fr, limiter, mode = self.fr, self.limiter, self.motion_mode
        now = time.monotonic()
        if not self.started:
            self.started, self.last_new, self.hold = True, now, _HOLD_TICKS
            limiter.reset(np.asarray(rs.q_d), np.asarray(rs.dq_d))
        else:
            b = (now - self.last_tick) / PERIOD_BIN
            i = _S_HIST + (PERIOD_BINS - 1 if b >= PERIOD_BINS - 1 else int(b))
            self._s[i] = self._s[i] + 1.0
        self.last_tick = now
        self.ticks += 1.0
        if period.to_sec() > 0.0015:  # a cycle (or more) went by without a command of ours
            self.late += 1.0
        self.publish(rs, STOPPING if self.stopping else MOVING)
        waited = False
        # Not during the motion's first ticks, which stand still whatever comes: the robot
        # sends its first states before it waits for commands, and a tick held up there lets
        # them pile up unanswered.
        if self.lockstep and not self.stopping and not self.hold:
            waited = self.await_command(rs.time.to_sec())
            now = time.monotonic()
        if self.take_command() or waited:
            self.last_new = now
            if self.mode != mode:  # a new mode: finish this motion at rest first
                self.stopping = True
                self.seen -= 2.0  # act on this command again once stopped
        if not self.stopping and self.stop_asked():
            self.stopping = True
        if not self.stopping and now - self.last_new > self.watchdog:
            self.stopping, self.watchdog_fired = True, now - self.last_new
            # said now, not once at rest: the user's next call reports the stall
            self.send("watchdog", self.watchdog_fired)
        stopping, finished = self.stopping, False
        if self.hold:  # the motion's first ticks stand still at its start
            self.hold -= 1
            if mode == TORQUE:
                return fr.Torques(limiter.tau)
            if mode == VELOCITY:
                return fr.JointVelocities(_ZERO)
            return fr.JointPositions(limiter.q)
        if mode == TORQUE:
            if stopping:
                np.multiply(self._dq, _BRAKE, out=self._scratch)  # rs.dq, as published
                tau = limiter.torque(self._scratch)
                finished = self._below(self._dq, _REST_SPEEDS)
            else:
                tau = limiter.torque(self.wanted)
            out = fr.Torques(tau)
        elif mode == VELOCITY:
            v = limiter.velocity(self.wanted if not stopping else _ZERO)
            finished = stopping and self._below(v, _AT_REST)
            out = fr.JointVelocities(v)
        else:
            if stopping:
                limiter.velocity(_ZERO)
                q = limiter.q
                finished = self._below(limiter.dq, _AT_REST)
            else:
                q = limiter.position(self.wanted)
            out = fr.JointPositions(q)
        if finished:
            out.motion_finished = True
        return out

    def await_command(self, arm_time: float) -> bool:
        """Lockstep: hold this tick until the user's command for it is there (one holding
        past `arm_time`), so that each command acts on the ticks it was sent for whatever the
        two processes' timing; the watchdog and a stop still end the wait. Whether a new
        command came meanwhile."""
        took = False
        while self.until < arm_time + 0.5 * _TICK and not self.stop_asked():
            if self.take_command():
                took = True
                continue
            if time.monotonic() - self.last_new > self.watchdog:
                break
            time.sleep(_LOCKSTEP_POLL)
        return took

    def _below(self, values: np.ndarray, bound: np.ndarray) -> bool:
        """Whether every |value| is below `bound` (7 values; without a temporary array)."""
        np.abs(values, out=self._scratch)
        np.less(self._scratch, bound, out=self._still)
        v = self._still_view
        return bool(v[0] and v[1] and v[2] and v[3] and v[4] and v[5] and v[6])


def _motion_fault(err: Exception) -> bool:
    """Whether `err` ended the motion only (a reflex, a refused Move): libfranka's
    ControlException, which panda-py raises as a plain RuntimeError with libfranka's text."""
    return type(err).__name__ == "ControlException" or "libfranka: Move command" in str(err)


_ZERO = np.zeros(7)
# the thresholds and gain above as arrays (a ufunc wraps a Python number in a new array)
_REST_SPEEDS, _AT_REST, _BRAKE = np.full(7, _REST_SPEED), np.full(7, 1e-6), np.full(7, -_DAMPING)


class _Events:
    """The child's messages, JSON lines on a pipe, read without blocking."""

    def __init__(self) -> None:
        self._read, self.child = os.pipe()
        os.set_blocking(self._read, False)
        self._buffer = b""
        self._ended = False

    def started(self) -> None:
        os.close(self.child)  # the child holds its end: EOF once it ends

    def wait(self, timeout: float) -> bool:
        """Whether a message (or the end) came within `timeout` seconds."""
        return bool(self._buffer) or bool(select.select([self._read], [], [], timeout)[0])

    def read(self) -> list[Any]:
        """The messages that came (None for the child's end)."""
        out: list[Any] = []
        if self._ended:
            return out
        while True:
            try:
                chunk = os.read(self._read, 65536)
            except BlockingIOError:
                break
            if not chunk:
                self._ended = True
                break
            self._buffer += chunk
        *lines, self._buffer = self._buffer.split(b"\n")
        out = [json.loads(line) for line in lines if line]
        if self._ended:
            out.append(None)
        return out

    def close(self) -> None:
        os.close(self._read)


def _shm_dir() -> str | None:
    """Memory-backed files where the system has them."""
    return "/dev/shm" if os.path.isdir("/dev/shm") else None


def _blocks(shared: mmap.mmap) -> tuple[np.ndarray, np.ndarray]:
    """The command and state blocks of the shared mapping."""
    cmd = np.ndarray((_C_LEN,), dtype=np.float64, buffer=shared)
    state = np.ndarray((_S_LEN,), dtype=np.float64, buffer=shared, offset=8 * _C_LEN)
    return cmd, state
