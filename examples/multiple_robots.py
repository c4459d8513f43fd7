"""Three Pandas placed by position and yaw, each moving relative to its own base.

As in dm_robotics_panda's multi-robot example, the robots are the same model placed three
times (`RobotSpec.pos`/`euler`, prefixes `r1_`..`r3_`). Each has its own Cartesian velocity
controller whose control frame is the robot's own base body (`rN_link0`), so one and the same
twist — a circle in the base's x/z plane — moves each TCP the same way relative to its robot,
in three different world directions. Each controller also keeps its hand 5 cm from the other
robots' hands.

    python examples/multiple_robots.py
    python examples/multiple_robots.py --headless --duration 4
"""

from __future__ import annotations

import math

import numpy as np
from common import create_panda, look_at, panda, panda_scene, parse_args, run

import mjkdl as mjk

# (prefix, position, yaw in degrees): the seed's three headings, with the bases far enough
# apart that the arms at their home pose do not reach into each other.
PLACEMENTS = [
    ("r1_", (0.0, 0.0, 0.0), 0.0),
    ("r2_", (1.0, -0.8, 0.0), 135.0),
    ("r3_", (1.0, 0.8, 0.0), 225.0),
]
RADIUS = 0.06  # m
PERIOD = 3.0  # s per circle


def main() -> int:
    args = parse_args(__doc__.splitlines()[0], duration=PERIOD)
    robots_spec = [panda(prefix, pos=pos, euler=(0.0, 0.0, yaw)) for prefix, pos, yaw in PLACEMENTS]
    camera = look_at("task", eye=[2.4, -2.2, 2.0], target=[0.5, 0.0, 0.3])
    with mjk.Env.build(panda_scene(robots_spec, camera=camera)) as env:
        prefixes = [prefix for prefix, _, _ in PLACEMENTS]
        robots = {prefix: create_panda(env, prefix) for prefix in prefixes}
        env.reset()
        ctrls = {
            prefix: mjk.CartesianVelocityController(
                robot,
                control_frame=f"{prefix}link0",
                avoid=[(f"{prefix}hand", f"{other}hand") for other in prefixes if other != prefix],
            )
            for prefix, robot in robots.items()
        }
        bases = {prefix: env.body_frame(f"{prefix}link0") for prefix in prefixes}
        for robot in robots.values():
            robot.update()
        start = {p: r.fk_frame().translation.copy() for p, r in robots.items()}
        omega = 2.0 * math.pi / PERIOD
        t0 = env.time()
        spread = 0.0  # largest difference between the robots' motions in their base frames

        def control() -> None:
            nonlocal spread
            t = env.time() - t0
            twist = (
                RADIUS * omega * np.array([math.cos(omega * t), 0, -math.sin(omega * t), 0, 0, 0])
            )
            local = []
            for prefix, robot in robots.items():
                robot.update()
                moved = robot.fk_frame().translation - start[prefix]
                local.append(bases[prefix].rotation.T @ moved)
                ctrls[prefix].command(twist)
            spread = max(spread, float(np.ptp(np.array(local), axis=0).max()))

        run(env, control, args, title="Three Pandas")
        print(f"simulated: {env.time() - t0:.2f} s")
        for prefix, robot in robots.items():
            base = bases[prefix]
            x, y, _ = base.translation
            yaw = math.degrees(math.atan2(base.rotation[1, 0], base.rotation[0, 0]))
            print(
                f"{prefix[:-1]}: base at ({x:+.2f}, {y:+.2f}) m, yaw {yaw:+.0f} deg, "
                f"{robot.n_joints} joints, QP {ctrls[prefix].last_status.value}"
            )
        print(f"max difference between the motions in the base frames: {spread:.6f} m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
