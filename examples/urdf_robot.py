"""A URDF robot: the UR5 of example-robot-data, on the table, under gravity compensation.

`RobotSpec.path` takes a URDF as readily as an MJCF. mjkdl resolves its `package://` meshes,
keeps its fixed-joint links (`tool0`) as bodies and gives every actuated joint a `motor`
limited to the URDF's effort. MuJoCo cannot read the UR5's `.dae` visual meshes: they are
converted once through trimesh into mjkdl's mesh cache (`mjkdl.urdf.mesh_cache_dir()`).

The arm runs in TORQUE mode on `robot.gravity_torques()` alone and the script prints the
drift of `tool0`.

    python examples/urdf_robot.py
    python examples/urdf_robot.py --headless --duration 2
"""

from __future__ import annotations

import warnings

import numpy as np
from common import gravity_compensation, parse_args, run, table_top, tabletop_spec, tcp_drift

import mjkdl as mjk
from mjkdl.urdf import UnreadableMeshWarning, example_robot_data_path

UR5_URDF = "ur_description/urdf/ur5_robot.urdf"
START = np.array([0.3, -1.2, 1.4, -1.5, -1.57, 0.2])  # a pose clear of the table


def ur5_spec() -> mjk.SceneSpec:
    arm = mjk.RobotSpec(path=example_robot_data_path(UR5_URDF), attach_to=table_top())
    return tabletop_spec([arm])


def build() -> mjk.Env:
    """Compile the scene; report the replaced meshes in one line instead of a warning."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", UnreadableMeshWarning)
        env = mjk.Env.build(ur5_spec())
    for warning in caught:
        print(f"note: {warning.message}")
    return env


def main() -> int:
    args = parse_args(__doc__.splitlines()[0], duration=2.0)
    with build() as env:
        robot = env.create_robot("base_link", "tool0")
        robot.ctrl_mode = mjk.CtrlMode.TORQUE
        env.on_reset = lambda ctx: robot.set_joint_pos(START, call_forward=False)
        env.reset()
        start = robot.fk_frame().translation.copy()

        run(env, gravity_compensation(robot), args, robot=robot, title="UR5 from URDF")
        robot.update()
        drift = tcp_drift(start, robot)
        print(f"joints: {robot.n_joints} ({', '.join(robot.joint_names)})")
        print(f"simulated: {env.time():.2f} s")
        print(f"tool0 drift: {drift:.6f} m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
