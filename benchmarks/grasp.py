"""Grasps at the arm's twist limit: slip and losses under the hand's drive and MuJoCo's contact
options, and their cost.

For each seed the PickCube expert grasps the cube (Menagerie Panda and hand, 2 ms steps),
then a scripted motion at the twist limit (0.5 m/s, the action at +-1): a lift of two
control steps (~7 cm from the floor, PickCube's lift), one more up, a carry of three sideways,
a shake of eight alternating steps (up/down, forward/back: reversals at the twist limit).
The hand is driven either by Menagerie's own finger servo (about 1 N a finger) or by a
`GripperDrive` (the tasks' `GripperDrive.franka_hand()`: 20 N a finger at 0.05 m/s, stiff
pads). Measured per setup, in the same process on the same seeds:
- slip: how far the cube's centre moved in the TCP's frame since the grasp closed, after the
  lift and the most over the whole motion (mm);
- held: both fingers still touch the cube at the end, off the floor;
- control-step time over the motion (the grasp in contact), as a ratio to the first row
  (Menagerie's servo under MuJoCo's defaults), interleaved seed by seed.
The same with Menagerie's Robotiq 2F-85 on the hand-less Panda (its model's own options,
elliptic and impratio 10, against pyramidal and impratio 1). Then the PickCube expert's
success (episodes of `mjkdl/PandaPickCube-v0`'s spec, 100 steps) lifting at full speed (its
default) and gently (a quarter of the gain), with and without the drive.

    python benchmarks/grasp.py              # 30 seeds
    python benchmarks/grasp.py --seeds 10
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import mujoco
import numpy as np
import scenes  # noqa: F401  (points MENAGERIE_ROOT at the shared Menagerie when unset)

import mjkdl as mjk
from mjkdl.task import ArmSpec, ContactSensor, GripperSpec, TaskEnv, TaskSpec
from mjkdl.task.experts import PickCubeExpert, _Phase
from mjkdl.task.registry import PANDA_HOME, panda_pick_cube_spec

# (contact options, physics timestep, the hand's drive): the tasks' Panda hand squeezes with
# `GripperDrive.franka_hand()` (20 N a finger, stiff pads); None is Menagerie's own finger servo
# (about 1 N a finger), the tasks' hand before it.
FRANKA = mjk.GripperDrive.franka_hand()
OPTIONS = {
    "Menagerie's servo, MuJoCo defaults (pyramidal, impratio 1)": (
        mjk.PhysicsOptions(),
        0.002,
        None,
    ),
    "Menagerie's servo, grasping(): elliptic, impratio 10": (
        mjk.PhysicsOptions.grasping(),
        0.002,
        None,
    ),
    "Menagerie's servo, grasping(), 0.5 ms steps": (mjk.PhysicsOptions.grasping(), 0.0005, None),
    "franka_hand() 20 N, MuJoCo defaults": (mjk.PhysicsOptions(), 0.002, FRANKA),
    "franka_hand() 20 N, grasping() (the tasks')": (mjk.PhysicsOptions.grasping(), 0.002, FRANKA),
    "GripperDrive 70 N (datasheet, continuous), grasping()": (
        mjk.PhysicsOptions.grasping(),
        0.002,
        mjk.GripperDrive("actuator8", force=70.0),
    ),
}
# (action index, sign) per control step: lift, carry sideways, shake.
LIFT_STEPS = 2
MOTION = [(2, 1)] * LIFT_STEPS + [(2, 1)] + [(1, 1)] * 3 + [(2, 1), (2, -1), (0, 1), (0, -1)] * 2


ROBOTIQ_OPTIONS = {
    "2F-85: its model's own (elliptic, impratio 10)": mjk.PhysicsOptions(),
    "2F-85: pyramidal, impratio 1": mjk.PhysicsOptions(cone="pyramidal", impratio=1.0),
}


def robotiq_spec(physics: mjk.PhysicsOptions) -> TaskSpec:
    """PickCube with the 2F-85 (prefix `g_`) on the hand-less Panda's flange, TCP at its
    `pinch` site, contacts of the cube with its pads."""
    spec = panda_pick_cube_spec()
    nohand = Path(mjk.menagerie.model_path("franka_emika_panda")).parent / "panda_nohand.xml"
    gripper = mjk.AttachmentSpec(
        mjcf_path=mjk.menagerie.model_path("robotiq_2f85"),
        attach_to=mjk.AttachTarget(mjk.AttachKind.Site, "attachment_site"),
        prefix="g_",
    )
    spec.scene.robots = [mjk.RobotSpec(path=str(nohand), attachments=[gripper])]
    spec.scene.cameras = []
    spec.scene.physics = physics
    spec.arms = [
        ArmSpec(
            name="panda",
            base_body="link0",
            tip_body="link7",
            tool=mjk.ToolFrameSpec(tool_body="g_base", tcp_site="g_pinch"),
            gripper=GripperSpec("g_fingers_actuator", open=0.0, closed=255.0),
            home=list(PANDA_HOME),
        )
    ]
    spec.sensors = [
        s
        if not isinstance(s, ContactSensor)
        else ContactSensor("cube", ["g_left_pad", "g_right_pad"])
        for s in spec.sensors
    ]
    return spec


def panda_spec(
    physics: mjk.PhysicsOptions, drive: mjk.GripperDrive | None, timestep: float = 0.002
) -> TaskSpec:
    """PickCube's spec under `physics`, its hand driven by `drive` (None: Menagerie's servo)."""
    spec = panda_pick_cube_spec()
    spec.scene.physics, spec.scene.timestep = physics, timestep
    spec.scene.robots[0].grippers = [] if drive is None else [drive]
    return spec


def _in_tcp(obs: dict[str, np.ndarray]) -> np.ndarray:
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, obs["panda_tcp_quat"].astype(float))
    return rot.reshape(3, 3).T @ (obs["cube_pose"][:3] - obs["panda_tcp_pos"])


def trial(env: TaskEnv, seed: int) -> tuple[float, float, bool, float] | None:
    """(slip after the lift, worst slip, held, seconds per control step), None when the
    expert did not close on the cube within 60 steps."""
    obs, _ = env.reset(seed=seed)
    expert = PickCubeExpert(env)
    for _ in range(60):
        action = expert(obs)
        if expert.phase is _Phase.LIFT:
            break
        obs, *_ = env.step(action)
    else:
        return None
    start = _in_tcp(obs)
    worst = lifted = 0.0
    hold = np.zeros(7, np.float32)
    hold[6] = 1.0
    t0 = time.perf_counter()
    for k, (axis, sign) in enumerate(MOTION):
        action = hold.copy()
        action[axis] = sign
        obs, *_ = env.step(action)
        slip = float(np.linalg.norm(_in_tcp(obs) - start)) * 1e3
        worst = max(worst, slip)
        if k == LIFT_STEPS - 1:
            lifted = slip
    per_step = (time.perf_counter() - t0) / len(MOTION)
    held = bool(np.all(obs["cube_contacts"] > 0.5)) and obs["cube_pose"][2] > 0.05
    return lifted, worst, held, per_step


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=30)
    args = parser.parse_args()
    envs = {}
    for name, (physics, timestep, drive) in OPTIONS.items():
        envs[name] = TaskEnv(panda_spec(physics, drive, timestep))
    for name, physics in ROBOTIQ_OPTIONS.items():
        envs[name] = TaskEnv(robotiq_spec(physics))
    results: dict[str, list[tuple[float, float, bool, float]]] = {n: [] for n in envs}
    for seed in range(args.seeds):
        for name, env in envs.items():  # interleaved: the same load on every option set
            r = trial(env, seed)
            if r is not None:
                results[name].append(r)
    base = float(np.median([r[3] for r in results[next(iter(OPTIONS))]]))
    print(f"{args.seeds} seeds, motion at the twist limit: {len(MOTION)} control steps")
    print("| options | slip after lift, median / max | worst slip, median / max | held | "
          "step time, ratio to defaults |")  # fmt: skip
    print("|---|---|---|---|---|")
    for name, rows in results.items():
        lift, worst = np.array([r[0] for r in rows]), np.array([r[1] for r in rows])
        held = sum(r[2] for r in rows)
        step = float(np.median([r[3] for r in rows]))
        print(
            f"| {name} | {np.median(lift):.1f} / {lift.max():.1f} mm | "
            f"{np.median(worst):.1f} / {worst.max():.1f} mm | {held}/{len(rows)} | "
            f"{step * 1e3:.1f} ms, {step / base:.2f} |"
        )
    for env in envs.values():
        env.close()
    print()
    print("| PickCube expert | Menagerie's servo, MuJoCo defaults | Menagerie's servo, "
          "grasping() | franka_hand(), grasping() (the tasks') |")  # fmt: skip
    print("|---|---|---|---|")
    setups = [
        (mjk.PhysicsOptions(), None),
        (mjk.PhysicsOptions.grasping(), None),
        (mjk.PhysicsOptions.grasping(), FRANKA),
    ]
    for label, lift_gain in (("full-speed lift (lift_gain 10)", 10.0), ("gentle lift (2.5)", 2.5)):
        wins = []
        for physics, drive in setups:
            spec = panda_spec(physics, drive)
            spec.terminate_on_success, spec.success_hold = True, 0.5
            with_env = TaskEnv(spec)
            wins.append(sum(_episode(with_env, lift_gain, s) for s in range(args.seeds)))
            with_env.close()
        print(f"| {label} | " + " | ".join(f"{w}/{args.seeds}" for w in wins) + " |")


def _episode(env: TaskEnv, lift_gain: float, seed: int) -> bool:
    """Whether the expert succeeds within 100 control steps."""
    obs, _ = env.reset(seed=seed)
    expert = PickCubeExpert(env, lift_gain=lift_gain)
    for _ in range(100):
        obs, _, terminated, _, info = env.step(expert(obs))
        if terminated:
            break
    return bool(info["is_success"])


if __name__ == "__main__":
    main()
