"""The Panda hand driven by random binary actions, closing around a box between its fingers.

`Gripper(env, "actuator8", open=255, closed=0)` maps an action in [0, 1] to the hand's
control value: below 0.5 it opens, otherwise it closes (binary, like dm_robotics_panda's
gripper effector). Every `--period` seconds a new random action is drawn. The hand holds
still around a 5 cm box standing on the floor, so a grasp stops at the box: the measured
opening (1 open, 0 closed) then reads about two thirds rather than zero.

    python examples/gripper.py
    python examples/gripper.py --headless --duration 6 --seed 3
"""

from __future__ import annotations

import argparse

import numpy as np
from common import (
    PANDA_HAND,
    PANDA_HOME,
    create_panda,
    panda,
    panda_scene,
    parse_args,
    run,
    top_down,
)

import mjkdl as mjk

BOX_HALF = 0.025
BOX_POS = np.array([0.5, 0.0, BOX_HALF])
GRASP_HEIGHT = 0.03  # TCP above the floor: the fingertips clear it by about 2 cm
FINGERS = ("finger_joint1", "finger_joint2")


def options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seed", type=int, default=0, help="random seed of the actions")
    parser.add_argument(
        "--period", type=float, default=0.6, help="seconds between actions (default 0.6)"
    )


def box() -> mjk.SceneObject:
    return mjk.SceneObject(
        name="box",
        shape=mjk.Shape.BOX,
        size=[BOX_HALF] * 3,
        pos=list(BOX_POS),
        rgba=[0.9, 0.5, 0.1, 1.0],
        mass=0.1,
        friction=[1.0, 0.02, 0.001],
    )


def main() -> int:
    args = parse_args(__doc__.splitlines()[0], duration=6.0, extra=options)
    rng = np.random.default_rng(args.seed)
    with mjk.Env.build(panda_scene([panda()], objects=[box()])) as env:
        robot = create_panda(env)
        # The arm holds the TCP at the box's centre, pointing down, fingers across the box.
        grasp = robot.ik(top_down([BOX_POS[0], BOX_POS[1], GRASP_HEIGHT]), PANDA_HOME)
        if not grasp.success:
            raise RuntimeError("no IK solution around the box")
        finger_qpos = [env.model.joint(f).qposadr[0] for f in FINGERS]

        def place(ctx: mjk.ResetContext) -> None:
            robot.set_joint_pos(grasp.q, call_forward=False)
            ctx.data.qpos[finger_qpos] = 0.04  # open, around the box

        env.on_reset = place
        env.reset()
        hand = mjk.Gripper(env, PANDA_HAND, open=255, closed=0)
        hand.command(0.0)
        box_start = env.body_frame("box").translation
        every = max(1, round(args.period / env.timestep()))
        steps = 0
        action = 0.0
        readings: dict[str, list[float]] = {"open": [], "closed": []}

        def control() -> None:
            nonlocal steps, action
            robot.update()
            if steps % every == every - 1:  # the end of a period: how did the hand settle?
                readings["closed" if action >= 0.5 else "open"].append(hand.opening())
            if steps % every == 0:
                action = float(rng.random())
                hand.command(action)
            steps += 1

        run(env, control, args, robot=robot, title="Gripper: random binary actions")
        moved = np.linalg.norm(env.body_frame("box").translation - box_start)
        print(f"actions: {len(readings['open'])} open, {len(readings['closed'])} closed")
        for kind in ("open", "closed"):
            if readings[kind]:
                lo, hi = min(readings[kind]), max(readings[kind])
                print(f"opening when {kind}: {lo:.3f} to {hi:.3f}")
        print(f"box moved: {moved:.4f} m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
