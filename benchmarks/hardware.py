"""The simulated Franka (`python -m mjkdl.hw.franka_sim`) driven by the real client libraries.

Baseline: the bare simulation, `mj_step` of the server's own scene at 1 kHz steps, timed in this
process. Against it: the lockstep rate (steps/s, every state waits for its command) through
pylibfranka, and in `--realtime` the client's loop at the robot's 1 kHz through pylibfranka
(period median and p99 between the states it reads) and franky, with the commands the server
counted missed, per 10 000 cycles.

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
for i in range(n):
    state, _ = ctrl.readOnce()
    stamps.append(time.perf_counter())
    hold.motion_finished = i == n - 1
    ctrl.writeOnce(hold)
print(time.perf_counter() - t0)
print(" ".join(f"{b - a:.6f}" for a, b in zip(stamps, stamps[1:])))
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
    found = re.findall(r"motion finished after (\d+) cycles, (\d+) without a command", log)
    cycles, lost = (int(v) for v in found[-1])
    return cycles, lost


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


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

    server = Server("--realtime")
    try:
        periods = [float(v) for v in run(PYLIBFRANKA, str(n)).splitlines()[1].split()]
    finally:
        log = server.close()
    cycles, lost = missed(log)
    ms = [p * 1e3 for p in periods]
    print(
        f"realtime, pylibfranka: period median {percentile(ms, 0.5):.3f} ms, "
        f"p99 {percentile(ms, 0.99):.3f} ms; missed {lost * 10000 / cycles:.0f} per 10 000"
    )

    server = Server("--realtime")
    try:
        run(FRANKY, str(n))
    finally:
        log = server.close()
    cycles, lost = missed(log)
    print(f"realtime, franky: missed {lost * 10000 / cycles:.0f} per 10 000 ({cycles} cycles)")


if __name__ == "__main__":
    main()
