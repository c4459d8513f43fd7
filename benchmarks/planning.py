"""Motion planning: success, planning time and clearance on random queries in clutter.

For Menagerie's Panda (with its hand, on the floor) and the tutorial's Gen3 + 2F-85 (on the
table), the same clutter is placed around the arm's base: two shelves, a wall between them, two
posts, a box and a beam overhead. Queries are pairs of random joint configurations (uniform
within the limits, unlimited joints in [-π, π]) that keep the planner's 5 mm margin, drawn
with np.random.default_rng(0). Each is planned with `MotionPlanner.plan(goal, start=...,
timeout=1.0)` (RRTConnect): success within the timeout, planning time (everything: search,
simplification, toppra, the final check) and the search alone, as median and 90th percentile.

Then, in the same process:
  * each query's planning time in mj_steps of the same model, timed just before it (the
    shared machine's speed drifts);
  * the cost of one validity check (`CollisionChecker.valid`) on random configurations, as a
    ratio to one raw `mj_step` of the same model;
  * every planned trajectory is executed in the simulation (`TrajectoryFollower`, POSITION
    mode) and the measured arm's clearance to everything is taken at every physics step: the
    smallest, and how many trajectories came closer than the margin.

pyroboplan (the peer the issue names) is not run: its wheel pins pin==4.0.0 and pulls drake,
which would replace this environment's Pinocchio.

    python benchmarks/planning.py                      # a few minutes
    python benchmarks/planning.py --queries 10 --execute 3
"""

from __future__ import annotations

import argparse
import itertools
import time

import mujoco
import numpy as np
from scenes import HOME, TOOL, tabletop_spec

import mjkdl as mjk
from mjkdl.plan import CollisionChecker, MotionPlanner, PlanningError, TrajectoryFollower

PANDA_HOME = [0.0, 0.0, 0.0, -1.57079, 0.0, 1.57079, -0.7853]
PANDA_TCP = [0.0, 0.0, 0.1034]
TABLE_TOP = 0.7


def clutter(base: np.ndarray) -> list[mjk.SceneObject]:
    """Shelves, a wall, posts, a box and a beam around an arm whose base is at `base`."""

    def box(name: str, size: list[float], offset: list[float]) -> mjk.SceneObject:
        return mjk.SceneObject(
            name=name,
            shape=mjk.Shape.BOX,
            size=size,
            pos=list(base + offset),
            fixed=True,
            rgba=[0.6, 0.5, 0.4, 1.0],
        )

    return [
        box("shelf_a", [0.12, 0.12, 0.01], [0.45, 0.35, 0.29]),
        box("shelf_b", [0.12, 0.12, 0.01], [0.45, -0.35, 0.29]),
        box("wall", [0.25, 0.01, 0.35], [0.55, 0.0, 0.35]),
        box("post_a", [0.04, 0.04, 0.3], [-0.3, 0.4, 0.3]),
        box("post_b", [0.05, 0.05, 0.25], [-0.35, -0.35, 0.25]),
        box("block", [0.08, 0.08, 0.08], [0.0, 0.55, 0.08]),
        box("beam", [0.02, 0.5, 0.02], [0.3, 0.0, 1.0]),
    ]


def panda_scene() -> tuple[mjk.Env, mjk.Robot, list[float]]:
    arm = mjk.RobotSpec(path=mjk.menagerie.model_path("franka_emika_panda"))
    spec = mjk.SceneSpec(
        timestep=0.002,
        add_floor=True,
        add_skybox=False,
        robots=[arm],
        objects=clutter(np.zeros(3)),
    )
    env = mjk.Env.build(spec)
    robot = env.create_robot("link0", "hand", tool=mjk.ToolFrameSpec(tcp_pos=PANDA_TCP))
    return env, robot, PANDA_HOME


def gen3_scene() -> tuple[mjk.Env, mjk.Robot, list[float]]:
    spec = tabletop_spec()
    spec.objects += clutter(np.array([0.0, 0.0, TABLE_TOP]))
    env = mjk.Env.build(spec)
    return env, env.create_robot("base_link", "bracelet_link", tool=TOOL), HOME


def queries(planner: MotionPlanner, count: int, rng: np.random.Generator) -> list[np.ndarray]:
    """`count` + 1 random configurations that keep the margin (consecutive pairs: queries)."""
    limits = planner.robot.joint_limits
    low = np.where(np.isfinite(limits[:, 0]), limits[:, 0], -np.pi)
    high = np.where(np.isfinite(limits[:, 1]), limits[:, 1], np.pi)
    out: list[np.ndarray] = []
    while len(out) <= count:
        q = rng.uniform(low, high)
        if planner.checker.valid(q):
            out.append(q)
    return out


