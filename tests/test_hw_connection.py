"""The arm connection's 1 kHz loop (the control process's tick) allocates nothing per tick."""

from __future__ import annotations

import io
import multiprocessing
import os
import tracemalloc
from dataclasses import dataclass, field

import numpy as np
import pytest

from mjkdl.hw import connection as conn

HOME = np.array([0.0, -0.785398, 0.0, -2.356194, 0.0, 1.570796, 0.785398])  # inside both arms'


@dataclass
class _Duration:
    seconds: float

    def to_sec(self) -> float:
        return self.seconds


@dataclass
class _State:
    """What the loop reads of the client's RobotState (arrays made once)."""

    q: np.ndarray = field(default_factory=lambda: HOME.copy())
    dq: np.ndarray = field(default_factory=lambda: np.zeros(7))
    q_d: np.ndarray = field(default_factory=lambda: HOME.copy())
    dq_d: np.ndarray = field(default_factory=lambda: np.zeros(7))
    tau_J: np.ndarray = field(default_factory=lambda: np.zeros(7))
    tau_ext_hat_filtered: np.ndarray = field(default_factory=lambda: np.zeros(7))
    O_F_ext_hat_K: np.ndarray = field(default_factory=lambda: np.zeros(6))
    time: _Duration = field(default_factory=lambda: _Duration(0.0))
    control_command_success_rate: float = 1.0


class _Command:
    motion_finished = False


class _Client:
    """The client's command constructors; one object handed back (the vendor's own
    constructor is the vendor's allocation, not the loop's)."""

    command = _Command()

    @staticmethod
    def Torques(values: np.ndarray) -> _Command:
        return _Client.command

    JointPositions = JointVelocities = Torques


def _ticks(model: str, mode: int, n: int) -> tuple[np.ndarray, np.ndarray, bool]:
    """Run `n` ticks of a motion in `mode` with a new command each tick, then ask it to stop;
    the bytes each tick allocated beyond what it started with, the bytes each kept, and
    whether the motion finished."""
    cmd, state = np.zeros(conn._C_LEN), np.zeros(conn._S_LEN)
    loop = conn._Loop(model, 10.0, cmd, state, io.StringIO(), os.getpid())
    loop.fr, loop.motion_mode, loop.mode = _Client, mode, mode
    rs, period = _State(), _Duration(0.001)
    c, values = memoryview(cmd), cmd[conn._C_CMD :]
    wanted = np.zeros(7)
    base = HOME if mode == conn.POSITION else np.zeros(7)
    c[conn._C_MODE] = float(mode)
    for _ in range(50):  # the motion's start (its first tick sets the limiter up) and hold
        loop.tick(rs, period)
    _Client.command.motion_finished = False  # an instance attribute, made before tracing
    extra = np.full(n, -1)  # made before tracing starts, as everything of the harness
    kept = np.zeros(n, dtype=int)
    tracemalloc.start()
    for i in range(n):
        np.add(base, 0.2 * (i % 700) / 700.0, out=wanted)
        c[conn._C_SEQ] = c[conn._C_SEQ] + 1.0
        np.copyto(values, wanted)
        c[conn._C_SEQ] = c[conn._C_SEQ] + 1.0
        if i == n - 500:
            c[conn._C_STOP] = 1.0
        before = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
        out = loop.tick(rs, period)
        after, peak = tracemalloc.get_traced_memory()
        extra[i], kept[i] = peak - before, after - before
        rs.q[:] = loop.limiter.q  # the arm follows
        rs.dq[:] = loop.limiter.dq
        if out.motion_finished:
            break
    tracemalloc.stop()
    ran = extra >= 0
    # every tick after the motion's first is counted in the period histogram
    assert state[conn._S_HIST :].sum() == 50 - 1 + ran.sum()
    return extra[ran], kept[ran], bool(out.motion_finished)


def _warmed_ticks(model: str, mode: int, n: int) -> tuple[np.ndarray, np.ndarray, bool]:
    """`_ticks` after one whole motion (started, stopped, finished) warmed every path up, as
    a control process's first motion does."""
    _ticks(model, mode, 600)
    return _ticks(model, mode, n)


@pytest.mark.parametrize("model", ["panda", "fr3"])
@pytest.mark.parametrize("mode", [conn.POSITION, conn.VELOCITY, conn.TORQUE])
def test_a_tick_allocates_nothing(model: str, mode: int) -> None:
    """tracemalloc around each of 3000 ticks (new commands, the rate limiter, the state
    published, then the stop brought to rest): no tick allocates a byte, nothing grows.
    Measured in a fresh interpreter, as the loop runs in one (the control process): after
    other tests, collecting their leftovers inside a tick would count against it."""
    with multiprocessing.get_context("spawn").Pool(1) as pool:
        extra, kept, finished = pool.apply(_warmed_ticks, (model, mode, 3000))
    assert len(extra) > 2500
    # the first ticks fill the interpreter's free list of floats (one PyFloat, 32 B, at most)
    assert extra[:10].max() <= 32 and kept[:10].sum() <= 32
    extra, growth = extra[10:], int(kept[10:].sum())
    assert max(extra) == 0, f"{sum(1 for e in extra if e)} ticks allocated, up to {max(extra)} B"
    assert growth == 0
    assert finished  # the stop ran to its end (the arm at rest), allocation-free as well


def test_a_lockstep_tick_waits_for_the_command_of_its_time() -> None:
    """With `lockstep`, a tick whose arm time lies past the last command's `until` waits for
    the next command and acts on it; one within it goes on at once, as do the motion's first
    ticks (they stand still); without lockstep no tick waits. (A wait that should not be ends
    at the watchdog, which stops the motion.)"""
    import threading

    cmd, state = np.zeros(conn._C_LEN), np.zeros(conn._S_LEN)
    loop = conn._Loop("panda", 2.0, cmd, state, io.StringIO(), os.getpid(), lockstep=True)
    loop.fr, loop.motion_mode, loop.mode = _Client, conn.POSITION, conn.POSITION
    rs, period = _State(), _Duration(0.001)
    c = memoryview(cmd)

    def send(values: np.ndarray, until: float) -> None:
        c[conn._C_SEQ] = c[conn._C_SEQ] + 1.0
        c[conn._C_UNTIL] = until
        cmd[conn._C_CMD :] = values
        c[conn._C_SEQ] = c[conn._C_SEQ] + 1.0

    send(HOME, 0.0)  # holds for no tick
    loop.tick(rs, period)  # the motion's first tick: it stands still, without waiting
    assert loop.hold and not loop.stopping
    loop.hold = 0  # past the motion's first ticks
    send(HOME, 0.002)  # holds for the ticks at 0 and 1 ms
    for t in (0.0, 0.001):
        rs.time = _Duration(t)
        loop.tick(rs, period)
        assert not loop.stopping
    goal = HOME + 0.1
    late = threading.Timer(0.2, send, (goal, 0.004))
    late.start()
    rs.time = _Duration(0.002)
    loop.tick(rs, period)  # waits for the command holding past 2 ms
    late.join()
    np.testing.assert_array_equal(loop.wanted, goal)
    assert loop.until == 0.004 and not loop.stopping
    loop.lockstep = False
    rs.time = _Duration(0.010)
    loop.tick(rs, period)
    assert not loop.stopping
