"""POSITION mode: the arm's own servos move it back and forth between two poses.

In POSITION mode `update()` turns the chain's actuators into position servos (the Gen3's
Menagerie gains) and adds Pinocchio's gravity torques as feed-forward, so the controller only
writes `jnt_pos_cmd`. The command follows minimum-jerk moves of `--move` seconds from one pose
to the other and back, resting half a second at each end.

    python examples/position_control.py
    python examples/position_control.py --headless --duration 4
"""

from __future__ import annotations

import argparse

import numpy as np
from common import HOME, JointCycle, create_arm, parse_args, run, tutorial_spec

import mjkdl as mjk

# A second pose: turned 60° about the base, leaning forward over the table.
READY = HOME + np.array([1.05, 0.35, 0.0, 0.45, 0.0, -0.4, 0.0])
DWELL = 0.5  # seconds spent at each pose before moving on


def options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--move", type=float, default=1.5, help="seconds per move (default 1.5)")


def main() -> int:
    args = parse_args(__doc__.splitlines()[0], duration=6.0, extra=options)
    with mjk.Env.build(tutorial_spec()) as env:
        robot = create_arm(env)
        robot.ctrl_mode = mjk.CtrlMode.POSITION
        env.on_reset = lambda ctx: robot.set_joint_pos(HOME, call_forward=False)
        env.reset()  # runs the hook, then sets jnt_pos_cmd to the measured (home) pose
        cycle = JointCycle([HOME, READY], args.move, DWELL, t0=env.time())
        worst = 0.0
        arrivals: list[float] = []  # error to each pose reached, at the end of its dwell
        leg = 0

        def follow() -> None:
            nonlocal worst, leg
            robot.update()
            t = env.time()
            worst = max(worst, float(np.abs(robot.jnt_pos_cmd - robot.jnt_pos_msr).max()))
            if cycle.leg(t) > leg:
                leg = cycle.leg(t)
                arrived_at = cycle.poses[leg % len(cycle.poses)]
                arrivals.append(float(np.abs(arrived_at - robot.jnt_pos_msr).max()))
            robot.jnt_pos_cmd = cycle.sample(t)[0]

        run(env, follow, args, robot=robot, title="POSITION mode")
        print(f"mode: {robot.ctrl_mode.name}, {args.move:g} s per move")
        print(f"simulated: {env.time():.2f} s")
        print(f"max tracking error: {worst:.4f} rad")
        settle = f"{max(arrivals):.4f} rad" if arrivals else "n/a (no move completed)"
        print(f"poses reached: {len(arrivals)}, worst error on arrival: {settle}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
