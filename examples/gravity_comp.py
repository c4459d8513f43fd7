"""Gravity compensation of a bare Gen3, checked against MuJoCo, from several poses.

The smallest scene there is: one Menagerie Gen3 on the floor, no tool. In TORQUE mode the
controller writes `robot.gravity_torques()` and nothing else, so there is no stiffness: the arm
stays where it is only because Pinocchio's model of it matches MuJoCo's. In the viewer, drag a
link with the mouse (double-click it, then Ctrl + right drag) and it floats where you leave it.

Headless, the arm is reset to `--poses` random contact-free poses around home, held for
`--duration` seconds each; for each pose the script prints the TCP drift and how far the
gravity torques are from MuJoCo's own bias forces (`qfrc_bias`, at rest only gravity).

    python examples/gravity_comp.py
    python examples/gravity_comp.py --headless --duration 1 --poses 3
"""

from __future__ import annotations

import argparse

import numpy as np
from common import HOME, gravity_compensation, menagerie_model, parse_args, run, tcp_drift

import mjkdl as mjk


def options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--poses", type=int, default=3, help="poses to try headless (default 3)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the random poses")


def bare_gen3_spec() -> mjk.SceneSpec:
    return mjk.SceneSpec(
        timestep=0.002,
        add_floor=True,
        add_skybox=True,
        robots=[mjk.RobotSpec(path=menagerie_model("kinova_gen3"))],
    )


def bias_error(env: mjk.Env, robot: mjk.Robot) -> float:
    """Largest gap between Pinocchio's gravity torques and MuJoCo's `qfrc_bias` (N m)."""
    dofs = [env.model.joint(name).dofadr[0] for name in robot.joint_names]
    return float(np.abs(robot.gravity_torques() - env.data.qfrc_bias[dofs]).max())


def free_poses(env: mjk.Env, robot: mjk.Robot, count: int, seed: int) -> list[np.ndarray]:
    """`count` random poses near home, within the joint limits and free of contacts."""
    rng = np.random.default_rng(seed)
    low, high = robot.joint_limits.T
    poses: list[np.ndarray] = []
    while len(poses) < count:
        q = np.clip(HOME + rng.uniform(-0.6, 0.6, robot.n_joints), low, high)
        robot.set_joint_pos(q)  # forwards, so MuJoCo's contact list is up to date
        if env.data.ncon == 0:
            poses.append(q)
    return poses


def main() -> int:
    args = parse_args(__doc__.splitlines()[0], duration=1.0, extra=options)
    with mjk.Env.build(bare_gen3_spec()) as env:
        robot = env.create_robot("base_link", "bracelet_link")
        robot.ctrl_mode = mjk.CtrlMode.TORQUE

        poses = free_poses(env, robot, args.poses, args.seed) if args.headless else [HOME]
        for k, pose in enumerate(poses):
            env.on_reset = lambda ctx, q=pose: robot.set_joint_pos(q, call_forward=False)
            env.reset()
            gap = bias_error(env, robot)
            start = robot.fk_frame().translation.copy()
            run(env, gravity_compensation(robot), args, robot=robot, title="gravity compensation")
            robot.update()
            drift = tcp_drift(start, robot)
            print(
                f"pose {k}: TCP drift {drift:.2e} m after {env.time():.2f} s, "
                f"|gravity - qfrc_bias| {gap:.2e} N m"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
