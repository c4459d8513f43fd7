"""Add and remove an object while the arm is moving; the arm does not notice.

`env.add_object(obj)` and `env.remove_object(name)` recompile the MuJoCo model and replace
its data, carrying over the state of everything that survives (joint positions and velocities,
actuator controls, time) and rebinding every Robot handle. The controller below keeps running
through both changes: a third of the way into the run a red pillar appears on the table, two
thirds of the way it goes again. Each change prints how much the arm's state moved across it
(nothing) and the model's body count. It is a coarse operation (a recompile), not a way to
spawn objects every frame.

    python examples/modify_scene.py
    python examples/modify_scene.py --headless --duration 3
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from common import (
    HOME,
    TABLE_HEIGHT,
    JointCycle,
    create_arm,
    impedance_torques,
    parse_args,
    run,
    tutorial_spec,
)

import mjkdl as mjk

SWING = HOME + np.array([0.8, 0.3, 0.0, 0.4, 0.0, -0.3, 0.0])


def pillar() -> mjk.SceneObject:
    """A free 10 x 10 x 30 cm box standing on the table, out of the arm's way."""
    return mjk.SceneObject(
        name="pillar",
        shape=mjk.Shape.BOX,
        size=[0.05, 0.05, 0.15],
        pos=[0.3, 0.4, TABLE_HEIGHT + 0.15],
        rgba=[0.8, 0.2, 0.2, 1.0],
        mass=0.5,
        friction=[0.8, 0.02, 0.001],
    )


def carried_over(env: mjk.Env, robot: mjk.Robot, change: Callable[[], None], what: str) -> None:
    """Apply `change` to the scene; print how the arm's measured state moved across it."""
    robot.update()
    t, bodies = env.time(), env.model.nbody
    q, v = robot.jnt_pos_msr.copy(), robot.jnt_vel_msr.copy()
    change()
    robot.update()  # the same handle now reads the new model's data
    dq = np.abs(robot.jnt_pos_msr - q).max()
    dv = np.abs(robot.jnt_vel_msr - v).max()
    print(
        f"t={t:.2f} s {what}: {bodies} -> {env.model.nbody} bodies; arm state carried over: "
        f"|dq| {dq:.1e} rad, |dv| {dv:.1e} rad/s, time {env.time() - t:+.1e} s"
    )


def main() -> int:
    args = parse_args(__doc__.splitlines()[0], duration=4.5)
    with mjk.Env.build(tutorial_spec()) as env:
        robot = create_arm(env)
        robot.ctrl_mode = mjk.CtrlMode.TORQUE
        env.on_reset = lambda ctx: robot.set_joint_pos(HOME, call_forward=False)
        env.reset()
        cycle = JointCycle([HOME, SWING], move=1.5, t0=env.time())
        worst = 0.0
        changes = [
            (args.duration / 3, lambda: env.add_object(pillar()), "added 'pillar'"),
            (2 * args.duration / 3, lambda: env.remove_object("pillar"), "removed 'pillar'"),
        ]

        def swing() -> None:
            nonlocal worst
            robot.update()
            q_des, v_des, a_des = cycle.sample(env.time())
            worst = max(worst, float(np.abs(q_des - robot.jnt_pos_msr).max()))
            robot.jnt_trq_cmd = impedance_torques(robot, q_des, v_des, a_des)

        def modify() -> None:
            if changes and env.time() >= changes[0][0]:
                _, change, what = changes.pop(0)
                carried_over(env, robot, change, what)

        run(env, swing, args, robot=robot, title="modify a running scene", after_step=modify)
        print(f"simulated: {env.time():.2f} s")
        print(f"max tracking error: {worst:.4f} rad")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
