"""Two Pandas on a turning torso, both driven along the x axis of a frame on the torso.

`examples/assets/two_arm_torso.xml` is a torso on a vertical hinge with two mounting sites
(`left`, `right`) and a `control` site. The arms are mounted on the sites, so they turn with
the torso, and both Cartesian velocity controllers express their twists in the `control`
site's axes, which the controllers read afresh every step. The torso swings back and forth
by ±60° under its own position servo while each arm is told to move sinusoidally along x
only: seen from the torso, every TCP moves along the torso's x, however the torso turns.

    python examples/two_arm_robot.py
    python examples/two_arm_robot.py --headless --duration 8
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from common import create_panda, look_at, panda, panda_scene, parse_args, run

import mjkdl as mjk

TORSO_XML = Path(__file__).resolve().parent / "assets" / "two_arm_torso.xml"
TORSO_SWING = math.radians(60.0)
TORSO_PERIOD = 8.0  # s
STROKE = 0.1  # m, amplitude of each TCP's motion along the torso's x
STROKE_PERIOD = 4.0  # s
ARMS = ("left_", "right_")
TORSO_MOTOR = "torso/torso_motor"  # names inside an object's MJCF get the object's name


def torso() -> mjk.SceneObject:
    return mjk.SceneObject(name="torso", mjcf_path=str(TORSO_XML), fixed=True)


def on_torso(site: str) -> mjk.AttachTarget:
    return mjk.AttachTarget(mjk.AttachKind.Site, mjk.scene_object_site_name(torso(), site))


def main() -> int:
    args = parse_args(__doc__.splitlines()[0], duration=TORSO_PERIOD)
    arms = [panda(prefix, on_torso(prefix[:-1])) for prefix in ARMS]
    camera = look_at("task", eye=[2.6, -1.6, 2.2], target=[0.3, 0.0, 1.0])
    with mjk.Env.build(panda_scene(arms, objects=[torso()], camera=camera)) as env:
        robots = {prefix: create_panda(env, prefix) for prefix in ARMS}
        env.reset()
        control_frame = mjk.scene_object_site_name(torso(), "control")
        ctrls = {
            prefix: mjk.CartesianVelocityController(robot, control_frame=control_frame)
            for prefix, robot in robots.items()
        }
        site = env.site_id(control_frame)
        data = env.data

        def in_torso(point: np.ndarray) -> np.ndarray:
            rot = data.site_xmat[site].reshape(3, 3)
            return rot.T @ (point - data.site_xpos[site])

        for robot in robots.values():
            robot.update()
        start = {p: in_torso(r.fk_frame().translation) for p, r in robots.items()}
        stroke = {p: [0.0, 0.0] for p in ARMS}  # min and max x travelled in the torso frame
        off_axis = dict.fromkeys(ARMS, 0.0)
        turned = [0.0, 0.0]
        t0 = env.time()
        omega = 2.0 * math.pi / STROKE_PERIOD

        def control() -> None:
            t = env.time() - t0
            angle = TORSO_SWING * math.sin(2.0 * math.pi * t / TORSO_PERIOD)
            env.set_actuator_ctrl(TORSO_MOTOR, angle)
            yaw = math.atan2(data.site_xmat[site][3], data.site_xmat[site][0])
            turned[0], turned[1] = min(turned[0], yaw), max(turned[1], yaw)
            twist = np.array([STROKE * omega * math.cos(omega * t), 0.0, 0.0, 0.0, 0.0, 0.0])
            for prefix, robot in robots.items():
                robot.update()
                moved = in_torso(robot.fk_frame().translation) - start[prefix]
                stroke[prefix][0] = min(stroke[prefix][0], float(moved[0]))
                stroke[prefix][1] = max(stroke[prefix][1], float(moved[0]))
                off_axis[prefix] = max(off_axis[prefix], float(np.linalg.norm(moved[1:])))
                ctrls[prefix].command(twist)

        run(env, control, args, title="Two arms on a turning torso")
        print(f"simulated: {env.time() - t0:.2f} s")
        print(f"torso turned: {math.degrees(turned[0]):.1f} to {math.degrees(turned[1]):.1f} deg")
        for prefix in ARMS:
            lo, hi = stroke[prefix]
            print(
                f"{prefix[:-1]}: x in the torso frame {lo:+.4f} to {hi:+.4f} m, "
                f"max off-axis {off_axis[prefix]:.4f} m"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
