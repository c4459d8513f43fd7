"""Another gripper on the Panda: a Robotiq 2F-85 on `panda_nohand`, driven continuously.

The hand-less Panda from Menagerie gets the 2F-85 on its flange site (`attachment_site`,
names prefixed `g_`), and the arm's tool is the gripper: its pinch site is the TCP. With
`binary=False` the action is linear between open (ctrl 0) and closed (ctrl 255), and the
script sweeps it as a sinusoid, `a = (1 - cos(2 pi t / T)) / 2`. The measured opening follows
with the gripper's own lag.

    python examples/custom_gripper.py
    python examples/custom_gripper.py --headless --duration 8
"""

from __future__ import annotations

import math

import numpy as np
from common import create_panda, panda, panda_scene, parse_args, run

import mjkdl as mjk

PERIOD = 4.0  # seconds per close-and-open cycle
PREFIX = "g_"


def robotiq_on_panda() -> mjk.RobotSpec:
    arm = panda(hand=False)
    arm.attachments.append(
        mjk.AttachmentSpec(
            mjcf_path=mjk.menagerie.model_path("robotiq_2f85"),
            attach_to=mjk.AttachTarget(mjk.AttachKind.Site, "attachment_site"),
            prefix=PREFIX,
        )
    )
    return arm


def main() -> int:
    args = parse_args(__doc__.splitlines()[0], duration=2 * PERIOD)
    with mjk.Env.build(panda_scene([robotiq_on_panda()])) as env:
        tool = mjk.ToolFrameSpec(tool_body=f"{PREFIX}base_mount", tcp_site=f"{PREFIX}pinch")
        robot = create_panda(env, tip="link7", tool=tool)
        env.reset()
        grip = mjk.Gripper(env, f"{PREFIX}fingers_actuator", open=0, closed=255, binary=False)
        t0 = env.time()
        actions: list[float] = []
        openings: list[float] = []

        def control() -> None:
            robot.update()
            t = env.time() - t0
            a = 0.5 * (1.0 - math.cos(2.0 * math.pi * t / PERIOD))
            grip.command(a)
            actions.append(a)
            openings.append(grip.opening())

        run(env, control, args, robot=robot, title="Robotiq 2F-85 on a Panda")
        tcp = robot.fk_frame().translation
        print(
            f"tool: {PREFIX}base_mount, TCP at {PREFIX}pinch ({tcp[0]:.3f}, {tcp[1]:.3f}, "
            f"{tcp[2]:.3f}) m"
        )
        opening = np.array(openings)
        print(f"action range: {min(actions):.3f} to {max(actions):.3f}")
        print(f"opening range: {opening.min():.3f} to {opening.max():.3f}")
        # How far behind the command the fingers are: the delay that best matches 1 - a.
        target = 1.0 - np.array(actions)
        dt = env.timestep()
        lags = range(0, min(round(1.0 / dt), len(target) // 2), 5)
        if lags:
            errors = [np.abs(opening[k:] - target[: len(target) - k]).mean() for k in lags]
            best = int(np.argmin(errors))
            print(
                f"opening lags the action by {lags[best] * dt:.2f} s "
                f"(mean error then {errors[best]:.3f})"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
