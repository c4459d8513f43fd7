"""Cartesian velocity control: the Panda's TCP traces a figure eight from velocities alone.

Every physics step the controller turns the twist of an open-loop figure eight in the x/y
plane of the control frame, `vx = r cos t`, `vy = r cos 2t` (so `x = r sin t`,
`y = r/2 sin 2t`), into joint velocities with one small QP, and integrates them into the
position command of the Panda's own position servos. Nothing closes the loop on the TCP
position: the path is what the velocities add up to, as in dm_robotics_panda.

The command itself follows the ideal path closely; the arm trails it by the servos' lag
(Menagerie's gains: kv/kp = 0.1 s), which shows as the measured path error. A wrist camera
rides on the hand (`CameraSpec.attach_to`); `--camera wrist` watches through it.

    python examples/cartesian_velocity.py
    python examples/cartesian_velocity.py --camera wrist
    python examples/cartesian_velocity.py --headless --duration 6.3
    python examples/cartesian_velocity.py --control-frame link0
"""

from __future__ import annotations

import argparse
import math

import numpy as np
import pinocchio as pin
from common import create_panda, panda, panda_scene, parse_args, run

import mjkdl as mjk

RADIUS = 0.1  # m; the eight is 0.2 m wide and 0.1 m tall


def options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--control-frame", default="", help='site or body the twist is expressed in ("": world)'
    )
    parser.add_argument("--camera", default="task", choices=["task", "wrist"])


def wrist_camera() -> mjk.CameraSpec:
    """A camera on the hand, 8 cm off its axis, looking along the fingers."""
    return mjk.CameraSpec(
        name="wrist",
        pos=[0.08, 0.0, 0.0],
        euler=[180.0, 0.0, -90.0],
        fovy=80.0,
        attach_to=mjk.AttachTarget(mjk.AttachKind.Body, "hand"),
    )


def figure_eight(t: float) -> tuple[np.ndarray, np.ndarray]:
    """Offset from the start and the twist of the eight at time `t` (in the control frame)."""
    offset = np.array([RADIUS * math.sin(t), 0.5 * RADIUS * math.sin(2.0 * t), 0.0])
    twist = np.array([RADIUS * math.cos(t), RADIUS * math.cos(2.0 * t), 0.0, 0.0, 0.0, 0.0])
    return offset, twist


def main() -> int:
    args = parse_args(__doc__.splitlines()[0], duration=2 * math.pi, extra=options)
    spec = panda_scene([panda()])
    spec.cameras.append(wrist_camera())
    with mjk.Env.build(spec) as env:
        robot = create_panda(env)
        env.reset()
        robot.update()
        ctrl = mjk.CartesianVelocityController(robot, control_frame=args.control_frame)
        rot = ctrl.frame_rotation()  # fixed here; a moving frame would be read every step
        start = robot.fk_frame()
        t0 = env.time()
        worst = {"command": 0.0, "measured": 0.0, "z": 0.0, "rotation": 0.0}
        statuses: set[str] = set()

        def follow() -> None:
            robot.update()
            t = env.time() - t0
            offset, twist = figure_eight(t)
            ideal = start.translation + rot @ offset
            commanded = robot.fk_frame(robot.jnt_pos_cmd).translation
            measured = robot.fk_frame()
            worst["command"] = max(worst["command"], float(np.linalg.norm(commanded - ideal)))
            worst["measured"] = max(
                worst["measured"], float(np.linalg.norm(measured.translation - ideal))
            )
            local = rot.T @ (measured.translation - start.translation)
            worst["z"] = max(worst["z"], abs(float(local[2])))
            turn = np.linalg.norm(pin.log3(start.rotation.T @ measured.rotation))
            worst["rotation"] = max(worst["rotation"], math.degrees(turn))
            ctrl.command(twist)
            statuses.add(ctrl.last_status.value)

        title = "Cartesian velocity: figure eight"
        run(env, follow, args, robot=robot, title=title, camera=args.camera)
        print(f"control frame: {args.control_frame or 'world'}")
        print(f"simulated: {env.time() - t0:.2f} s")
        print(f"max command path error: {worst['command']:.5f} m")
        print(f"max measured path error: {worst['measured']:.4f} m")
        print(f"max out-of-plane drift: {worst['z']:.5f} m")
        print(f"max TCP rotation: {worst['rotation']:.3f} deg")
        print(f"QP status: {', '.join(sorted(statuses))}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
