"""The simulated Franka (`python -m mjkdl.hw.franka_sim`) driven by the real client libraries.

Baseline: the bare simulation, `mj_step` of the server's own scene at 1 kHz steps, timed in this
process. Against it: the lockstep rate (steps/s, every state waits for its command) through
pylibfranka, and in `--realtime` the client's loop at the robot's 1 kHz through pylibfranka
(period median and p99 between the states it reads) and franky, with the commands the server
counted missed, per 10 000 cycles. Then mjkdl's handle (`FrankaArm`, its loop in a process of
its own driving pylibfranka, and panda-py) holding the arm in `--realtime` for the same number
of cycles, against pylibfranka's own loop timed in the same run: the handle's period between
ticks (wall clock, from its 0.1 ms histogram) and the commands the server counted missed.

    python benchmarks/hardware.py [--cycles 10000]
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
os.environ.setdefault("MENAGERIE_ROOT", str(ROOT.parent / "shared" / "menagerie"))

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

import mjkdl as mjk  # noqa: E402
from mjkdl.hw.connection import PERIOD_BIN  # noqa: E402
from mjkdl.hw.faults import HardwareError, ReflexError  # noqa: E402
from mjkdl.hw.franka import FrankaArm  # noqa: E402
from mjkdl.hw.franka_sim.scene import franka_scene  # noqa: E402
from mjkdl.scene import Env  # noqa: E402

HOST = f"127.{os.getpid() % 250 + 1}.77.1"

# pylibfranka, holding the arm where it is for N cycles through its external loop; prints the
# periods between the states it read (s).
PYLIBFRANKA = """
import sys, time, pylibfranka as plf
robot = plf.Robot(sys.argv[1], plf.RealtimeConfig.kIgnore)
ctrl = robot.start_joint_position_control(plf.ControllerMode.JointImpedance)
state, _ = ctrl.readOnce()
hold = plf.JointPositions(list(state.q_d))
n = int(sys.argv[2])
stamps = []
t0 = time.perf_counter()
error = ""
try:
    for i in range(n):
        state, _ = ctrl.readOnce()
        stamps.append(time.perf_counter())
        hold.motion_finished = i == n - 1
        ctrl.writeOnce(hold)
except Exception as e:  # a reflex on a loaded machine: the periods until then, and why
    error = str(e).splitlines()[0]
