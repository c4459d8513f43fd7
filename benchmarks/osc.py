"""Operational-space control: the cost of one `OperationalSpaceController.torques()` call in
`mj_step`s of the same model, and the controller's 5 cm step response.

Four scenes: Menagerie's Panda (with its hand) on a bare floor, the tutorial's Gen3 + 2F-85 on
its table, and each of them in `planning.py`'s clutter (shelves, a wall, posts, a box, a beam:
more geoms, so a dearer `mj_step`). In each, the controller first holds the arm at home for
3 s (the 2F-85's fingers settle), then blocks of `--calls` calls toward a pose 5 cm away
alternate with blocks of as many raw `mujoco.mj_step`s of the same model (on a scratch `MjData`
that restarts every block from the settled state, the holding torques in its controls: the
cheapest steps the scene has, so the ratio flatters nothing). Each figure is the median over
blocks of its ratio to the step block next to it, then the ratio of the fastest blocks of each
(nearer what a quiet machine shows). Rows:

  * `torques()`: robosuite's OSC_POSE, whole task-space inertia (the default);
  * `torques()`, decoupled: position and orientation blocks inverted apart;
  * `command()`: `torques()` plus the checked write to `jnt_trq_cmd`;
  * Pinocchio alone: the library calls `torques()` cannot do without (CRBA, the frame's
    placement and Jacobian, log3, `robot.nonlinear_effects()`'s RNEA), the floor of any
    Python implementation on this Robot handle.

Then tracemalloc over 1000 calls (what one call allocates for a moment and what stays), and on
the bare scenes 5 cm steps along x, y and z from home (kp 150, critically damped, 1.5 s):
settling time within 2 mm, overshoot along the step, largest TCP rotation.

    python benchmarks/osc.py                         # about a minute
    python benchmarks/osc.py --blocks 3 --calls 50
"""

from __future__ import annotations

import argparse
import math
import time
import tracemalloc
from collections.abc import Callable

import mujoco
import numpy as np
import pinocchio as pin
from planning import PANDA_HOME, PANDA_TCP, gen3_scene, panda_scene
from scenes import HOME, TOOL, tabletop_spec

import mjkdl as mjk
from mjkdl.control import OperationalSpaceController

STEP = 0.05  # m
SETTLE = 1500  # steps (3 s) before timing


def bare_panda() -> tuple[mjk.Env, mjk.Robot, list[float]]:
    arm = mjk.RobotSpec(path=mjk.menagerie.model_path("franka_emika_panda"))
    spec = mjk.SceneSpec(timestep=0.002, add_floor=True, add_skybox=False, robots=[arm])
    env = mjk.Env.build(spec)
    robot = env.create_robot("link0", "hand", tool=mjk.ToolFrameSpec(tcp_pos=PANDA_TCP))
    return env, robot, PANDA_HOME


def bare_gen3() -> tuple[mjk.Env, mjk.Robot, list[float]]:
    env = mjk.Env.build(tabletop_spec())
    return env, env.create_robot("base_link", "bracelet_link", tool=TOOL), HOME


SCENES = {
    ("panda", "bare"): ("Panda + hand, bare floor", bare_panda),
    ("panda", "clutter"): ("Panda + hand, planning clutter", panda_scene),
    ("gen3", "bare"): ("Gen3 + 2F-85, bare table", bare_gen3),
    ("gen3", "clutter"): ("Gen3 + 2F-85, planning clutter", gen3_scene),
}


def at_home(scene: Callable[[], tuple[mjk.Env, mjk.Robot, list[float]]]):
    """The scene with its robot at home in TORQUE mode, measured."""
    env, robot, home = scene()
    env.on_reset = lambda ctx: robot.set_joint_pos(home, call_forward=False)
    robot.ctrl_mode = mjk.CtrlMode.TORQUE
    env.reset()
    robot.update()
    return env, robot


def step_target(robot: mjk.Robot, offset: np.ndarray) -> pin.SE3:
    pose = robot.fk_frame()
    return pin.SE3(pose.rotation, pose.translation + offset)


def pinocchio_alone(robot: mjk.Robot) -> Callable[[], object]:
    """The Pinocchio calls of one `torques()`, on a Data of their own."""
    model, frame = robot.model, robot.tcp_frame_id
    data, q = model.createData(), robot.q
    rotation = robot.fk_frame().rotation
    world, lwa = pin.Convention.WORLD, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED

    def run() -> object:
        pin.crba(model, data, q, world)
        pin.updateFramePlacement(model, data, frame)
        pin.getFrameJacobian(model, data, frame, lwa)
        pin.log3(rotation)
        return robot.nonlinear_effects()

    return run


