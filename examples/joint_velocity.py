"""Joint velocity control: every Panda joint follows a sinusoidal velocity.

In VELOCITY mode `update()` turns the arm's actuators into velocity servos (with Pinocchio's
gravity torques as feed-forward) and the script writes `jnt_vel_cmd = 0.1 sin(t)` for every
joint, the small periodic motion of dm_robotics_panda's joint velocity example. The joints'
positions should then follow the integral, `q0 + 0.1 (1 - cos t)`; both errors are printed.

    python examples/joint_velocity.py
    python examples/joint_velocity.py --headless --duration 6.3
"""

from __future__ import annotations

import math

import numpy as np
from common import PANDA_HAND, create_panda, panda, panda_scene, parse_args, run

import mjkdl as mjk

AMPLITUDE = 0.1  # rad/s


def main() -> int:
    args = parse_args(__doc__.splitlines()[0], duration=2 * math.pi)
    with mjk.Env.build(panda_scene([panda()])) as env:
        robot = create_panda(env)
        robot.ctrl_mode = mjk.CtrlMode.VELOCITY
        env.reset()
        hand = mjk.Gripper(env, PANDA_HAND, open=255, closed=0)
        hand.command(0.0)  # the gripper's action stays at "open"
        robot.update()
        q0 = robot.jnt_pos_msr.copy()
        t0 = env.time()
        worst = {"velocity": 0.0, "position": 0.0}

        def follow() -> None:
            robot.update()
            t = env.time() - t0
            if t > 0.1:  # after the servos' first response to the start
                expected = AMPLITUDE * math.sin(t)
                error = np.abs(robot.jnt_vel_msr - expected).max()
                worst["velocity"] = max(worst["velocity"], float(error))
            integral = q0 + AMPLITUDE * (1.0 - math.cos(t))
            error = np.abs(robot.jnt_pos_msr - integral).max()
            worst["position"] = max(worst["position"], float(error))
            robot.jnt_vel_cmd = np.full(robot.n_joints, AMPLITUDE * math.sin(t))

        run(env, follow, args, robot=robot, title="Joint velocity control")
        print(f"mode: {robot.ctrl_mode.name}, amplitude {AMPLITUDE:g} rad/s")
        print(f"simulated: {env.time() - t0:.2f} s")
        print(f"max joint velocity error: {worst['velocity']:.5f} rad/s")
        print(f"max joint position error: {worst['position']:.5f} rad")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
