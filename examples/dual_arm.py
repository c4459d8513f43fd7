"""Two Gen3 arms on one table, each with its own 2F-85, chain, ports and controller.

Both arms come from the same Menagerie file; the second one gets the prefix `r2_`, so its
joints, bodies and actuators are `r2_joint_1`, `r2_g_fingers_actuator` and so on. A Robot
handle is created for each with names *without* the prefix (`prefix="r2_"` adds it). Each arm
swings between home and a pose of its own under joint impedance, out of phase with the other,
and closes its gripper at one end of the swing and opens it at the other.

    python examples/dual_arm.py
    python examples/dual_arm.py --headless --duration 4
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass

import numpy as np
from common import (
    GRIPPER_CLOSED,
    GRIPPER_OPEN,
    HOME,
    JointCycle,
    create_arm,
    gen3_with_gripper,
    impedance_torques,
    parse_args,
    run,
    set_gripper,
    table_top,
    tabletop_spec,
)

import mjkdl as mjk

# Mount points on the table top and each arm's second pose (leaning out, turned outwards).
ARMS = {
    "": ((0.0, 0.3, 0.0), HOME + np.array([-0.6, 0.3, 0.0, 0.4, 0.0, -0.3, 0.0])),
    "r2_": ((0.0, -0.3, 0.0), HOME + np.array([0.6, 0.3, 0.0, 0.4, 0.0, -0.3, 0.0])),
}


def options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--move", type=float, default=1.5, help="seconds per swing (default 1.5)")


def dual_arm_spec() -> mjk.SceneSpec:
    top = table_top()
    return tabletop_spec([gen3_with_gripper(prefix, top, pos) for prefix, (pos, _) in ARMS.items()])


@dataclass
class Swing:
    """One arm going back and forth between home and another pose, gripper closed on the way
    out and open on the way back."""

    env: mjk.Env
    robot: mjk.Robot
    prefix: str
    cycle: JointCycle
    worst: float = 0.0

    def command(self) -> None:
        """Write this arm's torques and gripper command (after `robot.update()`)."""
        t = self.env.time()
        q_des, v_des, a_des = self.cycle.sample(t)
        self.worst = max(self.worst, float(np.abs(q_des - self.robot.jnt_pos_msr).max()))
        self.robot.jnt_trq_cmd = impedance_torques(self.robot, q_des, v_des, a_des)
        outward = self.cycle.leg(t) % 2 == 0
        set_gripper(self.env, GRIPPER_CLOSED if outward else GRIPPER_OPEN, self.prefix)


def main() -> int:
    args = parse_args(__doc__.splitlines()[0], duration=6.0, extra=options)
    with mjk.Env.build(dual_arm_spec()) as env:
        robots = {prefix: create_arm(env, prefix) for prefix in ARMS}
        for robot in robots.values():
            robot.ctrl_mode = mjk.CtrlMode.TORQUE

        def home_both(ctx: mjk.ResetContext) -> None:
            for robot in robots.values():
                robot.set_joint_pos(HOME, call_forward=False)

        env.on_reset = home_both
        env.reset()
        delay = args.move / 2  # the second arm starts half a swing later: never in step
        swings = [
            Swing(env, robots[prefix], prefix, JointCycle([HOME, away], args.move, t0=k * delay))
            for k, (prefix, (_, away)) in enumerate(ARMS.items())
        ]

        def control() -> None:
            for swing in swings:
                swing.robot.update()
            for swing in swings:
                swing.command()

        run(env, control, args, robot=robots[""], title="two arms")
        print(f"simulated: {env.time():.2f} s")
        for swing in swings:
            names = swing.robot.joint_names
            print(
                f"arm {swing.prefix or '(no prefix)'}: {swing.robot.n_joints} joints "
                f"{names[0]}..{names[-1]}, max tracking error {swing.worst:.4f} rad"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