print(time.perf_counter() - t0)
print(" ".join(f"{b - a:.6f}" for a, b in zip(stamps, stamps[1:])))
print(error)
"""

# franky, holding with a zero joint velocity motion for N ms (its loop runs in libfranka's own
# real-time callback thread).
FRANKY = """
import sys, franky
robot = franky.Robot(sys.argv[1], realtime_config=franky.RealtimeConfig.Ignore)
robot.move(franky.JointVelocityMotion([0.0] * 7, duration=franky.Duration(int(sys.argv[2]))))
"""


def bare_rate(steps: int) -> float:
    env = Env.build(franka_scene())
    m, d = env.model, env.data
    t0 = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(m, d)
    rate = steps / (time.perf_counter() - t0)
    env.close()
    return rate


class Server:
    def __init__(self, mode: str) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "mjkdl.hw.franka_sim", "--host", HOST, mode],
            stderr=subprocess.PIPE,
            text=True,
            cwd=ROOT,
        )
        assert self.proc.stderr is not None
        line = self.proc.stderr.readline()
        assert "franka_sim: panda on" in line, line

    def close(self) -> str:
        self.proc.terminate()
        _, err = self.proc.communicate(timeout=30)
        return err


def run(code: str, *args: str) -> str:
    done = subprocess.run(
        [sys.executable, "-c", code, HOST, *args], capture_output=True, text=True, check=True
    )
    return done.stdout


def missed(log: str) -> tuple[int, int]:
    found = re.findall(r"motion \w+ after (\d+) cycles, (\d+) without a command", log)
    # every motion of this server's run (the handle's restart after a reflex)
    return sum(int(c) for c, _ in found), sum(int(m) for _, m in found)


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


def handle(client: str, n: int) -> tuple[np.ndarray, int, str]:
    """FrankaArm holding the arm (zero joint velocity) for about `n` ticks; the histogram of
    its loop's periods, the reflexes that stopped it (each followed by a new motion) and why
    the connection ended early, if it did."""
    reflexes, ended = 0, ""
    with FrankaArm(HOST, client=client, watchdog=5.0) as arm:
        arm.ctrl_mode = mjk.CtrlMode.VELOCITY
        conn = arm.link.connection
        start = conn.state().ticks
        while conn.state().ticks - start < n:
            arm.jnt_vel_cmd = np.zeros(7)  # the user's loop keeps commanding, at ~100 Hz
            try:
                arm.step()
            except ReflexError:  # commands missed in a row: the robot stopped the motion
                reflexes += 1
            except HardwareError as err:  # the client gave up (no state for its timeout)
                ended = str(err).split(" (arm at")[0]
                break
            time.sleep(0.01)
        return conn.period_histogram(), reflexes, ended


def histogram_percentile(hist: np.ndarray, q: float) -> float:
    """The period (ms, the bin's upper edge) below which a share `q` of the ticks came."""
    edge = int(np.searchsorted(np.cumsum(hist), q * hist.sum()))
    return (edge + 1) * PERIOD_BIN * 1e3


def pylibfranka_realtime(n: int, label: str) -> None:
    server = Server("--realtime")
    try:
        out = run(PYLIBFRANKA, str(n)).split("\n")
    finally:
        log = server.close()
    periods = [float(v) for v in out[1].split()]
    cycles, lost = missed(log)
    cycles = max(cycles, 1)
    ms = [p * 1e3 for p in periods]
    stopped = f"; stopped after {len(ms) + 1} cycles: {out[2]}" if out[2] else ""
    print(
        f"{label}: period median {percentile(ms, 0.5):.3f} ms, "
        f"p99 {percentile(ms, 0.99):.3f} ms; missed {lost * 10000 / cycles:.0f} per 10 000{stopped}"
    )


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--cycles", type=int, default=10000)
    n = parser.parse_args().cycles

    bare = bare_rate(n)
    print(f"bare simulation (mj_step, the server's scene): {bare:8.0f} steps/s")

    server = Server("--lockstep")
    try:
        wall = float(run(PYLIBFRANKA, str(n)).splitlines()[0])
    finally:
        server.close()
    print(
        f"lockstep through pylibfranka:                  {n / wall:8.0f} steps/s "
        f"({n / wall / bare:.3f} of bare)"
    )

    pylibfranka_realtime(n, "realtime, pylibfranka")

    server = Server("--realtime")
    try:
        run(FRANKY, str(n))
    except subprocess.CalledProcessError as err:  # a reflex on a loaded machine: say which
        print(f"realtime, franky: failed: {err.stderr.strip().splitlines()[-1]}")
    finally:
        log = server.close()
    cycles, lost = missed(log)
    print(f"realtime, franky: missed {lost * 10000 / cycles:.0f} per 10 000 ({cycles} cycles)")

    # mjkdl's handle, with pylibfranka's own loop again beside it (the same minutes)
    for client in ("pylibfranka", "panda-py"):
        server = Server("--realtime")
        try:
            hist, reflexes, ended = handle(client, n)
        finally:
            log = server.close()
        cycles, lost = missed(log)
        late = hist[11:].sum() / hist.sum()  # ticks more than 1.1 ms after the previous
        print(
            f"realtime, FrankaArm ({client}): period median "
            f"{histogram_percentile(hist, 0.5):.1f} ms, p99 {histogram_percentile(hist, 0.99):.1f}"
            f" ms (0.1 ms bins), over 1.1 ms {late * 100:.1f} %; missed "
            f"{lost * 10000 / max(cycles, 1):.0f} per 10 000 ({cycles} cycles, {reflexes} "
            f"reflexes){'; ended: ' + ended if ended else ''}"
        )
        pylibfranka_realtime(n, "  beside it, pylibfranka's own loop")


if __name__ == "__main__":
    main()
