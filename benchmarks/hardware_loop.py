"""The 1 kHz loop of an arm connection while the user's loop is busy in Python.

A lockstep simulated Franka (`python -m mjkdl.hw.franka_sim --lockstep`, started here) holds a
joint velocity motion; for `--seconds` the user's process sleeps (quiet), then computes in pure
Python (busy). Counted: the control ticks the arm's clock advanced in each window, for

    mjkdl       FrankaArm: the loop in a process of its own (mjkdl.hw.connection)
    thread      the baseline: the same readOnce/writeOnce loop in a thread of the user's
                process, which waits for the GIL while the user's loop holds it

In lockstep each tick waits for its command, so a loop that is held up shows as fewer ticks
(against the robot it would be missed commands). The figure is busy ticks / quiet ticks.

    python benchmarks/hardware_loop.py [--seconds 3]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import threading
import time

import numpy as np
import pylibfranka as fr

import mjkdl as mjk
from mjkdl.hw.franka import FrankaArm


def busy(seconds: float) -> None:
    """Pure-Python work (holds the GIL) for `seconds`."""
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        sum(i * i for i in range(200))


def mjkdl_loop(host: str, seconds: float) -> tuple[int, int]:
    with FrankaArm(host, client="pylibfranka", watchdog=2 * seconds + 1) as arm:
        arm.ctrl_mode = mjk.CtrlMode.VELOCITY
        arm.jnt_vel_cmd = np.zeros(7)
        for _ in range(100):
            arm.step()
        conn = arm.link.connection
        t0 = conn.state().ticks
        time.sleep(seconds)
        t1 = conn.state().ticks
        busy(seconds)
        t2 = conn.state().ticks
    return t1 - t0, t2 - t1


def thread_loop(host: str, seconds: float) -> tuple[int, int]:
    robot = fr.Robot(host, fr.RealtimeConfig.kIgnore)
    ctrl = robot.start_joint_velocity_control(fr.ControllerMode.JointImpedance)
    ticks, stop = [0], [False]

    def loop() -> None:
        ctrl.readOnce()
        while True:
            out = fr.JointVelocities([0.0] * 7)
            out.motion_finished = stop[0]
            ctrl.writeOnce(out)
            if stop[0]:
                return
            ctrl.readOnce()
            ticks[0] += 1

    worker = threading.Thread(target=loop)
    worker.start()
    time.sleep(0.2)
    t0 = ticks[0]
    time.sleep(seconds)
    t1 = ticks[0]
    busy(seconds)
    t2 = ticks[0]
    stop[0] = True
    worker.join()
    return t1 - t0, t2 - t1


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0)
    args = parser.parse_args()
    host = f"127.{os.getpid() % 250 + 1}.254.1"
    server = subprocess.Popen(
        [sys.executable, "-m", "mjkdl.hw.franka_sim", "--host", host, "--lockstep"],
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert server.stderr is not None
        server.stderr.readline()  # it listens
        for name, run in (("mjkdl", mjkdl_loop), ("thread", thread_loop)):
            quiet, loaded = run(host, args.seconds)
            print(
                f"{name:6s}: {quiet / args.seconds:.0f} ticks/s quiet, "
                f"{loaded / args.seconds:.0f} ticks/s busy, busy/quiet {loaded / quiet:.2f}",
                flush=True,
            )
    finally:
        server.terminate()
        server.wait(30)


if __name__ == "__main__":
    main()