def per_call(fn, count: int) -> float:
    """Median seconds per call of `fn` over 7 blocks of `count` calls."""
    blocks = []
    for _ in range(7):
        t0 = time.perf_counter()
        for _ in range(count):
            fn()
        blocks.append((time.perf_counter() - t0) / count)
    return float(np.median(blocks))


def benchmark(name: str, scene, args: argparse.Namespace) -> None:
    env, robot, home = scene()
    robot.ctrl_mode = mjk.CtrlMode.POSITION
    env.on_reset = lambda ctx: robot.set_joint_pos(home, call_forward=False)
    env.reset()
    robot.update()
    planner = MotionPlanner(robot)
    rng = np.random.default_rng(0)
    configs = queries(planner, args.queries, rng)
    planner.plan(configs[1], start=configs[0])  # warm-up (imports, first IK)

    # Each query is also timed in mj_steps of the same model, measured just before it: the
    # shared machine's speed drifts by 2x and more within minutes.
    scratch = mujoco.MjData(env.model)
    mujoco.mj_copyData(scratch, env.model, env.data)
    total, search, steps, trajectories, failures = [], [], [], [], []
    for start, goal in itertools.pairwise(configs):
        t0 = time.perf_counter()
        for _ in range(20):
            mujoco.mj_step(env.model, scratch)
        step_now = (time.perf_counter() - t0) / 20
        t0 = time.perf_counter()
        try:
            traj = planner.plan(goal, start=start, timeout=args.timeout)
        except PlanningError as error:
            failures.append(str(error).split(":")[0])
            continue
        total.append(time.perf_counter() - t0)
        steps.append(total[-1] / step_now)
        search.append(planner.last_stats["search"] + planner.last_stats["simplify"])
        trajectories.append(traj)

    # One validity check against one raw mj_step (on a scratch copy of the same state).
    samples = rng.uniform(-1.0, 1.0, (1000, robot.n_joints)) * 0.5 + np.array(home)
    index = iter(range(10**9))
    check = per_call(lambda: planner.checker.valid(samples[next(index) % 1000]), 1000)
    step = per_call(lambda: mujoco.mj_step(env.model, scratch), 1000)

    # Execute, measuring the measured arm's clearance at every step.
    watch = CollisionChecker(robot, planner.margin, reach=0.05)
    follower = TrajectoryFollower(robot)
    closest, below = [], 0
    for traj in trajectories[: args.execute]:
        env.reset()
        robot.set_joint_pos(traj.positions[0])
        robot.sync_commands()
        watch.sync()
        mins = [np.inf]

        def measure(mins: list[float] = mins) -> None:
            mins.append(watch.clearance(env.data.qpos[watch.arm_qpos_adr]))

        follower.run(traj, after_step=measure)
        closest.append(min(mins))
        below += min(mins) < planner.margin

    n = args.queries
    ms_total, ms_search = np.array(total) * 1e3, np.array(search) * 1e3
    print(f"{name}: {n} random queries, RRTConnect, timeout {args.timeout:g} s, margin 5 mm")
    print(f"  solved:                {len(total) / n * 100:.1f} % ({len(total)}/{n})")
    if failures:
        print(f"  failures:              {', '.join(sorted(set(failures)))}")
    print(
        f"  planning time:         median {np.median(ms_total):.1f} ms, "
        f"p90 {np.percentile(ms_total, 90):.1f} ms (search + simplification + toppra + check)"
    )
    print(
        f"  planning time / step:  median {np.median(steps):.0f} mj_steps, "
        f"p90 {np.percentile(steps, 90):.0f} (each against a step timed just before it)"
    )
    print(
        f"  search + simplify:     median {np.median(ms_search):.1f} ms, "
        f"p90 {np.percentile(ms_search, 90):.1f} ms"
    )
    print(f"  straight line enough:  {np.mean(np.array(search) == 0) * 100:.0f} % of solved")
    print(f"  trajectory duration:   median {np.median([t.duration for t in trajectories]):.2f} s")
    print(
        f"  validity check:        {check * 1e6:.1f} us = {check / step:.2f} x mj_step "
        f"({step * 1e6:.1f} us)"
    )
    print(
        f"  executed:              {len(closest)} trajectories, closest approach "
        f"{min(closest) * 1000:.2f} mm, {below} closer than the margin"
    )
    env.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--queries", type=int, default=100)
    parser.add_argument("--timeout", type=float, default=1.0)
    parser.add_argument("--execute", type=int, default=100, help="trajectories run in simulation")
    parser.add_argument("--robots", nargs="+", default=["panda", "gen3"])
    args = parser.parse_args()
    scenes = {"panda": ("Panda + hand", panda_scene), "gen3": ("Gen3 + 2F-85", gen3_scene)}
    for key in args.robots:
        benchmark(*scenes[key], args)


if __name__ == "__main__":
    main()
