"""Gravity-compensation control loop: mjkdl vs a hand-written raw-MuJoCo loop.

Gen3 + 2F-85 held at the home pose by gravity compensation in TORQUE mode, 2 ms steps.
(a) raw MuJoCo: mj_step1, qfrc_applied[arm] = qfrc_bias[arm], mj_step2;
(b) mjkdl: robot.update(), robot.jnt_trq_cmd = robot.gravity_torques(), robot.step();
(c) for reference, a lean Pinocchio loop on the same chain model: copy q, Pinocchio's gravity
    into qfrc_applied, mj_step — the floor for any loop that calls Pinocchio from Python.
All three run interleaved in one process, in blocks, after the fingers have settled; the figure
is the median of the per-block ratios to (a).

    python benchmarks/control_loop.py
    python benchmarks/control_loop.py --only mjkdl --steps 1000   # one loop, e.g. for callgrind

Wall-clock time on a shared virtual machine is noisy; instruction counts are not:
    valgrind --tool=callgrind --callgrind-out-file=/dev/null \\
        python benchmarks/control_loop.py --only raw --steps N
for two values of N gives the instructions per step of each loop.
"""

from __future__ import annotations

import argparse
import time
import tracemalloc
from collections.abc import Callable

import mujoco
import numpy as np
import pinocchio as pin
from scenes import HOME, TOOL, tabletop_spec

import mjkdl as mjk

BLOCKS = 60
STEPS = 250
WARMUP = 1500  # 3 s: the 2F-85's fingers settle, the steady hold is what is measured
ARM = np.arange(7)


def raw_loop() -> tuple[Callable[[int], None], mjk.Scene]:
    """The hand-written MuJoCo loop; the arm's servos are switched off, the force holds it."""
    scene = mjk.Scene.build(tabletop_spec())
    m, d = scene.model, scene.data
    d.qpos[ARM] = HOME
    m.actuator_gainprm[ARM] = 0.0
    m.actuator_biasprm[ARM] = 0.0
    mujoco.mj_forward(m, d)

    def run(n: int) -> None:
        for _ in range(n):
            mujoco.mj_step1(m, d)
            d.qfrc_applied[ARM] = d.qfrc_bias[ARM]
            mujoco.mj_step2(m, d)

    return run, scene


def lean_loop() -> tuple[Callable[[int], None], mjk.Scene]:
    """Pinocchio's gravity on mjkdl's chain model, written straight into qfrc_applied."""
    scene = mjk.Scene.build(tabletop_spec())
    model = scene.create_robot("base_link", "bracelet_link", tool=TOOL).model
    data = model.createData()
    m, d = scene.model, scene.data
    d.qpos[ARM] = HOME
    m.actuator_gainprm[ARM] = 0.0
    m.actuator_biasprm[ARM] = 0.0
    mujoco.mj_forward(m, d)
    q, qpos, applied = np.zeros(7), d.qpos[:7], d.qfrc_applied[:7]

    def run(n: int) -> None:
        for _ in range(n):
            np.copyto(q, qpos)
            applied[:] = pin.computeGeneralizedGravity(model, data, q)
            mujoco.mj_step(m, d)

    return run, scene


def mjkdl_loop() -> tuple[Callable[[int], None], mjk.Scene, mjk.Robot]:
    scene = mjk.Scene.build(tabletop_spec())
    robot = scene.create_robot("base_link", "bracelet_link", tool=TOOL)
    robot.set_joint_pos(HOME)
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    robot.sync_commands()

    def run(n: int) -> None:
        for _ in range(n):
            robot.update()
            robot.jnt_trq_cmd = robot.gravity_torques()
            robot.step()

    return run, scene, robot


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", choices=["raw", "lean", "mjkdl"], help="run one loop only")
    parser.add_argument("--steps", type=int, default=1000, help="steps for --only")
    args = parser.parse_args()

    raw, raw_scene = raw_loop()
    lean, lean_scene = lean_loop()
    ours, scene, robot = mjkdl_loop()
    loops = {"raw": raw, "lean": lean, "mjkdl": ours}
    for run in loops.values():
        run(WARMUP)
    if args.only:
        loops[args.only](args.steps)
        return

    times: dict[str, list[float]] = {name: [] for name in loops}
    for _ in range(BLOCKS):
        for name, run in loops.items():
            t0 = time.perf_counter()
            run(STEPS)
            times[name].append((time.perf_counter() - t0) / STEPS)
    base = np.array(times["raw"])

    tracemalloc.start()
    ours(100)
    before = tracemalloc.take_snapshot()
    ours(2000)
    after = tracemalloc.take_snapshot()
    tracemalloc.stop()
    retained = sum(s.size_diff for s in after.compare_to(before, "filename"))
    robot.update()
    drift = np.abs(robot.jnt_pos_msr - HOME).max()

    print(f"MuJoCo {mjk.mujoco_version()}, {BLOCKS} blocks x {STEPS} steps, interleaved")
    for name in loops:
        t = np.array(times[name])
        ratio = t / base
        print(
            f"{name:6} median {np.median(t) * 1e6:7.2f} us/step   ratio to raw: median "
            f"{np.median(ratio):.3f} (p10 {np.percentile(ratio, 10):.3f}, "
            f"p90 {np.percentile(ratio, 90):.3f})"
        )
    print(f"memory retained over 2000 mjkdl steps: {retained} bytes")
    print(f"largest joint drift of the held arm after the run: {drift:.2e} rad")
    for s in (raw_scene, lean_scene, scene):
        s.close()


if __name__ == "__main__":
    main()