def cost(name: str, scene, blocks: int, calls: int) -> None:
    env, robot = at_home(scene)
    m = env.model
    osc = OperationalSpaceController(robot)
    decoupled = OperationalSpaceController(robot, decoupled=True)
    hold = robot.fk_frame()
    for _ in range(SETTLE):  # the OSC holds home while the 2F-85's fingers settle
        osc.command(hold)
        robot.step()
        robot.update()
    osc.command(hold)
    robot.update()  # the holding torques are in data.ctrl: the raw steps keep the arm there
    target = step_target(robot, np.array([STEP, 0.0, 0.0]))
    start, scratch = mujoco.MjData(m), mujoco.MjData(m)
    mujoco.mj_copyData(start, m, env.data)

    def raw_steps() -> None:
        for _ in range(calls):
            mujoco.mj_step(m, scratch)

    def repeat(fn: Callable[[], object]) -> Callable[[], None]:
        def run() -> None:
            for _ in range(calls):
                fn()

        return run

    cases = {
        "torques()": repeat(lambda: osc.torques(target)),
        "torques(), decoupled": repeat(lambda: decoupled.torques(target)),
        "command()": repeat(lambda: osc.command(target)),
        "Pinocchio alone": repeat(pinocchio_alone(robot)),
    }
    for run in cases.values():  # warm-up
        run()
    steps: list[float] = []
    times: dict[str, list[float]] = {key: [] for key in cases}
    for _ in range(blocks):
        mujoco.mj_copyData(scratch, m, start)
        t0 = time.perf_counter()
        raw_steps()
        steps.append((time.perf_counter() - t0) / calls)
        for key, run in cases.items():
            t0 = time.perf_counter()
            run()
            times[key].append((time.perf_counter() - t0) / calls)
    step = np.array(steps)
    print(f"{name} ({m.ngeom} geoms, nv {m.nv}):")
    print(f"  mj_step:                 {np.median(step) * 1e6:.1f} us")
    for key, seconds in times.items():
        ratio = np.median(np.array(seconds) / step)
        best = min(seconds) / step.min()
        print(
            f"  {key + ':':24} {ratio:.2f} x mj_step ({np.median(seconds) * 1e6:.1f} us); "
            f"fastest blocks {best:.2f} x"
        )

    tracemalloc.start()
    base = tracemalloc.get_traced_memory()[0]
    for _ in range(1000):
        osc.torques(target)
    retained, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    print(
        f"  allocation:              {peak - base} B at most during a call, {retained - base} B "
        "still held after 1000 calls"
    )
    env.close()


def step_response(name: str, scene) -> None:
    """Settling time, overshoot and largest rotation of 5 cm steps along x, y and z."""
    env, robot = at_home(scene)
    dt = env.timestep()
    settle, overshoot, turn = [], [], []
    for axis in range(3):
        env.reset()
        robot.update()
        offset = np.zeros(3)
        offset[axis] = STEP
        start = robot.fk_frame()
        target = step_target(robot, offset)
        osc = OperationalSpaceController(robot)
        outside, beyond, rotation = 0, 0.0, 0.0
        for i in range(round(1.5 / dt)):
            osc.command(target)
            robot.step()
            robot.update()
            pose = robot.fk_frame()
            if np.linalg.norm(pose.translation - target.translation) > 0.002:
                outside = i + 1
            beyond = max(beyond, pose.translation[axis] - start.translation[axis] - STEP)
            rotation = max(rotation, np.linalg.norm(pin.log3(start.rotation.T @ pose.rotation)))
        settle.append(outside * dt)
        overshoot.append(beyond / STEP * 100)
        turn.append(math.degrees(rotation))
    times = " / ".join(f"{s:.2f}" for s in settle)
    print(
        f"  {name}: settles within 2 mm in {times} s (x / y / z), overshoot at most "
        f"{max(overshoot):.2f} %, TCP rotation at most {max(turn):.2f} deg"
    )
    env.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--blocks", type=int, default=21)
    parser.add_argument("--calls", type=int, default=500, help="calls (and mj_steps) per block")
    parser.add_argument("--robots", nargs="+", default=["panda", "gen3"])
    args = parser.parse_args()
    print(
        f"OperationalSpaceController against one raw mj_step of the same model: median of "
        f"{args.blocks} interleaved blocks of {args.calls} calls"
    )
    for robot in args.robots:
        for kind in ("bare", "clutter"):
            cost(*SCENES[robot, kind], args.blocks, args.calls)
    print("Step response, 5 cm steps from home (kp 150, critically damped), bare scenes:")
    for robot in args.robots:
        name, scene = SCENES[robot, "bare"]
        step_response(name.split(",")[0], scene)


if __name__ == "__main__":
    main()
