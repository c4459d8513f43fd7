"""Joint-space impedance in TORQUE mode: the TCP traces a square above the table.

The corners of a square are turned into joint positions by `robot.ik` before the loop; the
target then moves from corner to corner along minimum-jerk paths. Each step the controller
writes

    tau = g(q) + M(q) (a_d + K (q_d - q) + D (v_d - v))

gravity feed-forward plus a spring and damper of `--stiffness` Hz acting through the mass
matrix, with the path's acceleration fed forward. Push the arm in the viewer: it gives way and
springs back. Headless, the largest tracking error (joints and TCP) is printed.

    python examples/impedance.py
    python examples/impedance.py --headless --duration 4
"""

from __future__ import annotations

import argparse

import numpy as np
from common import (
    HOME,
    JointCycle,
    JointMove,
    create_arm,
    impedance_torques,
    parse_args,
    run,
    top_down,
    tutorial_spec,
)

import mjkdl as mjk

SQUARE_CENTRE = np.array([0.45, 0.0, 0.95])
SQUARE_HALF = 0.1


def options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--move", type=float, default=1.0, help="seconds per side (default 1)")
    parser.add_argument("--stiffness", type=float, default=4.0, help="spring frequency in Hz")


def corner_poses(robot: mjk.Robot) -> list[np.ndarray]:
    """Joint positions of the square's four corners, each IK seeded with the previous one."""
    q = HOME
    poses = []
    for dx, dy in ((1, 1), (1, -1), (-1, -1), (-1, 1)):
        corner = SQUARE_CENTRE + SQUARE_HALF * np.array([dx, dy, 0.0])
        result = robot.ik(top_down(corner), q)
        if not result.success:
            raise RuntimeError(f"no IK solution for the corner at {corner}")
        q = result.q
        poses.append(q)
    return poses


def main() -> int:
    args = parse_args(__doc__.splitlines()[0], duration=6.0, extra=options)
    with mjk.Env.build(tutorial_spec()) as env:
        robot = create_arm(env)
        robot.ctrl_mode = mjk.CtrlMode.TORQUE
        env.on_reset = lambda ctx: robot.set_joint_pos(HOME, call_forward=False)
        env.reset()
        corners = corner_poses(robot)
        approach = JointMove(HOME, corners[0], env.time(), args.move)
        cycle = JointCycle(corners, args.move, t0=approach.t0 + approach.duration)
        worst_q = worst_tcp = 0.0

        def track() -> None:
            nonlocal worst_q, worst_tcp
            robot.update()
            t = env.time()
            q_des, v_des, a_des = (cycle if t >= cycle.t0 else approach).sample(t)
            worst_q = max(worst_q, float(np.abs(q_des - robot.jnt_pos_msr).max()))
            tcp_error = robot.fk_frame().translation - robot.fk_frame(q_des).translation
            worst_tcp = max(worst_tcp, float(np.linalg.norm(tcp_error)))
            robot.jnt_trq_cmd = impedance_torques(robot, q_des, v_des, a_des, args.stiffness)

        run(env, track, args, robot=robot, title="joint impedance")
        print(f"stiffness: {args.stiffness:g} Hz, {args.move:g} s per side")
        print(f"simulated: {env.time():.2f} s")
        print(f"max joint tracking error: {worst_q:.5f} rad")
        print(f"max TCP tracking error: {worst_tcp:.5f} m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
