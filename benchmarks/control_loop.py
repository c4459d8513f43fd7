"""Gravity-compensation control loop: mjkdl vs a hand-written raw-MuJoCo loop.

Gen3 + 2F-85 held at the home pose by gravity compensation in TORQUE mode, 2 ms steps.
(a) raw MuJoCo: mj_step1, qfrc_applied[arm] = qfrc_bias[arm], mj_step2;
(b) mjkdl: robot.update(), robot.jnt_trq_cmd = robot.gravity_torques(), robot.step().
Both run interleaved in one process, in blocks; the median of the per-block ratio b/a is the
figure. Run: python benchmarks/control_loop.py
"""

from __future__ import annotations

import time
import tracemalloc

import mujoco
import numpy as np
from scenes import HOME, TOOL, tabletop_spec

import mjkdl as mjk

BLOCKS = 60
STEPS = 250
WARMUP = 1500


def main() -> None:
    raw_scene = mjk.Scene.build(tabletop_spec())
    m, d = raw_scene.model, raw_scene.data
    arm = np.arange(7)
    d.qpos[arm] = HOME
    m.actuator_gainprm[arm] = 0.0  # the arm's servos off: the applied force holds it
    m.actuator_biasprm[arm] = 0.0
    mujoco.mj_forward(m, d)

    scene = mjk.Scene.build(tabletop_spec())
    robot = scene.create_robot("base_link", "bracelet_link", tool=TOOL)
    robot.set_joint_pos(HOME)
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    robot.sync_commands()

    def raw(n: int) -> None:
        for _ in range(n):
            mujoco.mj_step1(m, d)
            d.qfrc_applied[arm] = d.qfrc_bias[arm]
            mujoco.mj_step2(m, d)

    def ours(n: int) -> None:
        for _ in range(n):
            robot.update()
            robot.jnt_trq_cmd = robot.gravity_torques()
            robot.step()

    raw(WARMUP)  # let the fingers settle: the steady hold is what is measured
    ours(WARMUP)
    ratios, t_raw, t_ours = [], [], []
    for _ in range(BLOCKS):
        t0 = time.perf_counter()
        raw(STEPS)
        t1 = time.perf_counter()
        ours(STEPS)
        t2 = time.perf_counter()
        t_raw.append((t1 - t0) / STEPS)
        t_ours.append((t2 - t1) / STEPS)
        ratios.append((t2 - t1) / (t1 - t0))

    tracemalloc.start()
    ours(100)
    before = tracemalloc.take_snapshot()
    ours(2000)
    after = tracemalloc.take_snapshot()
    tracemalloc.stop()
    grown = sum(s.size_diff for s in after.compare_to(before, "filename"))

    robot.update()
    drift = np.abs(robot.jnt_pos_msr - HOME).max()
    print(f"MuJoCo {mjk.mujoco_version()}, {BLOCKS} blocks x {STEPS} steps, interleaved")
    print(f"raw MuJoCo loop   median {np.median(t_raw) * 1e6:7.2f} us/step")
    print(f"mjkdl loop        median {np.median(t_ours) * 1e6:7.2f} us/step")
    print(f"ratio mjkdl/raw   median {np.median(ratios):.3f}  (p10 {np.percentile(ratios, 10):.3f},"
          f" p90 {np.percentile(ratios, 90):.3f})")
    print(f"memory retained over 2000 steps: {grown} bytes; max joint drift {drift:.2e} rad")
    raw_scene.close()
    scene.close()


if __name__ == "__main__":
    main()
