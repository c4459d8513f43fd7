"""Control loops of a Robot against hand-written raw-MuJoCo loops, in the same process.

Gen3 (+ Robotiq 2F-85 unless bare) held at the home pose, 2 ms steps. The raw loops switch the
arm's servos off and write MuJoCo's own bias forces into `qfrc_applied` between `mj_step1` and
`mj_step2` (a perfect gravity compensation, at no cost beyond reading them). The mjkdl cases:

    seed            update(); jnt_trq_cmd = gravity_torques(); step()   (TORQUE)
    gravcomp        update(); step()   with robot.gravity_compensation = True
    position        update(); jnt_pos_cmd = HOME; step()   (POSITION, gravity feed-forward),
                    against a raw loop with the same servos and qfrc_bias as feed-forward
    bare seed       the seed loop on a Gen3 without gripper
    floor           no Robot calls: the seed loop's work written out by hand (copy q, v and
                    the measured torque, Pinocchio's gravity on the same model, write the
                    controls, mj_step), the least any wrapper around Pinocchio can cost

each measured settled (after 3 s at rest, fingers open) and, for the gripper cases, over the
first second after a reset while the fingers close. Loops run interleaved in blocks; each
figure is the median of the per-block ratios to the raw loop of the same scene and phase.

    python benchmarks/control_loop.py
    python benchmarks/control_loop.py --only "seed settled" --steps 1000   # e.g. for callgrind
"""

from __future__ import annotations

import argparse
import time
import tracemalloc
from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np
import pinocchio as pin
from scenes import HOME, TOOL, tabletop_spec
from tqdm import tqdm

import mjkdl as mjk

BLOCKS = 40
STEPS = 250  # per block, settled phase
FIRST = 500  # the first second after a reset
WARMUP = 1500  # 3 s: the 2F-85's fingers settle
ARM = np.arange(7)
HOME_Q = np.array(HOME)
FINGERS = "g_fingers_actuator"


@dataclass
class Loop:
    """A loop to time: `run(n)` steps it, `reset()` (untimed) starts a first-second phase."""

    run: Callable[[int], None]
    reset: Callable[[], None]
    scene: mjk.Scene


def _spec(gripper: bool) -> mjk.SceneSpec:
    spec = tabletop_spec()
    if not gripper:
        spec.robots[0].attachments = []
    return spec


def _home(scene: mjk.Scene, close_fingers: bool = False) -> None:
    """Arm at home, at rest, fingers open; `close_fingers`: commanded to close from there."""
    m, d = scene.model, scene.data
    mujoco.mj_resetData(m, d)
    d.qpos[ARM] = HOME_Q
    if close_fingers and scene.has_actuator(FINGERS):
        d.ctrl[scene.actuator_id(FINGERS)] = 255.0
    mujoco.mj_forward(m, d)


def raw_loop(gripper: bool = True, servos_of: mjk.Scene | None = None) -> Loop:
    """The hand-written MuJoCo loop: MuJoCo's bias forces hold the arm.

    Without `servos_of` the arm's servos are switched off and the force goes into
    `qfrc_applied`; with it the arm's actuators get that scene's (POSITION mode) servo
    parameters and the force goes into their controls as feed-forward, holding home.
    """
    scene = mjk.Scene.build(_spec(gripper))
    m, d = scene.model, scene.data
    if servos_of is None:
        m.actuator_gainprm[ARM] = 0.0
        m.actuator_biasprm[ARM] = 0.0
    else:
        src = servos_of.model
        for field in ("gaintype", "biastype", "gainprm", "biasprm", "ctrllimited"):
            getattr(m, f"actuator_{field}")[ARM] = getattr(src, f"actuator_{field}")[ARM]
    # A servo's joint torque is gear * gain * (ctrl - q): feed-forward enters scaled.
    scale = 1.0 / (m.actuator_gear[ARM, 0] * m.actuator_gainprm[ARM, 0]) if servos_of else None
    _home(scene)

    def run(n: int) -> None:
        for _ in range(n):
            mujoco.mj_step1(m, d)
            d.qfrc_applied[ARM] = d.qfrc_bias[ARM]
            mujoco.mj_step2(m, d)

    def run_servo(n: int) -> None:
        for _ in range(n):
            mujoco.mj_step1(m, d)
            d.ctrl[ARM] = HOME_Q + d.qfrc_bias[ARM] * scale
            mujoco.mj_step2(m, d)

    return Loop(run if servos_of is None else run_servo, lambda: _home(scene, True), scene)


def mjkdl_loop(kind: str, gripper: bool = True) -> Loop:
    scene = mjk.Scene.build(_spec(gripper))
    tool = TOOL if gripper else None
    robot = scene.create_robot("base_link", "bracelet_link", tool=tool)
    robot.ctrl_mode = mjk.CtrlMode.POSITION if kind == "position" else mjk.CtrlMode.TORQUE
    robot.gravity_compensation = kind == "gravcomp"

    def reset() -> None:
        _home(scene, close_fingers=True)
        robot.sync_commands()

    _home(scene)
    robot.sync_commands()
    if kind == "seed":

        def run(n: int) -> None:
            for _ in range(n):
                robot.update()
                robot.jnt_trq_cmd = robot.gravity_torques()
                robot.step()

    elif kind == "gravcomp":

        def run(n: int) -> None:
            for _ in range(n):
                robot.update()
                robot.step()

    else:

        def run(n: int) -> None:
            for _ in range(n):
                robot.update()
                robot.jnt_pos_cmd = HOME_Q
                robot.step()

    return Loop(run, reset, scene)


