"""Motion planning: the Panda carries a cube from one shelf to the other, around a wall.

The two shelves stand either side of the arm with a 0.7 m wall between them, so no straight
move connects them. `MotionPlanner` plans each leg collision-free with OMPL (MuJoCo's own
collision checks, 5 mm margin) and times it with toppra; `TrajectoryFollower` plays it in
POSITION mode with velocity and dynamics feed-forward. The legs:

    down to the cube on shelf A (straight line) -> close the hand -> up (straight line)
    -> above shelf B carrying the cube (plan) -> down (straight line) -> open the hand
    -> up (straight line) -> back above shelf A (plan)

While the cube is held, `carry="cube"` moves it with the hand in the planner's checks, so the
cube clears the wall too, and a second planner with half the velocity and a quarter of the
acceleration limits moves it. Headless, the script prints each leg's planning time and
duration, the largest tracking error and where the cube ended.

OMPL samples at random; `--seed` fixes its generator so a run repeats. Menagerie's hand holds
the cube by friction alone (about 2 N of squeeze), and on some paths the cube creeps out of
the fingers mid-carry without touching anything, or slips far enough to meet shelf B on the
way down (seeds 1, 2, 4, 5, 9 and 10 of the first eleven): a limit of the simulated grasp,
not of the plan.

    python examples/plan_shelves.py
    python examples/plan_shelves.py --headless --seed 3
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Iterator

import numpy as np
import ompl.util
import pinocchio as pin
from common import (
    PANDA_HAND,
    PANDA_HOME,
    create_panda,
    look_at,
    panda,
    panda_scene,
    parse_args,
    run,
)

import mjkdl as mjk
from mjkdl.plan import JointTrajectory, MotionPlanner, TrajectoryFollower

SHELF_TOP = 0.30  # m
SHELF_A = np.array([0.45, 0.35])
SHELF_B = np.array([0.45, -0.35])
CUBE_HALF = 0.02
HAND_OPEN, HAND_CLOSED = 255.0, 0.0
GRASP = SHELF_TOP + CUBE_HALF + 0.005  # TCP height holding the cube (fingertips off the shelf)
HOVER = 0.15  # above the grasp height, for the planned legs
RELEASE = 0.02  # the held cube (it slips a little in the grasp) is let go this far up
SEED = 3  # OMPL's (see above)
DOWN = np.diag([1.0, -1.0, -1.0])  # TCP z pointing down


def shelves() -> list[mjk.SceneObject]:
    """Two shelves, the wall between them, and the cube on shelf A."""

    def board(name: str, size: list[float], pos: list[float]) -> mjk.SceneObject:
        return mjk.SceneObject(
            name=name, shape=mjk.Shape.BOX, size=size, pos=pos, fixed=True, rgba=[0.6, 0.5, 0.4, 1]
        )

    return [
        board("shelf_a", [0.12, 0.12, 0.01], [*SHELF_A, SHELF_TOP - 0.01]),
        board("shelf_b", [0.12, 0.12, 0.01], [*SHELF_B, SHELF_TOP - 0.01]),
        board("wall", [0.25, 0.01, 0.35], [0.55, 0.0, 0.35]),
        mjk.SceneObject(
            name="cube",
            shape=mjk.Shape.BOX,
            size=[CUBE_HALF] * 3,
            pos=[*SHELF_A, SHELF_TOP + CUBE_HALF],
            mass=0.05,
            rgba=[0.1, 0.25, 1.0, 1.0],
            condim=mjk.Condim.Torsional,
            friction=[1.0, 0.02, 0.001],
        ),
    ]


def at(xy: np.ndarray, z: float) -> pin.SE3:
    return pin.SE3(DOWN, np.array([*xy, z]))


def options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seed", type=int, default=SEED, help=f"OMPL's seed (default {SEED})")


def main() -> int:
    args = parse_args(__doc__.splitlines()[0], duration=20.0, extra=options)
    # OMPL draws its samples from one process-wide generator: seeded, the run repeats.
    ompl.util.RNG.setSeed(args.seed)
    camera = look_at("task", eye=[1.7, 0.0, 1.3], target=[0.3, 0.0, 0.35])
    with mjk.Env.build(panda_scene([panda()], shelves(), camera)) as env:
        robot = create_panda(env)
        # Start (and end) above shelf A: Menagerie's home pose would be inside the wall.
        ready = robot.ik(at(SHELF_A, GRASP + HOVER), PANDA_HOME).q
        env.on_reset = lambda ctx: robot.set_joint_pos(ready, call_forward=False)
        env.reset()
        robot.update()
        env.set_actuator_ctrl(PANDA_HAND, HAND_OPEN)
        # The fingers touch the cube they grasp: those contacts do not count.
        fingers = [("left_finger", "cube"), ("right_finger", "cube"), ("hand", "cube")]
        planner = MotionPlanner(robot, allowed_contacts=fingers)
        # Carrying, at half the speed and a quarter of the acceleration: the hand's grip is light.
        gentle = MotionPlanner(
            robot,
            allowed_contacts=fingers,
            velocity_limits=0.5 * planner.velocity_limits,
            acceleration_limits=0.25 * planner.acceleration_limits,
        )
        follower = TrajectoryFollower(robot)
        done = [False]

        def leg(name: str, make) -> Iterator[None]:
            t0 = time.perf_counter()
            traj: JointTrajectory = make()
            took = (time.perf_counter() - t0) * 1e3
            follower.start(traj)
            while not follower.finished:
                robot.update()
                follower.command()
                yield
            cube = env.body_frame("cube").translation
            print(
                f"{name}: planned in {took:.0f} ms, {traj.duration:.2f} s, "
                f"max error {follower.max_error * 1000:.1f} mrad, cube at z {cube[2]:.3f} m",
                flush=True,
            )

        def hold(seconds: float) -> Iterator[None]:
            for _ in range(round(seconds / env.timestep())):
                robot.update()
                yield

        def mission() -> Iterator[None]:
            yield from leg("down to the cube", lambda: planner.plan_cartesian(at(SHELF_A, GRASP)))
            env.set_actuator_ctrl(PANDA_HAND, HAND_CLOSED)
            yield from hold(0.6)
            yield from leg("lift", lambda: gentle.plan_cartesian(at(SHELF_A, GRASP + HOVER)))
            yield from leg(
                "around the wall to shelf B",
                lambda: gentle.plan(at(SHELF_B, GRASP + HOVER), carry="cube"),
            )
            yield from leg(
                "down to shelf B",
                lambda: gentle.plan_cartesian(at(SHELF_B, GRASP + RELEASE), carry="cube"),
            )
            env.set_actuator_ctrl(PANDA_HAND, HAND_OPEN)
            yield from hold(0.6)
            yield from leg("retreat", lambda: planner.plan_cartesian(at(SHELF_B, GRASP + HOVER)))
            yield from leg("back around the wall", lambda: planner.plan(ready))
            done[0] = True

        steps = mission()

        def control() -> None:
            if next(steps, "over") == "over":  # after the last leg: hold where it ended
                robot.update()

        run(
            env, control, args, robot=robot, title="Planning: shelf to shelf", until=lambda: done[0]
        )
        cube = env.body_frame("cube").translation
        error = float(np.linalg.norm(cube[:2] - SHELF_B))
        on_shelf = abs(cube[2] - (SHELF_TOP + CUBE_HALF)) < 0.005
        print(f"cube at ({cube[0]:.3f}, {cube[1]:.3f}, {cube[2]:.3f})")
        print(f"place error: {error:.4f} m")
        success = done[0] and on_shelf and error < 0.02
        print(f"result: {'success' if success else 'FAILURE'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
