"""Render docs/planning-your-arm.png: the UR5 of docs/planning-your-arm.md moving its tool
over the divider, free (left) and kept upright within 5° (right), each TCP path drawn in.

    MUJOCO_GL=egl python docs/plan_arm_picture.py
"""

from __future__ import annotations

import numpy as np
from make_pictures import orbit, render, save
from ompl import util as ou

import mjkdl as mjk
from mjkdl.plan import MotionPlanner, OrientationConstraint, TrajectoryFollower
from mjkdl.urdf import example_robot_data_path

SEED = 1  # OMPL's


def scene() -> mjk.SceneSpec:
    ur5 = mjk.RobotSpec(path=str(example_robot_data_path("ur_description/urdf/ur5_robot.urdf")))

    def box(name, size, pos):
        return mjk.SceneObject(
            name=name, shape=mjk.Shape.BOX, size=size, pos=pos, fixed=True, rgba=[0.6, 0.5, 0.4, 1]
        )

    objects = [box("shelf", [0.15, 0.3, 0.01], [0.5, 0.0, 0.3])]
    objects.append(box("divider", [0.08, 0.01, 0.12], [0.62, 0.0, 0.43]))
    return mjk.SceneSpec(
        timestep=0.002, add_floor=True, add_skybox=False, robots=[ur5], objects=objects
    )


def picture(constrained: bool) -> np.ndarray:
    """The UR5 half-way from left of the divider to right of it, its TCP path drawn."""
    ou.RNG.setSeed(SEED)
    with mjk.Env.build(scene()) as env:
        arm = env.create_robot("base_link", "tool0")
        home = np.array([0.0, -1.57, 1.57, -1.57, -1.57, 0.0])
        arm.set_joint_pos(home)
        arm.ctrl_mode = mjk.CtrlMode.POSITION
        arm.update()
        planner = MotionPlanner(arm)
        down = arm.fk_frame(home).rotation
        turn = (np.full(6, -np.pi), np.full(6, np.pi))
        start = planner.plan(mjk_pose(down, [0.6, -0.2, 0.4]), bounds=turn).positions[-1]
        arm.set_joint_pos(start)
        arm.update()
        upright = OrientationConstraint((0.0, 0.0, 1.0), (0.0, 0.0, -1.0), np.radians(5.0))
        trajectory = planner.plan(
            mjk_pose(down, [0.6, 0.2, 0.4]),
            bounds=turn,
            constraint=upright if constrained else None,
            timeout=5.0,
        )
        times = np.linspace(0.0, trajectory.duration, 120)
        path = np.array([arm.fk_frame(trajectory.sample(t)[0]).translation for t in times])
        follower = TrajectoryFollower(arm)
        follower.start(trajectory)
        for _ in range(round(0.5 * trajectory.duration / env.timestep())):
            arm.update()
            follower.command()
            arm.step()
        return render(env, orbit([0.45, 0.0, 0.4], 1.6, 200.0, -25.0), path=path)


def mjk_pose(rotation: np.ndarray, position: list[float]):
    import pinocchio as pin

    return pin.SE3(rotation, np.array(position))


if __name__ == "__main__":
    save("planning-your-arm.png", np.hstack([picture(False), picture(True)]), limit=300_000)
