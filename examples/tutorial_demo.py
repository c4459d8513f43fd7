"""The tutorial's complete scene, held still by gravity compensation.

A Kinova Gen3 with a Robotiq 2F-85 stands on a table next to a cube, filmed by a `task`
camera. The robot handle knows about the gripper (its inertia joins the chain, its pinch site
is the TCP), a reset hook puts the arm at home and the cube on its spot, and the arm runs in
TORQUE mode on Pinocchio's gravity torques alone while the fingers are held open. Without any
stiffness the arm stays put only if the model is right; the TCP drift says how well it is.

    python examples/tutorial_demo.py                 # interactive viewer
    python examples/tutorial_demo.py --headless      # prints the drift after 2 s
"""

from __future__ import annotations

from common import (
    CUBE_START,
    GRIPPER_OPEN,
    HOME,
    create_arm,
    parse_args,
    run,
    set_gripper,
    tcp_drift,
    tutorial_spec,
)

import mjkdl as mjk


def main() -> int:
    args = parse_args(__doc__.splitlines()[0], duration=2.0)
    with mjk.Env.build(tutorial_spec()) as env:
        robot = create_arm(env)
        robot.ctrl_mode = mjk.CtrlMode.TORQUE

        def on_reset(ctx: mjk.ResetContext) -> None:
            robot.set_joint_pos(HOME, call_forward=False)
            env.set_body_pose("cube", CUBE_START, [1.0, 0.0, 0.0, 0.0])

        env.on_reset = on_reset
        env.reset()
        start = robot.fk_frame().translation.copy()

        def hold() -> None:
            robot.update()
            robot.jnt_trq_cmd = robot.gravity_torques()
            set_gripper(env, GRIPPER_OPEN)

        run(env, hold, args, robot=robot, title="mjkdl tutorial")
        robot.update()  # read the final state
        print(f"MuJoCo {mjk.mujoco_version()}")
        print(f"joints: {robot.n_joints} ({', '.join(robot.joint_names)})")
        print(f"cameras: {', '.join(env.camera_names())}")
        print(f"simulated: {env.time():.2f} s")
        print(f"TCP drift: {tcp_drift(start, robot):.6f} m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
