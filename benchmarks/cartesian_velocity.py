"""Cartesian velocity control: the cost of one QP solve, and how well the TCP tracks.

Timing. The controller drives a figure eight (as in examples/cartesian_velocity.py); at every
step of that loop, in the same process and on the same model, it times
  (a) `controller.solve(twist)` — Jacobian, cost, bounds, the DAQP solve, checks;
  (b) one raw `mujoco.mj_step` of the same model from the same state (on a scratch copy);
and reports median(a) / median(b). Done for Menagerie's Panda with its hand and for the
tutorial's Gen3 + 2F-85 on the table, without and with collision avoidance active.

Solvers. The QPs the controller built along the way are handed again to: DAQP's reusable
workspace (what the controller uses), `daqp.solve`, `qpsolvers.solve_qp` with DAQP and with
ProxQP, ProxSuite's dense solver called directly (warm-started), and — for the same task
from scratch — pin-pink's `solve_ik` (FrameTask + PostureTask, configuration and velocity
limits, DAQP). Each as a ratio to mj_step, with its largest deviation from the controller's
answer.

Tracking. A constant 5 cm/s twist for 2 s, a pure 0.3 rad/s rotation, and the figure eight,
in VELOCITY and POSITION mode: the error along the commanded axis, off the axis, the rotation.

    python benchmarks/cartesian_velocity.py            # about a minute
    python benchmarks/cartesian_velocity.py --steps 500
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable
from importlib.metadata import version

import daqp
import mujoco
import numpy as np
import pinocchio as pin
import proxsuite
import qpsolvers
from scenes import HOME, TOOL, tabletop_spec
from tqdm import tqdm

import mjkdl as mjk

PANDA_HOME = np.array([0.0, 0.0, 0.0, -1.57079, 0.0, 1.57079, -0.7853])
PANDA_TCP = mjk.ToolFrameSpec(tcp_pos=[0.0, 0.0, 0.1034])
RADIUS = 0.1


def panda_spec(objects: list[mjk.SceneObject] | None = None) -> mjk.SceneSpec:
    arm = mjk.RobotSpec(path=mjk.menagerie.model_path("franka_emika_panda"))
    return mjk.SceneSpec(
        timestep=0.002, add_floor=True, add_skybox=False, robots=[arm], objects=objects or []
    )


def arm(env: mjk.Env, mode: mjk.CtrlMode, chain: tuple, tool: mjk.ToolFrameSpec, home) -> mjk.Robot:
    """The robot on `chain` (base, tip) in `mode`, reset to `home`."""
    robot = env.create_robot(*chain, tool=tool)
    env.on_reset = lambda ctx: robot.set_joint_pos(home, call_forward=False)
    robot.ctrl_mode = mode
    env.reset()
    robot.update()
    return robot


def panda(env: mjk.Env, mode: mjk.CtrlMode) -> mjk.Robot:
    return arm(env, mode, ("link0", "hand"), PANDA_TCP, PANDA_HOME)


def gen3(env: mjk.Env, mode: mjk.CtrlMode) -> mjk.Robot:
    return arm(env, mode, ("base_link", "bracelet_link"), TOOL, HOME)


def eight(t: float) -> np.ndarray:
    return np.array([RADIUS * math.cos(t), RADIUS * math.cos(2 * t), 0.0, 0.0, 0.0, 0.0])


def median_us(samples: list[float]) -> float:
    return float(np.median(samples)) * 1e6


# ---------------------------------------------------------------------- timing


def time_loop(
    env: mjk.Env, robot: mjk.Robot, ctrl: mjk.CartesianVelocityController, steps: int
) -> tuple[float, float, list[tuple]]:
    """Median solve() and raw mj_step times along the figure eight; the QPs seen on the way."""
    model, data = env.model, env.data
    scratch = mujoco.MjData(model)
    solve_t, step_t, problems = [], [], []
    clock = time.perf_counter
    for k in range(steps):
        robot.update()
        twist = eight(env.time())
        t0 = clock()
        ctrl.solve(twist)
        t1 = clock()
        solve_t.append(t1 - t0)
        if k % 10 == 0:
            problems.append(ctrl_problem(ctrl))
        ctrl.command(twist)
        mujoco.mj_copyData(scratch, model, data)
        t0 = clock()
        mujoco.mj_step(model, scratch)
        t1 = clock()
        step_t.append(t1 - t0)
        env.step()
    return median_us(solve_t), median_us(step_t), problems


def ctrl_problem(ctrl: mjk.CartesianVelocityController) -> tuple:
    """The QP the controller just solved (H, f, bounds, its answer, the robot's q)."""
    n = ctrl.robot.n_joints
    return (
        ctrl._H.copy(),
        ctrl._f.copy(),
        ctrl._bu[:n].copy(),
        ctrl._bl[:n].copy(),
        ctrl._last.copy(),
        ctrl.robot.jnt_pos_cmd.copy(),
    )


def solver_table(problems: list[tuple], step_us: float, robot: mjk.Robot) -> None:
    """Each QP library on the controller's own problems; and pink on the same task."""
    n = robot.n_joints
    empty = np.zeros((0, n))
    workspace = daqp.Model()
    H, f, ub, lb, *_ = problems[0]
    workspace.setup(H, f, empty, ub, lb)
    prox = proxsuite.proxqp.dense.QP(n, 0, 0, True)
    prox.settings.eps_abs = 1e-9
    prox.init(H, f, None, None, None, None, None, lb, ub)
    prox.settings.initial_guess = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT

    def daqp_workspace(H, f, ub, lb):
        workspace.update(H=H, f=f, bupper=ub, blower=lb)
        return workspace.solve()[0]

    def proxsuite_direct(H, f, ub, lb):
        prox.update(H=H, g=f, l_box=lb, u_box=ub)
        prox.solve()
        return prox.results.x

    solvers: dict[str, Callable] = {
        "daqp.Model update+solve (used)": daqp_workspace,
        "daqp.solve": lambda H, f, ub, lb: daqp.solve(H, f, empty, ub, lb)[0],
        "qpsolvers daqp": lambda H, f, ub, lb: qpsolvers.solve_qp(
            H, f, lb=lb, ub=ub, solver="daqp"
        ),
        "qpsolvers proxqp": lambda H, f, ub, lb: qpsolvers.solve_qp(
            H, f, lb=lb, ub=ub, solver="proxqp", eps_abs=1e-9
        ),
        "proxsuite dense, direct, warm": proxsuite_direct,
    }
    print(
        f"  {'QP solver on the same problems':34s} {'median':>9s} {'/ mj_step':>10s} "
        f"{'max |dx|':>10s}"
    )
    for name, solve in solvers.items():
        times, worst = [], 0.0
        for _ in range(5):
            for H, f, ub, lb, x, _ in problems:
                t0 = time.perf_counter()
                out = solve(H, f, ub, lb)
                times.append(time.perf_counter() - t0)
                worst = max(worst, float(np.abs(out - x).max()))
        us = median_us(times)
        print(f"  {name:34s} {us:7.1f} us {us / step_us:9.2f}x {worst:10.1e}")
    pink_us = time_pink(problems, robot)
    print(f"  {'pin-pink solve_ik (whole task)':34s} {pink_us:7.1f} us {pink_us / step_us:9.2f}x")


def time_pink(problems: list[tuple], robot: mjk.Robot) -> float:
    """pin-pink's solve_ik for the same twist: a FrameTask whose target is one step ahead."""
    import pink
    from pink.limits import ConfigurationLimit, VelocityLimit
    from pink.tasks import FrameTask, PostureTask

    # The robot's model also holds the fingers: pink solves for them too (their posture held).
    model = pin.Model(robot.model)
    model.velocityLimit = np.ones(model.nv)
    data = model.createData()
    frame = model.frames[robot.tcp_frame_id].name
    task = FrameTask(frame, position_cost=1.0, orientation_cost=1.0)
    posture = PostureTask(cost=1e-3)
    limits = [ConfigurationLimit(model), VelocityLimit(model)]
    dt = 0.002
    whole = robot.q.copy()
    whole[robot.arm_q] = problems[0][-1]
    config = pink.Configuration(model, data, whole)
    times = []
    for *_, arm_q in problems:
        q = whole.copy()
        q[robot.arm_q] = arm_q
        t0 = time.perf_counter()
        config.update(q)  # as in a pink control loop: one Configuration, updated
        here = config.get_transform_frame_to_world(frame)
        task.set_target(here * pin.exp6(pin.Motion(np.r_[0.1, 0.0, 0.0], np.zeros(3)) * dt))
        posture.set_target(q)
        pink.solve_ik(config, [task, posture], dt, solver="daqp", limits=limits)
        times.append(time.perf_counter() - t0)
    return median_us(times)


# ---------------------------------------------------------------------- tracking


def track(mode: mjk.CtrlMode, twist: np.ndarray, seconds: float) -> tuple[float, float, float]:
    """Constant `twist` for `seconds`: (along-axis error %, off-axis mm, rotation error deg)."""
    with mjk.Env.build(panda_spec()) as env:
        robot = panda(env, mode)
        ctrl = mjk.CartesianVelocityController(robot)
        start = robot.fk_frame()
        for _ in range(round(seconds / env.timestep())):
            robot.update()
            ctrl.command(twist)
            robot.step()
        if mode is mjk.CtrlMode.POSITION:  # let the servos catch up with the last command
            for _ in range(150):
                robot.update()
                ctrl.command(np.zeros(6))
                robot.step()
        robot.update()
        end = robot.fk_frame()
    moved = end.translation - start.translation
    turned = start.rotation @ pin.log3(start.rotation.T @ end.rotation)
    want_move, want_turn = twist[:3] * seconds, twist[3:] * seconds
    if np.any(want_move):
        axis = want_move / np.linalg.norm(want_move)
        along = 100 * (moved @ axis - np.linalg.norm(want_move)) / np.linalg.norm(want_move)
        off = 1000 * np.linalg.norm(moved - (moved @ axis) * axis)
    else:
        along, off = 0.0, 1000 * np.linalg.norm(moved)
    rot = math.degrees(np.linalg.norm(turned - want_turn))
    return along, off, rot


def eight_errors(mode: mjk.CtrlMode) -> tuple[float, float]:
    """Largest distance (mm) of the commanded and of the measured TCP from the ideal eight."""
    with mjk.Env.build(panda_spec()) as env:
        robot = panda(env, mode)
        ctrl = mjk.CartesianVelocityController(robot)
        start = robot.fk_frame().translation
        worst_cmd = worst_msr = 0.0
        for _ in range(round(2 * math.pi / env.timestep())):
            robot.update()
            t = env.time()
            ideal = start + np.array([RADIUS * math.sin(t), 0.5 * RADIUS * math.sin(2 * t), 0])
            if mode is mjk.CtrlMode.POSITION:
                commanded = robot.fk_frame(robot.jnt_pos_cmd).translation
                worst_cmd = max(worst_cmd, float(np.linalg.norm(commanded - ideal)))
            worst_msr = max(worst_msr, float(np.linalg.norm(robot.fk_frame().translation - ideal)))
            ctrl.command(eight(t))
            robot.step()
    return 1000 * worst_cmd, 1000 * worst_msr


# ---------------------------------------------------------------------- main


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=3000, help="control steps timed per case")
    args = parser.parse_args()
    print(
        f"MuJoCo {mjk.mujoco_version()}, Pinocchio {pin.__version__}, daqp {version('daqp')}, "
        f"qpsolvers {qpsolvers.__version__}, proxsuite {proxsuite.__version__}, "
        f"pin-pink {version('pin-pink')}"
    )
    print("\nsolve() vs one raw mj_step of the same model (medians along a figure eight)")
    print(f"  {'case':44s} {'solve':>9s} {'mj_step':>9s} {'ratio':>7s}")
    block = mjk.SceneObject(
        name="block",
        shape=mjk.Shape.BOX,
        size=[0.1, 0.1, 0.2],
        pos=[0.55, 0.0, 0.2],
        fixed=True,
    )
    cases = [
        ("Panda + hand, POSITION", panda_spec(), panda, {}),
        ("Panda + hand, VELOCITY", panda_spec(), panda, {}),
        (
            "Panda + hand, avoid hand/block (13 pairs)",
            panda_spec([block]),
            panda,
            {"avoid": [("hand", "block")]},
        ),
        ("Gen3 + 2F-85 on the table, POSITION", tabletop_spec(), gen3, {}),
    ]
    panda_problems: list[tuple] = []
    panda_step = 0.0
    for name, spec, make, kw in tqdm(cases, desc="scenes", disable=None, leave=False):
        mode = mjk.CtrlMode.VELOCITY if "VELOCITY" in name else mjk.CtrlMode.POSITION
        with mjk.Env.build(spec) as env:
            robot = make(env, mode)
            ctrl = mjk.CartesianVelocityController(robot, **kw)
            solve_us, step_us, problems = time_loop(env, robot, ctrl, args.steps)
            tqdm.write(
                f"  {name:44s} {solve_us:6.1f} us {step_us:6.1f} us {solve_us / step_us:6.2f}x"
            )
            if name == "Panda + hand, POSITION":
                panda_problems, panda_step = problems, step_us
                with mjk.Env.build(panda_spec()) as env2, tqdm.external_write_mode():
                    solver_robot = panda(env2, mode)
                    print()
                    solver_table(panda_problems, panda_step, solver_robot)
                    print()
    print("\ntracking, Panda + hand (POSITION measured after the servos caught up, 0.3 s)")
    print(f"  {'motion':34s} {'mode':9s} {'along axis':>11s} {'off axis':>9s} {'rotation':>9s}")
    motions = [
        ("5 cm/s along x for 2 s", np.array([0.05, 0, 0, 0, 0, 0]), 2.0),
        ("5 cm/s along z for 2 s", np.array([0, 0, 0.05, 0, 0, 0]), 2.0),
        ("0.3 rad/s about z for 2 s", np.array([0, 0, 0, 0, 0, 0.3]), 2.0),
    ]
    for label, twist, seconds in motions:
        for mode in (mjk.CtrlMode.VELOCITY, mjk.CtrlMode.POSITION):
            along, off, rot = track(mode, twist, seconds)
            print(f"  {label:34s} {mode.name:9s} {along:+10.2f}% {off:7.2f} mm {rot:7.3f} deg")
    for mode in (mjk.CtrlMode.VELOCITY, mjk.CtrlMode.POSITION):
        cmd, msr = eight_errors(mode)
        command = f"command {cmd:.2f} mm, " if mode is mjk.CtrlMode.POSITION else ""
        print(
            f"  figure eight, r = 0.1 m, 6.3 s ({mode.name}): max distance from the ideal path: "
            f"{command}measured {msr:.2f} mm"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