def floor_loop(gripper: bool = True) -> Loop:
    """The seed loop's work without the Robot: what its checks and calls cost on top."""
    scene = mjk.Scene.build(_spec(gripper))
    robot = scene.create_robot("base_link", "bracelet_link", tool=TOOL if gripper else None)
    robot.ctrl_mode = mjk.CtrlMode.TORQUE  # the arm's actuators become motors in joint units
    _home(scene)
    robot.sync_commands()
    m, d = scene.model, scene.data
    pm = robot.model
    pd = pm.createData()
    assert robot.arm_v == slice(0, 7) and np.array_equal(robot.q, d.qpos[: pm.nq])
    qsrc, vsrc, trq_src, ctrl = d.qpos[: pm.nq], d.qvel[: pm.nv], d.qfrc_actuator[:7], d.ctrl[:7]
    q, v, trq, cmd = np.zeros(pm.nq), np.zeros(pm.nv), np.zeros(7), np.zeros(7)
    gravity, step = pin.computeGeneralizedGravity, mujoco.mj_step

    def run(n: int) -> None:
        for _ in range(n):
            q[...] = qsrc
            v[...] = vsrc
            trq[...] = trq_src
            cmd[...] = gravity(pm, pd, q)[:7]
            ctrl[...] = cmd
            step(m, d)

    return Loop(run, lambda: _home(scene, True), scene)


def _retained(run: Callable[[int], None]) -> int:
    """Bytes still allocated after 2000 more steps of `run` (nothing should accumulate)."""
    tracemalloc.start()
    run(100)
    before = tracemalloc.take_snapshot()
    run(2000)
    after = tracemalloc.take_snapshot()
    tracemalloc.stop()
    return sum(s.size_diff for s in after.compare_to(before, "filename"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--only",
        help="run one loop only: a case printed below, or 'raw gripper|bare|servos settled|first'",
    )
    parser.add_argument("--steps", type=int, default=1000, help="steps for --only")
    args = parser.parse_args()

    position = mjkdl_loop("position")
    # A raw loop per scene and phase: a "first" phase restarts from a reset every block.
    raws = {
        ("gripper", "settled"): raw_loop(),
        ("gripper", "first"): raw_loop(),
        ("bare", "settled"): raw_loop(gripper=False),
        ("servos", "settled"): raw_loop(servos_of=position.scene),
    }
    # name -> (loop, the scene of its raw baseline, phase)
    cases: dict[str, tuple[Loop, str, str]] = {
        "seed settled": (mjkdl_loop("seed"), "gripper", "settled"),
        "seed first second": (mjkdl_loop("seed"), "gripper", "first"),
        "bare seed settled": (mjkdl_loop("seed", gripper=False), "bare", "settled"),
        "floor settled": (floor_loop(), "gripper", "settled"),
        "floor first second": (floor_loop(), "gripper", "first"),
        "bare floor settled": (floor_loop(gripper=False), "bare", "settled"),
        "position settled": (position, "servos", "settled"),
        "gravcomp settled": (mjkdl_loop("gravcomp"), "gripper", "settled"),
        "gravcomp first second": (mjkdl_loop("gravcomp"), "gripper", "first"),
    }
    loops = list(raws.values()) + [c[0] for c in cases.values()]
    for loop in loops:
        loop.run(WARMUP)
    if args.only:
        if args.only.startswith("raw "):
            kind, phase = args.only.split()[1:]
            raws[kind, phase].run(args.steps)
        else:
            cases[args.only][0].run(args.steps)
        return

    def timed(loop: Loop, phase: str) -> float:
        n = FIRST if phase == "first" else STEPS
        if phase == "first":
            loop.reset()
        t0 = time.perf_counter()
        loop.run(n)
        return (time.perf_counter() - t0) / n

    ratios: dict[str, list[float]] = {name: [] for name in cases}
    base: dict[tuple[str, str], list[float]] = {}
    for _ in tqdm(range(BLOCKS), desc="blocks", disable=None, leave=False):
        block = {key: timed(loop, key[1]) for key, loop in raws.items()}
        for k, t in block.items():
            base.setdefault(k, []).append(t)
        for name, (loop, key, phase) in cases.items():
            ratios[name].append(timed(loop, phase) / block[key, phase])

    print(f"MuJoCo {mjk.mujoco_version()}, {BLOCKS} interleaved blocks")
    for (key, phase), t in base.items():
        print(f"raw MuJoCo, {key:7} {phase:8}: median {np.median(t) * 1e6:6.2f} us/step")
    for name, r in ratios.items():
        print(
            f"{name:22} ratio to raw: median {np.median(r):.3f} "
            f"(p10 {np.percentile(r, 10):.3f}, p90 {np.percentile(r, 90):.3f})"
        )
    for name in ("seed settled", "gravcomp settled"):
        print(f"memory retained over 2000 steps, {name}: {_retained(cases[name][0].run)} bytes")
    held = cases["gravcomp settled"][0].scene.data.qpos[ARM]
    print(
        f"largest joint drift of the gravity-compensated arm: {np.abs(held - HOME_Q).max():.2e} rad"
    )
    for loop in loops:
        loop.scene.close()


if __name__ == "__main__":
    main()
